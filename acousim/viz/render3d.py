"""3D views (pyvista, offscreen): the scene's meshes, the sensor at its pose, the
traced echoes where the sensor sees them (their apparent positions), the paths of
the strongest ones and the acoustic image's peaks placed in the scene.

Every view has a legend (inside the view, or for ``scene3d.png`` and the animation
below it in black text: :func:`view_figure`) and a 1 m scale bar.  Ray-traced echoes
are drawn only
within `truth_range_db` of the strongest echo, the stronger ones larger, so that a
few strong echoes are not hidden among hundreds of weak scatterers; a peak of the
image then sits on the echo it shows, even one beyond every surface (a two-bounce
echo), whose path (a thin line through its reflections) says where it came from.  Without a
scene mesh (a real recording) the camera is fitted to the sensor and the peaks, and
a labelled grid in metres gives the scale.

A sensor that moves or turns during its measurement is drawn smeared (motion blur):
its axis at several instants of the measurement window, fading, and the wedge they
sweep (:func:`sensor_sweep`, :func:`sweep_wedge`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acousim.viz.fan import DYNAMIC_RANGE_DB
from processing.base.atomic import atomic_path

__all__ = [
    "SceneRenderer",
    "FrameContent",
    "render_scene",
    "legend_entries",
    "legend_handles",
    "view_figure",
    "SCENE_WINDOW",
    "import_pyvista",
    "PEAK_COLOR",
    "TRUTH_COLOR",
    "SENSOR_COLOR",
    "SWEEP_COLOR",
    "sensor_sweep",
    "sweep_wedge",
]

PEAK_COLOR = (1.0, 0.1, 0.1)  # image peaks: red
TRUTH_COLOR = (0.1, 0.8, 1.0)  # ray-traced echoes where the sensor sees them: cyan
CHAIN_COLOR = (0.0, 0.45, 0.6)  # the chains of the strongest echoes: dark cyan
SENSOR_COLOR = (1.0, 0.85, 0.0)  # the sensor: yellow
SWEEP_COLOR = (1.0, 0.45, 0.0)  # the sensor's sweep during a measurement: orange
#: length of the drawn axis and of the swept wedge (m)
AXIS_LENGTH_M = 0.6
WEDGE_LENGTH_M = 1.5


MOVING_COLOR = (0.45, 0.35, 0.7)  # meshes that move (a person, a robot): violet
LIDAR_COLOR = (0.15, 0.6, 0.2)  # the LiDAR's points: green


@dataclass(frozen=True)
class FrameContent:
    """What one frame draws; points in the world frame (m).

    sensor_position (3,), sensor_axis (3,) : the sensor and where it points.
    truth, peaks : (N, 3) points: ray-traced reflectors, image peaks.
    truth_level_db : (N,) level of each reflector in dB re the strongest (default:
        all 0 dB); those below -`truth_range_db` (default: the renderer's) are not
        drawn, the others are spheres from 2 cm (at the threshold) to 6 cm (the
        strongest) in diameter.
    sweep : the sensor's positions and axes (K, 3) each over its measurement
        (:func:`sensor_sweep`): drawn as fading axes and the wedge they sweep.
    moving_triangles : (F, 3, 3) faces of the scene's moving meshes where they are
        in this frame.
    lidar : (P, 3) points of the LiDAR's scan (small dots).
    chains : polylines (each (K, 3)) of the strongest echoes' paths: from the sensor
        through their interactions and back, then on to where the sensor sees them
        (thin lines).
    sensor_rotation : (3, 3) sensor -> world (its columns the sensor's x forward, y
        left, z up), for the plan view (:mod:`acousim.viz.plan`); None: made from the
        axis with the world's z up.
    """

    sensor_position: np.ndarray
    sensor_axis: np.ndarray
    truth: np.ndarray | None = None
    peaks: np.ndarray | None = None
    truth_level_db: np.ndarray | None = None
    truth_range_db: float | None = None
    sweep: tuple[np.ndarray, np.ndarray] | None = None
    moving_triangles: np.ndarray | None = None
    lidar: np.ndarray | None = None
    chains: tuple | list = ()
    sensor_rotation: np.ndarray | None = None


def _polydata(pv, triangles: np.ndarray):
    """A pyvista mesh of (F, 3, 3) triangles."""
    tri = np.asarray(triangles, float)
    faces = np.hstack([np.full((len(tri), 1), 3), np.arange(3 * len(tri)).reshape(-1, 3)])
    return pv.PolyData(tri.reshape(-1, 3), faces.ravel())


def sensor_sweep(
    position_m: np.ndarray,
    rotation: np.ndarray,
    velocity_m_s: np.ndarray,
    angular_velocity_rad_s: np.ndarray,
    window_s: float,
    count: int = 6,
) -> tuple[np.ndarray, np.ndarray]:
    """Where the sensor is and where it points at `count` instants spread evenly over
    a measurement window of `window_s`, from the start of the emission (position (3,),
    rotation sensor -> world (3, 3)) at constant rates (world frame; as a recording's
    ``provenance.motion`` holds them): positions (K, 3), unit axes (K, 3)."""
    from scipy.spatial.transform import Rotation

    t = np.linspace(0.0, window_s, count)
    turn = Rotation.from_rotvec(np.outer(t, np.asarray(angular_velocity_rad_s, float)))
    axes = turn.apply(np.asarray(rotation, float)[:, 0])  # R(t) = exp(w t) R_0
    positions = np.asarray(position_m, float) + np.outer(t, np.asarray(velocity_m_s, float))
    return positions, axes


def sweep_wedge(positions: np.ndarray, axes: np.ndarray, length_m: float = WEDGE_LENGTH_M):
    """The surface the sensor's axis (a segment of `length_m` from the sensor) sweeps
    through the instants of :func:`sensor_sweep`: vertices (2 K, 3) (sensor, tip for
    each instant) and quads (K - 1, 4) of vertex indices."""
    tips = positions + length_m * axes
    vertices = np.stack([positions, tips], axis=1).reshape(-1, 3)
    k = np.arange(len(positions) - 1)
    quads = np.column_stack([2 * k, 2 * k + 1, 2 * k + 3, 2 * k + 2])
    return vertices, quads


def import_pyvista():
    """Import pyvista (and VTK) for offscreen rendering.  Commands call this before
    their work starts: VTK's import is long, and an interrupt in the middle of it
    could crash the interpreter instead of raising KeyboardInterrupt."""
    try:
        import pyvista as pv
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("3D pictures need pyvista: pip install 'acousim[viz]'") from exc
    pv.OFF_SCREEN = True
    try:  # offscreen is intended: no "bad X server connection" warning on every run
        from vtkmodules.vtkCommonCore import vtkLogger

        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except ImportError:  # pragma: no cover - a VTK without its logger
        pass
    return pv


_pv = import_pyvista


def legend_entries(
    *,
    with_truth: bool,
    with_sweep: bool = False,
    with_moving: bool = False,
    truth_range_db: float = DYNAMIC_RANGE_DB,
    with_lidar: bool = False,
) -> list[tuple[str, tuple[float, float, float]]]:
    """The 3D view's legend: (label, RGB colour) of each kind of thing drawn."""
    entries = [("sensor, arrow: its axis", SENSOR_COLOR), ("image peaks", PEAK_COLOR)]
    if with_sweep:
        entries.append(("its sweep during the measurement", SWEEP_COLOR))
    if with_moving:
        entries.append(("moving meshes, at the emission", MOVING_COLOR))
    if with_truth:
        entries.append((f"traced echoes where seen, within {truth_range_db:g} dB", TRUTH_COLOR))
        entries.append(("paths of the strongest echoes", CHAIN_COLOR))
    if with_lidar:
        entries.append(("LiDAR points", LIDAR_COLOR))
    return entries


class SceneRenderer:
    """One offscreen plotter for many frames of the same scene: the meshes, legend
    and scale are added once, the sensor, reflectors and peaks are replaced per frame
    (a new plotter per frame costs most of an animation's time).

    triangles : (F, 3, 3) world-frame scene faces, or None.
    with_truth : list the ray-traced reflectors in the legend.
    with_sweep : list the sensor's sweep during the measurement in the legend.
    with_moving : list the moving meshes (drawn per frame) in the legend.
    truth_range_db : reflectors within this of the strongest echo are drawn (dB).
    with_lidar : list the LiDAR's points in the legend.
    legend : draw the legend inside the view (its entries are ``entries`` either way).
    (Its antialiasing: :meth:`antialiasing`, before the first frame.)
    """

    def __init__(
        self,
        triangles: np.ndarray | None,
        window_size: tuple[int, int] = (900, 600),
        with_truth: bool = True,
        with_sweep: bool = False,
        with_moving: bool = False,
        truth_range_db: float = DYNAMIC_RANGE_DB,
        with_lidar: bool = False,
        legend: bool = True,
    ) -> None:
        self.pv = pv = _pv()
        self.truth_range_db = truth_range_db
        self.plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
        self.plotter.set_background("white")
        self.has_mesh = triangles is not None and len(triangles) > 0
        if self.has_mesh:
            tri = np.asarray(triangles)
            mesh = _polydata(pv, tri)
            self.plotter.add_mesh(mesh, color=(0.72, 0.72, 0.75), opacity=0.35, show_edges=False)
            self.floor_z = float(tri[..., 2].min())
        else:
            self.floor_z = None
        self.entries = legend_entries(
            with_truth=with_truth,
            with_sweep=with_sweep,
            with_moving=with_moving,
            truth_range_db=truth_range_db,
            with_lidar=with_lidar,
        )
        if legend:  # inside the view; a picture may draw it outside instead
            self.plotter.add_legend(
                [list(e) for e in self.entries],
                bcolor=(0.2, 0.2, 0.22),  # the light colours read on a dark ground
                border=True,
                size=(0.36, max(0.12, 0.03 * len(self.entries))),
                loc="upper left",
                face="circle",
            )
        self._actors: list = []  # drawn for one frame, removed before the next
        self._kept: dict = {}  # by kind: an actor made once, its data replaced per frame
        self._ruler = None

    def antialiasing(self, samples: int) -> SceneRenderer:
        """Render with `samples` per pixel of antialiasing (pyvista's theme: 8; 1:
        none, a software renderer's frame in a third of the time); before the first
        frame (the window's first render fixes it). Returns the renderer."""
        self.plotter.ren_win.SetMultiSamples(int(samples))
        return self

    def frame(self, content: FrameContent, *, camera: str = "chase") -> np.ndarray:
        """Render one frame of `content` (:class:`FrameContent`): (H, W, 3) uint8.

        camera : 'chase' (above and behind the sensor) or 'top' (bird's eye); without
            a scene mesh the camera is fitted to the sensor and the peaks.
        """
        c = content
        plotter = self.plotter
        for actor in self._actors:
            plotter.remove_actor(actor, render=False)
        self._actors = []
        for actor in self._kept.values():  # shown again if this frame draws its kind
            actor.SetVisibility(False)
        pos = np.asarray(c.sensor_position, float)
        axis = np.asarray(c.sensor_axis, float) / np.linalg.norm(c.sensor_axis)
        self._sensor(pos, axis)
        if c.sweep is not None:
            self._sweep(*c.sweep)
        if c.moving_triangles is not None and len(c.moving_triangles):
            self._put("moving", _polydata(self.pv, c.moving_triangles), color=MOVING_COLOR)
        drawn_truth = self._truth(c)
        for i, chain in enumerate(c.chains):
            line = self.pv.lines_from_points(np.asarray(chain, float))
            self._put(f"chain {i}", line, color=CHAIN_COLOR, line_width=1.5)
        if c.lidar is not None and len(c.lidar):
            cloud = self.pv.PolyData(np.asarray(c.lidar, float).reshape(-1, 3))
            self._put("lidar", cloud, color=LIDAR_COLOR, point_size=3)
        if c.peaks is not None and len(c.peaks):
            cloud = self.pv.PolyData(np.asarray(c.peaks, float))
            self._put(
                "peaks", cloud, color=PEAK_COLOR, point_size=14, render_points_as_spheres=True
            )
        self._scale_bar(pos, axis)
        self._place_camera(c, pos, axis, camera, drawn_truth)
        plotter.render()  # the actors were added without rendering: once, here
        return plotter.screenshot(return_img=True)

    def _put(self, kind: str, mesh, **style) -> None:
        """Show `mesh` as this frame's `kind` of thing, drawn with `style` (add_mesh's
        keywords, the same for a kind in every frame): the kind's actor made on its
        first frame, its data replaced in the later ones (adding an actor costs more
        than a software render's share of the frame)."""
        actor = self._kept.get(kind)
        if actor is None:  # one render per frame: the screenshot's
            self._kept[kind] = self.plotter.add_mesh(mesh, render=False, **style)
        else:
            actor.mapper.SetInputData(mesh)
            actor.SetVisibility(True)

    def _sensor(self, pos: np.ndarray, axis: np.ndarray) -> None:
        """The sensor: a sphere at `pos` and an arrow along its unit `axis`."""
        pv = self.pv
        self._put("sensor", pv.Sphere(radius=0.06, center=pos), color=SENSOR_COLOR)
        arrow = pv.Arrow(start=pos, direction=axis, scale=AXIS_LENGTH_M)
        self._put("sensor axis", arrow, color=SENSOR_COLOR)

    def _truth(self, c: FrameContent) -> np.ndarray | None:
        """Draw the reflectors within the dynamic range (spheres sized by level);
        returns the drawn points (K, 3), None when there is no truth."""
        if c.truth is None or not len(c.truth):
            return None
        pv = self.pv
        t = np.asarray(c.truth, float).reshape(-1, 3)
        lvl = np.zeros(len(t)) if c.truth_level_db is None else np.asarray(c.truth_level_db)
        truth_range_db = c.truth_range_db or self.truth_range_db
        keep = lvl >= -truth_range_db
        if keep.any():
            cloud = pv.PolyData(t[keep])
            cloud["diameter"] = 0.02 + 0.04 * (1 + lvl[keep] / truth_range_db)
            glyphs = cloud.glyph(
                scale="diameter", orient=False, geom=pv.Sphere(radius=0.5, theta_resolution=10)
            )
            self._put("truth", glyphs, color=TRUTH_COLOR)
        return t[keep]

    def _place_camera(self, c: FrameContent, pos, axis, camera: str, truth) -> None:
        """The camera: fitted to what is drawn (no mesh), bird's eye or chasing."""
        plotter = self.plotter
        if not self.has_mesh:
            drawn = [
                np.asarray(q, float).reshape(-1, 3) for q in (c.peaks, c.lidar) if q is not None
            ]
            if truth is not None:
                drawn.append(truth)
            self._fit_camera(pos, axis, drawn)
        elif camera == "top":
            focus = pos + 2.5 * axis
            plotter.camera_position = [tuple(focus + [0, 0, 9.0]), tuple(focus), (1, 0, 0)]
        else:  # behind and above, looking past the sensor: the sensor in the lower third
            eye = pos - 2.8 * axis + np.array([0, 0, 1.5])
            plotter.camera_position = [tuple(eye), tuple(pos + 2.0 * axis), (0, 0, 1)]

    def _sweep(self, positions: np.ndarray, axes: np.ndarray) -> None:
        """Motion blur: the wedge the axis sweeps (translucent) and the axis at each
        instant after the first, fading towards the end of the window."""
        pv = self.pv
        vertices, quads = sweep_wedge(positions, axes)
        faces = np.column_stack([np.full(len(quads), 4), quads]).ravel()
        self._put("sweep", pv.PolyData(vertices, faces), color=SWEEP_COLOR, opacity=0.45)
        k = len(positions)
        for i in range(1, k):
            line = pv.Line(positions[i], positions[i] + WEDGE_LENGTH_M * axes[i])
            fade = 0.9 - 0.6 * (i - 1) / max(k - 2, 1)
            self._put(f"sweep {i} of {k}", line, color=SWEEP_COLOR, line_width=3, opacity=fade)

    def _scale_bar(self, pos: np.ndarray, axis: np.ndarray) -> None:
        """A 1 m ruler across the view, 0.8 m in front of the sensor and 0.2 m below
        it (above the floor, if the scene has one): made once, moved per frame (adding
        one resets the camera with a render of its own)."""
        side = np.cross([0.0, 0.0, 1.0], axis)
        side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-9 else np.array([0, 1, 0])
        z = pos[2] - 0.2
        if self.floor_z is not None:
            z = max(z, self.floor_z + 0.01)
        a = np.array([*(pos[:2] + 0.8 * axis[:2]), z]) - 0.5 * side
        if self._ruler is not None:
            self._ruler.GetPositionCoordinate().SetValue(*a)
            self._ruler.GetPosition2Coordinate().SetValue(*(a + side))
            return
        self._ruler = self.plotter.add_ruler(
            a,
            a + side,
            title="1 m",
            number_labels=2,
            label_format="%.1f",
            show_labels=False,
            label_color="black",
            tick_color="black",
        )

    def _fit_camera(self, pos, axis, points) -> None:
        """No mesh: a labelled grid in metres around the sensor and the drawn points
        (at least 2 m x 2 m x 1 m), seen from behind and above, zoomed to fit."""
        p = np.concatenate([pos[None], (pos + axis)[None], *points])
        lo, hi = p.min(axis=0) - 0.3, p.max(axis=0) + 0.3
        centre = (lo + hi) / 2
        half = np.maximum((hi - lo) / 2, [1.0, 1.0, 0.5])
        lo, hi = centre - half, centre + half
        self._actors.append(
            self.plotter.show_grid(
                bounds=[lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]],
                color="grey",
                xtitle="x (m)",
                ytitle="y (m)",
                ztitle="z (m)",
                n_xlabels=4,
                n_ylabels=4,
                n_zlabels=3,
                fmt="%.1f",
                render=False,
            )
        )
        size = float(np.max(hi - lo))
        eye = centre - 1.6 * size * axis + np.array([0, 0, 1.1 * size])
        self.plotter.camera_position = [tuple(eye), tuple(centre), (0, 0, 1)]
        self.plotter.reset_camera(render=False)  # fit everything drawn, grid included
        self.plotter.camera.zoom(0.9)

    def close(self) -> None:
        self.plotter.close()


#: scene3d.png: the 3D view's size in pixels (width, height); its legend lies below it
SCENE_WINDOW = (1600, 1000)


def render_scene(
    path: str | Path | None,
    content: FrameContent,
    *,
    triangles: np.ndarray | None,
    window_size: tuple[int, int] = SCENE_WINDOW,
    camera: str = "chase",
    truth_range_db: float = DYNAMIC_RANGE_DB,
    title: str | None = None,
) -> np.ndarray:
    """Render a single frame of `content` (see :meth:`SceneRenderer.frame`) among the
    scene's `triangles` (F, 3, 3) (None: no mesh); when `path` is given, write it
    as a PNG (atomically) as wide as the view, with `title` above it and the legend
    below it, outside the view (:func:`view_figure`).  Returns the view alone as an
    (H, W, 3) uint8 array."""
    renderer = SceneRenderer(
        triangles,
        window_size,
        with_truth=content.truth is not None,
        with_sweep=content.sweep is not None,
        with_moving=content.moving_triangles is not None,
        truth_range_db=truth_range_db,
        with_lidar=content.lidar is not None,
        legend=False,
    )
    try:
        image = renderer.frame(content, camera=camera)
    finally:
        renderer.close()
    if path is not None:
        import matplotlib.pyplot as plt

        fig = view_figure(image, renderer.entries, title)
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=fig.dpi, format="png")
        plt.close(fig)
    return image


def legend_handles(entries, markersize: float = 11.0) -> list:
    """Matplotlib legend entries of :func:`legend_entries`: a filled circle of each
    colour with a black edge (a light colour still shows on white), black text."""
    from matplotlib.lines import Line2D

    return [
        Line2D([], [], ls="none", marker="o", ms=markersize, mfc=c, mec="black", label=label)
        for label, c in entries
    ]


def view_figure(image: np.ndarray, entries, title: str | None = None, fontsize: float = 14.0):
    """A 3D view (H, W, 3) drawn one pixel per pixel, `title` above it and the legend
    (:func:`legend_entries`) below it in black text: nothing covers the view and the
    legend reads at the picture's size.  Returns the matplotlib Figure (Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h, w = image.shape[:2]
    dpi = 100.0
    rows = -(-len(entries) // 3)
    below = (0.35 + 0.32 * rows) * fontsize / 14  # inches
    above = 0.5 * fontsize / 14 if title else 0.0
    fig = plt.figure(figsize=(w / dpi, h / dpi + below + above), dpi=dpi)
    total = h / dpi + below + above
    ax = fig.add_axes((0.0, below / total, 1.0, h / dpi / total))
    ax.imshow(image, interpolation="nearest")
    ax.axis("off")
    fig.legend(
        handles=legend_handles(entries),
        loc="lower center",
        ncols=min(3, len(entries)),
        fontsize=fontsize,
        frameon=False,
        bbox_to_anchor=(0.5, 0.0),
    )
    if title:
        fig.text(0.5, 1 - 0.5 * above / total, title, ha="center", va="center", fontsize=fontsize)
    return fig
