"""3D views (pyvista, offscreen): the scene's meshes, the sensor at its pose, the
reflectors the ray tracer found and the acoustic image's peaks placed in the scene."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["SceneRenderer", "render_scene", "PEAK_COLOR", "TRUTH_COLOR", "SENSOR_COLOR"]

PEAK_COLOR = (1.0, 0.1, 0.1)  # image peaks: red
TRUTH_COLOR = (0.1, 0.8, 1.0)  # ray-traced reflectors: cyan
SENSOR_COLOR = (1.0, 0.85, 0.0)  # the sensor: yellow


def _pv():
    try:
        import pyvista as pv
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("3D pictures need pyvista: pip install 'acousim[viz]'") from exc
    pv.OFF_SCREEN = True
    return pv


class SceneRenderer:
    """One offscreen plotter for many frames of the same scene: the meshes are added
    once, the sensor, reflectors and peaks are replaced per frame (a new plotter per
    frame costs most of an animation's time).

    triangles : (F, 3, 3) world-frame scene faces, or None.
    """

    def __init__(
        self, triangles: np.ndarray | None, window_size: tuple[int, int] = (900, 600)
    ) -> None:
        self.pv = pv = _pv()
        self.plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
        self.plotter.set_background("white")
        if triangles is not None and len(triangles):
            tri = np.asarray(triangles)
            faces = np.hstack([np.full((len(tri), 1), 3), np.arange(3 * len(tri)).reshape(-1, 3)])
            mesh = pv.PolyData(tri.reshape(-1, 3), faces.ravel())
            self.plotter.add_mesh(mesh, color=(0.72, 0.72, 0.75), opacity=0.35, show_edges=False)
        self._actors: list = []

    def frame(
        self,
        sensor_position: np.ndarray,
        sensor_axis: np.ndarray,
        truth: np.ndarray | None = None,
        peaks: np.ndarray | None = None,
        camera: str = "chase",
    ) -> np.ndarray:
        """Render one frame: (H, W, 3) uint8.  truth, peaks: (N, 3) world-frame points;
        camera: 'chase' (above and behind the sensor) or 'top' (bird's eye)."""
        pv, plotter = self.pv, self.plotter
        for actor in self._actors:
            plotter.remove_actor(actor, render=False)
        pos = np.asarray(sensor_position, float)
        axis = np.asarray(sensor_axis, float) / np.linalg.norm(sensor_axis)
        self._actors = [
            plotter.add_mesh(pv.Sphere(radius=0.06, center=pos), color=SENSOR_COLOR, render=False),
            plotter.add_mesh(
                pv.Arrow(start=pos, direction=axis, scale=0.6), color=SENSOR_COLOR, render=False
            ),
        ]
        for points, color, size in ((truth, TRUTH_COLOR, 6), (peaks, PEAK_COLOR, 14)):
            if points is not None and len(points):
                self._actors.append(
                    plotter.add_mesh(
                        pv.PolyData(np.asarray(points, float)),
                        color=color,
                        point_size=size,
                        render_points_as_spheres=True,
                        render=False,  # one render per frame: the screenshot's
                    )
                )
        if camera == "top":
            focus = pos + 2.5 * axis
            plotter.camera_position = [tuple(focus + [0, 0, 9.0]), tuple(focus), (1, 0, 0)]
        else:
            eye = pos - 2.2 * axis + np.array([0, 0, 1.6])
            plotter.camera_position = [tuple(eye), tuple(pos + 3.0 * axis), (0, 0, 1)]
        plotter.render()  # the actors were added without rendering: once, here
        return plotter.screenshot(return_img=True)

    def close(self) -> None:
        self.plotter.close()


def render_scene(
    path: str | Path | None,
    *,
    triangles: np.ndarray | None,
    sensor_position: np.ndarray,
    sensor_axis: np.ndarray,
    truth: np.ndarray | None = None,
    peaks: np.ndarray | None = None,
    window_size: tuple[int, int] = (900, 600),
    camera: str = "chase",
) -> np.ndarray:
    """Render a single frame (see :class:`SceneRenderer`); write it to `path` (PNG,
    atomically) when given.  Returns the image as an (H, W, 3) uint8 array."""
    renderer = SceneRenderer(triangles, window_size)
    try:
        image = renderer.frame(sensor_position, sensor_axis, truth, peaks, camera)
    finally:
        renderer.close()
    if path is not None:
        path = Path(path)
        tmp = path.with_name(f".{path.stem}.part.png")
        from matplotlib.image import imsave

        imsave(tmp, image)
        os.replace(tmp, path)
    return image
