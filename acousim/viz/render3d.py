"""3D views (pyvista, offscreen): the scene's meshes, the sensor at its pose, the
reflectors the ray tracer found and the acoustic image's peaks placed in the scene."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["render_scene", "PEAK_COLOR", "TRUTH_COLOR", "SENSOR_COLOR"]

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
    """Render a frame; write it to `path` (PNG, atomically) when given.

    triangles : (F, 3, 3) world-frame scene faces, or None.
    truth, peaks : (N, 3) world-frame points.
    camera : 'chase' (above and behind the sensor) or 'top' (bird's eye).
    Returns the image as an (H, W, 3) uint8 array.
    """
    pv = _pv()
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
    plotter.set_background("white")
    if triangles is not None and len(triangles):
        tri = np.asarray(triangles)
        faces = np.hstack([np.full((len(tri), 1), 3), np.arange(3 * len(tri)).reshape(-1, 3)])
        mesh = pv.PolyData(tri.reshape(-1, 3), faces.ravel())
        plotter.add_mesh(mesh, color=(0.72, 0.72, 0.75), opacity=0.35, show_edges=False)
    pos = np.asarray(sensor_position, float)
    axis = np.asarray(sensor_axis, float) / np.linalg.norm(sensor_axis)
    plotter.add_mesh(pv.Sphere(radius=0.06, center=pos), color=SENSOR_COLOR)
    plotter.add_mesh(pv.Arrow(start=pos, direction=axis, scale=0.6), color=SENSOR_COLOR)
    if truth is not None and len(truth):
        plotter.add_mesh(
            pv.PolyData(np.asarray(truth, float)),
            color=TRUTH_COLOR,
            point_size=6,
            render_points_as_spheres=True,
        )
    if peaks is not None and len(peaks):
        plotter.add_mesh(
            pv.PolyData(np.asarray(peaks, float)),
            color=PEAK_COLOR,
            point_size=14,
            render_points_as_spheres=True,
        )
    if camera == "top":
        focus = pos + 2.5 * axis
        plotter.camera_position = [tuple(focus + [0, 0, 9.0]), tuple(focus), (1, 0, 0)]
    else:
        eye = pos - 2.2 * axis + np.array([0, 0, 1.6])
        plotter.camera_position = [tuple(eye), tuple(pos + 3.0 * axis), (0, 0, 1)]
    image = plotter.screenshot(return_img=True)
    plotter.close()
    if path is not None:
        path = Path(path)
        tmp = path.with_name(f".{path.stem}.part.png")
        from matplotlib.image import imsave

        imsave(tmp, image)
        os.replace(tmp, path)
    return image
