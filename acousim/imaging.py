"""Imaging recordings (simulated or real) and writing the pictures people look at:
fan images, elevation-azimuth maps, 3D renders of the scene, drive animations."""

from __future__ import annotations

import contextlib
import dataclasses
import signal
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import processing as P
from processing import interrupt
from processing.atomic import atomic_path
from processing.errors import InputError
from processing.settings import setting, validate

__all__ = [
    "ImagingOptions",
    "image_recordings",
    "peak_positions",
    "peaks_in_world",
    "prepare_pictures",
    "write_pictures",
]


@dataclass(frozen=True)
class ImagingOptions:
    """How recordings are imaged.

    methods : DOA methods (see ``processing.METHODS``).
    azimuth_deg, elevation_deg : (min, max) of the grid; step_deg its step.
    energy_fraction : range bins kept when their energy is at least this fraction of
        the strongest bin in [min_range_m, max_range_m] (the paper uses 0.5 for one
        reflector; a room needs a lower gate).
    min_range_m : bins nearer than this are ignored (the direct path).
    peak_threshold_db : peaks drawn in the 3D view.
    """

    methods: tuple[str, ...] = ("das", "capon-fbss", "music-fbss")
    azimuth_deg: tuple[float, float] = (-90.0, 90.0)
    elevation_deg: tuple[float, float] = (-40.0, 40.0)
    step_deg: float = setting(2.0, "deg", 0.1, 45, "grid step")
    energy_fraction: float = setting(
        P.ProcessingSettings.energy_fraction,  # one default, ProcessingSettings'
        "",
        0,
        1,
        "keep range bins with at least this fraction of the strongest bin's energy "
        "(the paper uses 0.5)",
    )
    min_range_m: float = setting(
        P.ProcessingSettings.range_limits_m[0], "m", 0, 1000, "ignore nearer range bins"
    )
    max_range_m: float | None = setting(
        None, "m", 0.01, 1000, "ignore farther range bins", kind="float"
    )
    peak_threshold_db: float = setting(
        -10.0, "dB", -200, 0, "peaks kept within this many dB of each image's strongest cell"
    )
    grid: P.Grid = field(init=False, repr=False)

    def __post_init__(self) -> None:
        validate(self)
        for m in self.methods:
            P.check_method(m)
        object.__setattr__(
            self, "grid", P.Grid.degrees(self.azimuth_deg, self.elevation_deg, self.step_deg)
        )

    def settings(self, recording: P.Recording) -> P.ProcessingSettings:
        hi = self.max_range_m or recording.speed_of_sound_m_s * recording.n_samples / (
            2 * recording.sample_rate_hz
        )
        return P.ProcessingSettings(
            energy_fraction=self.energy_fraction,
            grid=self.grid,
            range_limits_m=(self.min_range_m, hi),
        )


def image_recordings(
    recordings: Sequence[P.Recording],
    options: ImagingOptions,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict[str, P.Image]]:
    """Images of every recording by every method."""
    out = []
    for i, rec in enumerate(recordings):
        interrupt.check()  # Ctrl-C (when the command line records it): stop here
        if rec.array.n_mics and not rec.array.is_ura:
            smooth = [m for m in options.methods if P.requires_ura(m)]
            if smooth:
                raise InputError(
                    f"recording {i}: array {rec.array.name!r} is not a URA, so "
                    f"{', '.join(smooth)} cannot be used; choose das, music, capon "
                    "or a wideband (-wb) or broadband (-bb) method"
                )
        out.append(P.acoustic_images(rec, options.methods, options.settings(rec)))
        if progress:
            progress(i + 1, len(recordings))
    return out


def _pose(rec: P.Recording):
    from acousim.scene.pose import Pose

    p = P.pose_of(rec.metadata)
    if p is None:
        return Pose(np.zeros(3))
    return Pose(
        p["position_m"],
        *np.deg2rad([p["yaw_deg"], p["pitch_deg"], p["roll_deg"]]),
        time_s=p["time_s"],
    )


def peak_positions(rec: P.Recording, peaks: P.Peaks) -> tuple[np.ndarray, np.ndarray]:
    """Peaks (az, el, range from the array centre) as points: (sensor frame (N, 3),
    world frame (N, 3)), through the recording's pose (identity without one)."""
    d = np.column_stack(
        [
            np.cos(peaks.elevation_rad) * np.cos(peaks.azimuth_rad),
            np.cos(peaks.elevation_rad) * np.sin(peaks.azimuth_rad),
            np.sin(peaks.elevation_rad),
        ]
    ).reshape(-1, 3)
    sensor = rec.array.positions_m.mean(axis=0) + peaks.range_m.reshape(-1, 1) * d
    return sensor, _pose(rec).to_world(sensor)


def peaks_in_world(rec: P.Recording, image: P.Image, threshold_db: float) -> np.ndarray:
    """Image peaks as world points (N, 3): (az, el, range) from the array centre."""
    return peak_positions(rec, image.peaks(threshold_db))[1]


def _scene(rec: P.Recording):
    """The recording's scene, when its file is still there (None for real data).

    Read only for the 3D view and the animation, and only a scene file (.toml): a
    recording cannot make us open any other path."""
    file = rec.metadata.get("scene_file")
    if not file:
        return None
    if not isinstance(file, str) or Path(file).suffix.lower() != ".toml":
        raise InputError(
            "the recording's scene_file is not a scene file (.toml); "
            "image without the 3D view (--no-3d --no-animation)",
            key="scene_file",
            value=file,
        )
    if not Path(file).is_file():
        return None
    from acousim.scene import load_scene

    return load_scene(file)  # a scene file that no longer loads is an InputError


def _scene_triangles(scene) -> np.ndarray | None:
    """The faces (F, 3, 3) of the scene's meshes that do not move."""
    if scene is None or not any(not m.moving for m in scene.meshes):
        return None
    from acousim.trace.geometry import build_world

    if any(m.moving for m in scene.meshes):
        scene = dataclasses.replace(scene, meshes=tuple(m for m in scene.meshes if not m.moving))
    return build_world(scene).triangles


def _moving_triangles(scene, rec: P.Recording) -> np.ndarray | None:
    """The faces (F, 3, 3) of the scene's moving meshes where they are at the start of
    the recording's emission (None: none moves)."""
    if scene is None or not any(m.moving for m in scene.meshes):
        return None
    from acousim.trace.geometry import build_world

    t = _pose(rec).time_s
    moving = tuple(m.placed_at(t) for m in scene.meshes if m.moving)
    return build_world(dataclasses.replace(scene, meshes=moving)).triangles


def prepare_pictures(render_3d: bool = True, animation: bool = True) -> None:
    """Import what the pictures need (matplotlib; pyvista/VTK and imageio for the 3D
    views) before a command's work starts, so that Ctrl-C never lands in the middle of
    VTK's import (which could crash the interpreter instead of stopping cleanly).
    An interrupt during these imports is held back and raised once they are done."""
    with _interrupt_after():
        _import_pictures(render_3d, animation)


@contextlib.contextmanager
def _interrupt_after():
    """Hold SIGINT back during the block, then raise KeyboardInterrupt if it came."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda sig, frame: caught.append(sig))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


def _import_pictures(render_3d: bool, animation: bool) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401

    if render_3d or animation:
        from acousim.viz.render3d import import_pyvista

        import_pyvista()
    if animation:
        import imageio.v2  # noqa: F401


def write_pictures(
    recordings: Sequence[P.Recording],
    images: Sequence[dict[str, P.Image]],
    out_dir: str | Path,
    options: ImagingOptions,
    *,
    render_3d: bool = True,
    animation: bool = True,
    progress: Callable[[int, int], None] | None = None,
    indices: Sequence[int] | None = None,
) -> list[Path]:
    """Fan images and elevation-azimuth maps of the first recording, its 3D render,
    and for several recordings (a trajectory) an animated GIF of the drive.

    indices : the recordings' indices in their file (for the titles; default 0, 1, ...).
    """
    from acousim.viz import elaz_figure, fan_figure

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    trajectory = len(recordings) > 1
    written = []
    first, imgs = recordings[0], images[0]
    scene = _scene(first) if render_3d or animation else None
    limit = _range_limit(first, options)
    title = _title(first, indices[0], trajectory)
    written.append(
        fan_figure(
            imgs, out / "fan.png", truth=_truth_sensor(first), title=title, max_range_m=limit
        )
    )
    for m, img in imgs.items():
        if img.power.size:
            written.append(elaz_figure(img, out / f"elaz_{m}.png", title=title))
    triangles = _scene_triangles(scene) if render_3d or animation else None
    if render_3d:
        written.append(
            _render(
                first,
                imgs,
                triangles,
                out / "scene3d.png",
                options,
                _moving_triangles(scene, first),
            )
        )
    if animation and trajectory:
        written.append(
            _animate(
                recordings, images, triangles, out / "drive.gif", options, progress, indices, scene
            )
        )
    return written


def _range_limit(rec: P.Recording, options: ImagingOptions) -> float:
    """The farthest range a picture may show: the imaged range, within the simulated
    one (the recording's ``max_range_m`` metadata, when it was simulated)."""
    hi = options.settings(rec).range_limits_m[1]
    simulated = rec.metadata.get("max_range_m")
    if isinstance(simulated, int | float) and simulated > 0:
        hi = min(hi, float(simulated))
    return float(hi)


def _sharpest(imgs: dict[str, P.Image]) -> str:
    """The method drawn in the 3D view and the animation: a smoothed one if imaged."""
    for m in ("music-fbss", "capon-fbss", "music-fss", "capon-fss"):
        if m in imgs:
            return m
    return next(iter(imgs))


def _title(rec: P.Recording, index: int, trajectory: bool = False) -> str:
    """'corridor — recording 30, t = 3.0 s': the time only for a trajectory's pose."""
    p = P.pose_of(rec.metadata)
    moving = p and (trajectory or p["time_s"] or rec.metadata.get("pose_index", 0))
    where = f", t = {p['time_s']:.1f} s" if moving else ""
    kind = "simulated" if rec.metadata.get("simulated") else "real"
    return f"{rec.metadata.get('scene', kind)} — recording {index}{where}"


TRUTH_DRAWN_DB = 20.0  # fan pictures: ray-traced reflectors within this of the strongest


def _truth_sensor(rec: P.Recording) -> np.ndarray | None:
    """Ray-traced echo points (N, 3, sensor frame) within TRUTH_DRAWN_DB of the
    strongest echo (the direct path excluded)."""
    t = rec.truth
    if t is None or not len(t):
        return None
    pts = t.position_sensor_m
    lvl = _truth_level_db(t)
    strong = lvl >= -TRUTH_DRAWN_DB
    return pts[strong] if strong.any() else None


def _truth_level_db(truth: P.GroundTruth) -> np.ndarray:
    """Level (N,) of each ray-traced path in dB re the strongest echo; -inf for the
    direct path (not a reflector)."""
    kind = truth.kind
    amp = np.abs(truth.amplitude)
    echo = (kind != "direct") & (amp > 0)
    lvl = np.full(amp.shape, -np.inf)
    if echo.any():
        lvl[echo] = 20 * np.log10(amp[echo] / amp[echo].max())
    return lvl


def _truth_world(rec: P.Recording) -> tuple[np.ndarray | None, np.ndarray | None]:
    truth = rec.truth
    if truth is None or not len(truth):
        return None, None
    return truth.position_world_m, _truth_level_db(truth)


#: the sensor's sweep during a measurement is drawn when it turns or moves this much
SWEEP_MIN_RAD = np.deg2rad(0.5)
SWEEP_MIN_M = 0.05


def _sweep(rec: P.Recording):
    """The sensor's positions and axes over the recording's window if it moved or
    turned during it (``metadata["motion"]``), else None (nothing to smear)."""
    from acousim.viz.render3d import sensor_sweep

    motion = rec.metadata.get("motion")
    if not motion:
        return None
    v = np.asarray(motion.get("velocity_m_s", (0.0, 0.0, 0.0)), float)
    w = np.deg2rad(np.asarray(motion.get("angular_velocity_deg_s", (0.0, 0.0, 0.0)), float))
    window = rec.samples.shape[-1] / rec.sample_rate_hz
    if np.linalg.norm(w) * window < SWEEP_MIN_RAD and np.linalg.norm(v) * window < SWEEP_MIN_M:
        return None  # too small to be seen
    pose = _pose(rec)
    return sensor_sweep(pose.position_m, pose.rotation, v, w, window)


def lidar_in_world(rec: P.Recording) -> np.ndarray | None:
    """The recording's LiDAR points in the world frame (P, 3) through its pose (the
    scan's own frame at each firing: for a moving sensor, as its unit reports them),
    None without a scan."""
    if rec.lidar is None:
        return None
    return _pose(rec).to_world(rec.lidar.in_sensor())


def _render(rec, imgs, triangles, path, options, moving=None):
    from acousim.viz.render3d import render_scene

    pose = _pose(rec)
    method = _sharpest(imgs)
    truth_w, level = _truth_world(rec)
    render_scene(
        path,
        triangles=triangles,
        sensor_position=pose.position_m,
        sensor_axis=pose.rotation[:, 0],
        truth=truth_w,
        truth_level_db=level,
        peaks=peaks_in_world(rec, imgs[method], options.peak_threshold_db),
        sweep=_sweep(rec),
        moving_triangles=moving,
        lidar=lidar_in_world(rec),
    )
    return Path(path)


def _animate(recordings, images, triangles, path, options, progress, indices, scene=None):
    import imageio.v2 as imageio
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acousim.viz.fan import TRUTH_COLOR, draw_fan, fan_extent, truth_in_fan
    from acousim.viz.render3d import SceneRenderer

    dr = 30.0
    method = _sharpest(images[0])
    limit = min(_range_limit(rec, options) for rec in recordings)
    truths = [_truth_sensor(rec) for rec in recordings]
    truths_yx = [truth_in_fan(t) if t is not None else None for t in truths]
    # one fitted extent for the whole drive (the axes do not jump between frames)
    ext = np.array(
        [
            fan_extent(imgs[method], limit, dr, t)
            for imgs, t in zip(images, truths_yx)
            if imgs[method].range_m.size
        ]
        or [(1.0, -1.0, 0.0, 1.0)]
    )
    extent = (ext[:, 0].max(), ext[:, 1].min(), ext[:, 2].min(), ext[:, 3].max())
    frames = []
    sweeps = [_sweep(rec) for rec in recordings]
    renderer = SceneRenderer(
        triangles,
        window_size=(640, 480),
        with_truth=any(t is not None for t in truths),
        with_sweep=any(s is not None for s in sweeps),
        with_moving=scene is not None and any(m.moving for m in scene.meshes),
        with_lidar=any(rec.lidar is not None for rec in recordings),
    )
    try:
        for k, (rec, imgs) in enumerate(zip(recordings, images)):
            pose = _pose(rec)
            truth_w, level = _truth_world(rec)
            view = renderer.frame(
                pose.position_m,
                pose.rotation[:, 0],
                truth=truth_w,
                truth_level_db=level,
                peaks=peaks_in_world(rec, imgs[method], options.peak_threshold_db),
                sweep=sweeps[k],
                moving_triangles=_moving_triangles(scene, rec),
                lidar=lidar_in_world(rec),
            )
            fig, (a, b) = plt.subplots(
                1,
                2,
                figsize=(12, 5.4),
                gridspec_kw={"width_ratios": [1.2, 1]},
                layout="constrained",
            )
            a.imshow(view)
            a.axis("off")
            a.set_title(_title(rec, indices[k], True), fontsize=10)
            im = draw_fan(b, imgs[method], limit, dr, pixels=600, extent=extent)
            if truths_yx[k] is not None:
                t = truths_yx[k]
                b.scatter(t[:, 0], t[:, 1], s=60, facecolors="none", edgecolors=TRUTH_COLOR, lw=0.8)
            b.set_title(f"{method}, top view; white circles: ray-traced reflectors", fontsize=9)
            fig.colorbar(im, ax=b, shrink=0.8, label=f"dB re strongest ({dr:g} dB range)")
            fig.canvas.draw()
            frames.append(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
            plt.close(fig)
            if progress:
                progress(k + 1, len(recordings))
    finally:
        renderer.close()
    with atomic_path(path) as tmp:
        imageio.mimsave(tmp, frames, format="GIF", duration=0.1, loop=0)
    return Path(path)
