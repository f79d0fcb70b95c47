"""Imaging recordings (simulated or real) and writing the pictures people look at:
fan images, elevation-azimuth maps, 3D renders of the scene, drive animations."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import signal
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import processing as P
from acousim.imaging.matching import image_resolution, match_peaks
from acousim.imaging.outputs import file_safe
from acousim.scene import load_scene
from acousim.scene.pose import Pose
from acousim.trace.world.build import build_world
from acousim.viz import elaz_figure, fan_figure
from acousim.viz.drive import DriveFigure, DriveView, check_drive_view, write_gif
from acousim.viz.fan import DYNAMIC_RANGE_DB, FAN_ELEVATION_BAND_RAD, common_extent
from acousim.viz.plan import PlanScene, drive_track
from acousim.viz.render3d import (
    FrameContent,
    SceneRenderer,
    import_pyvista,
    legend_entries,
    render_scene,
    sensor_sweep,
)
from acousim.viz.truth import echo_points, fan_marks, own_sonar, truth_level_db
from processing.base import interrupt
from processing.base.atomic import atomic_path
from processing.base.errors import InputError
from processing.base.settings import setting, validate
from processing.imaging.pipeline import RANGE_LIMITS_M, whole_subarray

#: peaks kept within this many dB of each image's strongest cell: the default of
#: the pictures, the peak files, the bags and ``Image.peaks()`` (one home, processing's)
PEAK_THRESHOLD_DB = P.PEAK_THRESHOLD_DB

__all__ = [
    "ImagingOptions",
    "image_recordings",
    "recording_images",
    "peak_positions",
    "peak_table",
    "peaks_in_world",
    "prepare_pictures",
    "write_drive",
    "drive_steps",
    "drive_method",
    "write_pictures",
    "write_stills",
    "still_jobs",
    "PictureJob",
]


#: ImagingOptions' methods when not given
DEFAULT_METHODS: tuple[str, ...] = ("das", "capon-fbss", "music-fbss")
#: the methods an array that is not a uniform rectangular one (eRTIS) is imaged by
#: when the default methods were kept (their smoothing needs a URA): the same
#: methods without it
NON_URA_METHODS = ("das", "capon", "music")


def _as_processing(name: str) -> Any:
    """A field declared as :class:`processing.ProcessingSettings` declares `name` (one
    declaration: its type, unit, range and default)."""
    (decl,) = (f for f in dataclasses.fields(P.ProcessingSettings) if f.name == name)
    return field(default=decl.default, metadata=decl.metadata)


@dataclass(frozen=True)
class ImagingOptions:
    """How recordings are imaged.

    methods : DOA methods (see ``processing.METHODS``); the defaults image an array
        that is not a URA (eRTIS) by :data:`NON_URA_METHODS`.
    azimuth_deg, elevation_deg : (min, max) of the grid, degrees; step_deg its step.
    frequency_hz, n_sources, subarray : the steering frequency (Hz), the MUSIC
        subspace size and the smoothing subarray (rows, columns), as
        :class:`processing.ProcessingSettings` declares them (None: its defaults).
    energy_fraction : range bins kept when their energy is at least this fraction of
        the strongest bin in [min_range_m, max_range_m] (the paper uses 0.5 for one
        reflector; a room needs a lower gate).
    min_range_m : bins nearer than this are ignored (the direct path).
    peak_threshold_db : peaks drawn in the 3D view.
    dynamic_range_db : of every picture (fan, el-az maps, 3D view's reflectors,
        animation, the bag's fan image).
    """

    methods: tuple[str, ...] = DEFAULT_METHODS
    azimuth_deg: tuple[float, float] = setting(  # one default: Grid.degrees()'
        P.GRID_AZIMUTH_DEG, "deg", -90, 90, "azimuth span of the grid", kind="interval"
    )
    elevation_deg: tuple[float, float] = setting(
        P.GRID_ELEVATION_DEG, "deg", -90, 90, "elevation span of the grid", kind="interval"
    )
    step_deg: float = setting(P.GRID_STEP_DEG, "deg", 0.1, 45, "grid step")
    energy_fraction: float = setting(
        P.ProcessingSettings.energy_fraction,  # one default, ProcessingSettings'
        "",
        0,
        1,
        "keep range bins with at least this fraction of the strongest bin's energy "
        "(the paper uses 0.5)",
    )
    min_range_m: float = setting(RANGE_LIMITS_M[0], "m", 0, 1000, "ignore nearer range bins")
    max_range_m: float | None = setting(
        None, "m", 0.01, 1000, "ignore farther range bins", kind="float"
    )
    peak_threshold_db: float = setting(
        PEAK_THRESHOLD_DB,
        "dB",
        -200,
        0,
        "peaks kept within this many dB of each image's strongest cell",
    )
    dynamic_range_db: float = setting(
        DYNAMIC_RANGE_DB, "dB", 1, 200, "levels shown below each picture's strongest cell"
    )
    frequency_hz: float | None = _as_processing("frequency_hz")
    n_sources: int | None = _as_processing("n_sources")
    subarray: tuple[int, int] | None = _as_processing("subarray")
    grid: P.Grid = field(init=False, repr=False)

    def __post_init__(self) -> None:
        validate(self)
        subarray = whole_subarray(self.subarray, "ImagingOptions.subarray")
        object.__setattr__(self, "subarray", subarray)
        for m in self.methods:
            P.check_method(m)
        object.__setattr__(
            self, "grid", P.Grid.degrees(self.azimuth_deg, self.elevation_deg, self.step_deg)
        )

    def settings(self, recording: P.Recording) -> P.ProcessingSettings:
        hi = self.max_range_m or recording.speed_of_sound_m_s * recording.n_samples / (
            2 * recording.sample_rate_hz
        )
        hi = max(hi, self.min_range_m)  # a recording shorter than min_range: no bin
        return P.ProcessingSettings(
            energy_fraction=self.energy_fraction,
            grid=self.grid,
            range_limits_m=(self.min_range_m, hi),
            frequency_hz=self.frequency_hz,
            n_sources=self.n_sources,
            subarray=self.subarray,
        )


def image_recordings(
    recordings: Sequence[P.Recording],
    options: ImagingOptions,
    progress: Callable[[int, int], None] | None = None,
    each: Callable[[int, dict[str, P.Image]], None] | None = None,
) -> list[dict[str, P.Image]]:
    """Images of every recording by every method; `each` (if given) is called with
    each recording's position in `recordings` and its images as soon as they are made."""
    out = []
    for i, rec in enumerate(recordings):
        interrupt.check()  # Ctrl-C (when the command line records it): stop here
        out.append(recording_images(rec, options, i))
        if each:
            each(i, out[-1])
        if progress:
            progress(i + 1, len(recordings))
    return out


def recording_images(
    recording: P.Recording, options: ImagingOptions, position: int = 0
) -> dict[str, P.Image]:
    """The images of one recording by every method of `options`, by method; an
    InputError naming the recording (its `position`) when a method needs a uniform
    rectangular array it does not have."""
    rec = recording
    methods = options.methods
    if rec.array.n_mics and not rec.array.is_ura:
        smooth = [m for m in methods if P.requires_ura(m)]
        if smooth and methods == DEFAULT_METHODS:  # not asked for: the array's own
            methods = NON_URA_METHODS
        elif smooth:
            raise InputError(
                f"recording {position}: array {rec.array.name!r} is not a URA, so "
                f"{', '.join(smooth)} cannot be used; choose das, music, capon "
                "or a wideband (-wb) or broadband (-bb) method"
            )
    return P.acoustic_images(rec, methods, options.settings(rec))


def _pose(rec: P.Recording):
    p = rec.provenance.pose
    if p is None:
        return Pose(np.zeros(3))
    return Pose(np.asarray(p.position_m, float), p.yaw_rad, p.pitch_rad, p.roll_rad, p.time_s)


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


def peak_table(
    recording: P.Recording,
    image: P.Image,
    *,
    threshold_db: float = PEAK_THRESHOLD_DB,
    index: int | None = None,
    window_samples: int = P.ProcessingSettings.window,
) -> P.PeakTable:
    """The peaks of `image` (of `recording`) within `threshold_db` (dB) of its strongest
    cell as rows (:class:`processing.PeakRow`: the columns of ``peaks.csv``), strongest
    first: positions in the sensor and world frames (m, through the recording's pose),
    the grid-edge flag and the traced reflector matched within the image's resolution
    (:mod:`acousim.imaging.matching`; `window_samples`: the STFT window the image was made
    with). `index`: the recording's index in its file (its rows' ``recording``)."""
    pk = image.peaks(threshold_db)
    sensor, world = peak_positions(recording, pk)
    table = pk.table(
        sensor_m=sensor, world_m=world, recording=index, provenance=recording.provenance.kind
    )
    m = match_peaks(recording, pk, image_resolution(recording, image, window_samples))
    return P.PeakTable([dataclasses.replace(row, **_truth(m, k)) for k, row in enumerate(table)])


def _truth(match, k: int) -> dict[str, Any]:
    """The truth columns of peak `k` of a :class:`acousim.imaging.matching.Match` ({}: none)."""
    if match.index[k] < 0:
        return {"truth_note": "" if match.note is None else str(match.note[k])}
    tx, ty, tz = (float(v) for v in match.position_sensor_m[k])
    return {
        "truth_kind": str(match.kind[k]),
        "truth_order": None if match.order is None else int(match.order[k]),
        "truth_object": "" if match.object is None else str(match.object[k]),
        "truth_emitter": "" if match.emitter is None else str(match.emitter[k]),
        "truth_x_m": tx,
        "truth_y_m": ty,
        "truth_z_m": tz,
        "truth_level_db": float(match.level_db[k]),
        "truth_offset_deg": float(np.rad2deg(match.offset_rad[k])),
        "truth_range_offset_m": (
            np.nan if match.range_offset_m is None else float(match.range_offset_m[k])
        ),
        "truth_behind": bool(match.behind[k]),
    }


def peaks_in_world(rec: P.Recording, image: P.Image, threshold_db: float) -> np.ndarray:
    """Image peaks as world points (N, 3): (az, el, range) from the array centre."""
    return peak_positions(rec, image.peaks(threshold_db))[1]


def _scene(rec: P.Recording):
    """The recording's scene, when its file is still there (None for real data).

    Read only for the 3D view and the animation, and only a scene file (.toml): a
    recording cannot make us open any other path."""
    file = rec.provenance.scene_file
    if not file:
        return None
    if Path(file).suffix.lower() != ".toml":
        raise InputError(
            "the recording's scene_file is not a scene file (.toml); "
            "image without the 3D view (--no-3d --no-animation)",
            key="scene_file",
            value=file,
        )
    if not Path(file).is_file():
        return None

    return load_scene(file)  # a scene file that no longer loads is an InputError


def _scene_triangles(scene) -> np.ndarray | None:
    """The faces (F, 3, 3) of the scene's meshes that do not move."""
    if scene is None or not any(not m.moving for m in scene.meshes):
        return None

    if any(m.moving for m in scene.meshes):
        scene = dataclasses.replace(scene, meshes=tuple(m for m in scene.meshes if not m.moving))
    return build_world(scene).triangles


def _moving_triangles(scene, rec: P.Recording) -> np.ndarray | None:
    """The faces (F, 3, 3) of the scene's moving meshes where they are at the start of
    the recording's emission (None: none moves)."""
    if scene is None or not any(m.moving for m in scene.meshes):
        return None

    t = _pose(rec).time_s
    moving = tuple(m.placed_at(t) for m in scene.meshes if m.moving)
    return build_world(dataclasses.replace(scene, meshes=moving)).triangles


def prepare_pictures(
    render_3d: bool = True, animation: bool = True, drive_view: DriveView = "plan"
) -> None:
    """Import what the pictures need (matplotlib, its first figure drawn; pyvista/VTK
    for the 3D views, the animation's with `drive_view` "3d") before a command's work
    starts, so that Ctrl-C never lands in the middle of VTK's import (which could
    crash the interpreter instead of stopping cleanly).  An interrupt during these
    imports is held back and raised once they are done."""
    with _interrupt_after():
        _import_pictures(render_3d, animation and drive_view == "3d")


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


def _import_pictures(render_3d: bool, animation_3d: bool) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401
    import trimesh  # noqa: F401  (the scene's meshes, for the 3D views and the plan)

    if render_3d or animation_3d:
        # VTK's rendering modules (pyvista loads them on first use): imported once,
        # before the command's workers are forked
        import_pyvista().Plotter  # noqa: B018
    _first_figure()


def _first_figure() -> None:
    """Draw a small figure with what the pictures use (an image, a colour bar, marks,
    a legend, titles, constrained layout) into memory: the first figure a process
    draws pays matplotlib's one-time costs (its fonts loaded, its artists' and
    renderer's first use: about 0.3 s), paid here once, before the processes that
    draw the pictures are forked (they inherit it), not by each one's first picture."""
    import io

    import matplotlib.pyplot as plt

    from acousim.viz.render3d import legend_handles

    fig, ax = plt.subplots(figsize=(2, 2), layout="constrained")
    try:
        shown = ax.imshow(np.zeros((4, 4)), interpolation="nearest")
        ax.scatter([0.0], [0.0], s=4)
        ax.set_title("title")
        ax.set_xlabel("x (m)")
        fig.colorbar(shown, ax=ax, label="dB")
        fig.legend(handles=legend_handles([("echo", (1.0, 0.0, 0.0))]))
        fig.suptitle("suptitle")
        fig.canvas.print_figure(io.BytesIO(), format="png", dpi=50)  # written nowhere
    finally:
        plt.close(fig)


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
    """Fan images, elevation-azimuth maps and the 3D render of the first recording
    (:func:`write_stills`), and for several recordings (a trajectory) an animated GIF
    of the drive (:func:`write_drive`: the plan beside the fan; its 3D view:
    ``write_drive(..., view="3d")``).

    indices : the recordings' indices in their file (for the titles; default 0, 1, ...).
    """
    written = write_stills(
        recordings, images, out_dir, options, render_3d=render_3d, indices=indices
    )
    if animation and len(recordings) > 1:
        written += write_drive(
            recordings,
            images,
            out_dir,
            options,
            progress=progress,
            indices=indices,
        )
    return written


def write_stills(
    recordings: Sequence[P.Recording],
    images: Sequence[dict[str, P.Image]],
    out_dir: str | Path,
    options: ImagingOptions,
    *,
    shown: Sequence[int] = (0,),
    indices: Sequence[int] | None = None,
    render_3d: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> list[Path]:
    """Fan images, elevation-azimuth maps and (`render_3d`) the 3D render of the
    recordings at positions `shown` of `recordings`: the files written.

    indices : the recordings' indices in their file (for the titles and, when several
        are shown, the file names: ``fan_N.png``, ``elaz_METHOD_N.png``,
        ``scene3d_N.png``; default 0, 1, ...).
    progress : called ``(done, total)`` after each picture written.
    """
    jobs = still_jobs(
        recordings, images, out_dir, options, shown=shown, indices=indices, render_3d=render_3d
    )
    written: list[Path] = []
    for job in jobs:
        written.append(job())
        if progress is not None:
            progress(len(written), len(jobs))
    return written


def still_jobs(
    recordings: Sequence[P.Recording],
    images: Sequence[dict[str, P.Image]],
    out_dir: str | Path,
    options: ImagingOptions,
    *,
    shown: Sequence[int] = (0,),
    indices: Sequence[int] | None = None,
    render_3d: bool = True,
) -> list[PictureJob]:
    """The pictures of :func:`write_stills`, each a job of its own that writes one
    file (for two processes to share: each needs only its recording), in
    :func:`write_stills`' order: per recording shown, the fan, each method's el-az
    maps, the 3D view."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    trajectory = len(recordings) > 1
    scene = _scene(recordings[shown[0]]) if render_3d else None
    jobs: list[PictureJob] = []
    for k in shown:
        rec, imgs = recordings[k], images[k]
        tag = f"_{indices[k]}" if len(shown) > 1 else ""
        title = _title(rec, indices[k], trajectory)
        limit = _range_limit(rec, options)
        path = out / f"fan{tag}.png"
        draw = functools.partial(_fan_still, rec, imgs, path, options, limit, title)
        jobs.append(PictureJob(path, draw))
        for m, img in imgs.items():
            if img.power.size:
                path = out / f"elaz_{m}{tag}.png"
                draw = functools.partial(_elaz_still, rec, imgs, m, path, options, title)
                jobs.append(PictureJob(path, draw))
        if render_3d:
            path = out / f"scene3d{tag}.png"
            draw = functools.partial(_scene_still, rec, imgs, scene, path, options, title)
            jobs.append(PictureJob(path, draw))
    return jobs


@dataclass(frozen=True)
class PictureJob:
    """One picture to draw: the file it writes (`path`) and `draw`, which writes it
    and returns its path (called as the job is)."""

    path: Path
    draw: Callable[[], Path]

    def __call__(self) -> Path:
        return self.draw()


def write_drive(
    recordings: Sequence[P.Recording],
    images: Sequence[dict[str, P.Image]],
    out_dir: str | Path,
    options: ImagingOptions,
    *,
    progress: Callable[[int, int], None] | None = None,
    indices: Sequence[int] | None = None,
    view: DriveView = "plan",
    tables: Sequence[Mapping[str, P.PeakTable]] | None = None,
) -> list[Path]:
    """The animated GIF of a drive (``drive.gif``; a rig's recordings: one per sonar,
    ``drive_<sonar>.gif``, :func:`drive_parts`): per recording, the plan view (`view`
    "plan": the scene cut at the sensor's height, in the sensor's frame) or the 3D
    view ("3d") beside the fan of the sharpest method imaged, its peaks those of
    `tables` if given (:func:`drive_steps`).  Returns the files written."""
    check_drive_view(view)  # before any work
    jobs = drive_jobs(
        recordings, images, out_dir, options, indices=indices, view=view, tables=tables
    )
    return [job(progress) for job in jobs]


@dataclasses.dataclass(frozen=True)
class DriveJob:
    """One animation of :func:`drive_jobs`: the GIF `path` and `draw`, which draws it
    into a given file, yielding ``(frames drawn, frames)``; called (with an optional
    ``progress(done, total)``), it draws and writes it and returns its path."""

    path: Path
    draw: Callable[[Path], Iterator[tuple[int, int]]]

    def __call__(self, progress: Callable[[int, int], None] | None = None) -> Path:
        with atomic_path(self.path) as tmp:
            for done, total in self.draw(tmp):
                if progress:
                    progress(done, total)
        return self.path


def drive_jobs(
    recordings: Sequence[P.Recording],
    images: Sequence[dict[str, P.Image]],
    out_dir: str | Path,
    options: ImagingOptions,
    *,
    indices: Sequence[int] | None = None,
    view: DriveView = "plan",
    tables: Sequence[Mapping[str, P.PeakTable]] | None = None,
) -> list[DriveJob]:
    """The animations of :func:`write_drive` (the same arguments), one job each
    (:func:`drive_parts`: a rig's sonars each their own), not yet drawn."""
    check_drive_view(view)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    jobs = []
    for name, part in drive_parts(recordings):
        draw = functools.partial(  # drive_steps(..., path) of these recordings
            drive_steps, [recordings[k] for k in part], [images[k] for k in part],
            options=options, indices=[indices[k] for k in part], view=view,
            tables=None if tables is None else [tables[k] for k in part],
        )  # fmt: skip
        jobs.append(DriveJob(out / name, draw))
    return jobs


def drive_parts(recordings: Sequence[P.Recording]) -> list[tuple[str, list[int]]]:
    """The animations of a drive's recordings: (file name, their positions).  One
    sensor's: ``drive.gif`` of them all.  A rig's (several sonars, the metadata's
    ``sensor``): one per sonar, ``drive_<sonar>.gif`` of its recordings (each frame
    in one sensor's frame; interleaved, the plan turned with every firing), in the
    order of each sonar's first recording."""
    names = [rec.metadata.get("sensor") for rec in recordings]
    if len(set(names)) <= 1:
        return [("drive.gif", list(range(len(recordings))))]
    parts: dict[str, list[int]] = {}
    for k, name in enumerate(names):
        parts.setdefault(str(name), []).append(k)
    return [(f"drive_{file_safe(name)}.gif", ks) for name, ks in parts.items()]


def drive_steps(
    recordings: Sequence[P.Recording],
    images: Sequence[dict[str, P.Image]],
    path: str | Path,
    options: ImagingOptions,
    *,
    indices: Sequence[int] | None = None,
    tables: Sequence[Mapping[str, P.PeakTable]] | None = None,
    view: DriveView = "plan",
) -> Iterator[tuple[int, int]]:
    """Draw the drive's animation (:func:`write_drive`, its `view`) into the GIF
    `path` (written as it is: the caller's temporary), yielding ``(frames drawn,
    frames)`` after each frame.

    tables : each recording's peak tables by method, made with the options' peak
        threshold (``acousim.export.images.peak_tables``): the peaks drawn are
        theirs (None: found again here).
    """
    check_drive_view(view)
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    scene = _scene(recordings[0])
    return _animate(recordings, images, Path(path), options, indices, scene, tables, view)


def _fan_still(rec, imgs, path: Path, options: ImagingOptions, limit: float, title: str):
    """The fan of every method of one recording, its traced reflectors marked."""
    dr = options.dynamic_range_db
    truth = _truth_sensor(rec, dr, imgs[drive_method(imgs)], options)
    kw = {"title": title, "truth": truth, "dynamic_range_db": dr}
    return fan_figure(imgs, path, max_range_m=limit, **kw)


def _elaz_still(rec, imgs, method: str, path: Path, options: ImagingOptions, title: str):
    """The el-az maps of one recording's `method`, its traced reflectors marked."""
    dr = options.dynamic_range_db
    truth = _truth_sensor(rec, dr, imgs[drive_method(imgs)], options)
    kw = {"title": title, "truth": truth, "dynamic_range_db": dr}
    tol = _half_range_resolution(rec, imgs[method], options)
    return elaz_figure(imgs[method], path, truth_tolerance_m=tol, **kw)


def _scene_still(rec, imgs, scene, path: Path, options: ImagingOptions, title: str):
    """The 3D view of one recording (the scene's meshes where they are at its
    emission)."""
    moving = _moving_triangles(scene, rec)
    return _render(rec, imgs, _scene_triangles(scene), path, options, moving, title)


def _half_range_resolution(rec: P.Recording, image: P.Image, options: ImagingOptions) -> float:
    """Half the image's range resolution (m): the reflectors an el-az slice may show."""
    return image_resolution(rec, image, options.settings(rec).window).range_m / 2


def _range_limit(rec: P.Recording, options: ImagingOptions) -> float:
    """The farthest range a picture may show: the imaged range, within the simulated
    one (the recording's provenance ``max_range_m``, when it was simulated)."""
    limits = options.settings(rec).range_limits_m
    assert limits is not None  # ImagingOptions.settings sets both ends
    hi = limits[1]
    simulated = rec.provenance.max_range_m
    if simulated is not None:
        hi = min(hi, simulated)
    return float(hi)


def drive_method(imgs: dict[str, P.Image]) -> str:
    """The method drawn in the 3D view and the animation (of a recording's images by
    method): a smoothed one if imaged."""
    for m in ("music-fbss", "capon-fbss", "music-fss", "capon-fss"):
        if m in imgs:
            return m
    return next(iter(imgs))


def _title(rec: P.Recording, index: int, trajectory: bool = False) -> str:
    """'corridor — recording 30, t = 3.0 s': the time only for a trajectory's pose (a
    rig's recording: its sonar's name for the index, the firing time to the ms)."""
    prov = rec.provenance
    p = prov.pose
    moving = p is not None and (trajectory or p.time_s or prov.pose_index)
    sonar = rec.metadata.get("sensor")  # a rig's recording: its sonar, the firing time
    where = f", t = {p.time_s:.{3 if sonar else 1}f} s" if moving and p is not None else ""
    name = f"{prov.scene} ({prov.kind})" if prov.kind == "emulated" and prov.scene else prov.scene
    if sonar:  # 'corridor_rig — front_left, t = 0.200 s'
        return f"{name or prov.kind} — {sonar}{where}"
    return f"{name or prov.kind} — recording {index}{where}"


def _truth_sensor(
    rec: P.Recording,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    image: P.Image | None = None,
    options: ImagingOptions | None = None,
):
    """Ray-traced echoes (:class:`acousim.viz.truth.Reflectors`) where the sensor sees
    them, within `dynamic_range_db` of the strongest echo (the direct path
    excluded), one mark per resolved cell of `image` (made with `options`), or None."""
    cell = None
    if image is not None and image.range_m.size:
        window = (options or ImagingOptions()).settings(rec).window
        res = image_resolution(rec, image, window)
        cell = (res.range_m, res.angle_rad)
    centre = rec.array.positions_m.mean(axis=0)
    found = echo_points(rec.truth, centre, dynamic_range_db, cell, own=own_sonar(rec))
    return found if len(found) else None


#: the 3D view draws the chains of this many of the strongest echoes
CHAINS_DRAWN = 6


def _truth_world(rec: P.Recording) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Where the sensor sees each traced path (its apparent position; a file without
    them: its last reflection), world frame (N, 3), and its level (N,) in dB re the
    strongest echo."""
    truth = rec.truth
    if truth is None or not len(truth):
        return None, None

    where = truth.apparent_position_world_m if truth.has_apparent else truth.position_world_m
    return where, truth_level_db(truth, own_sonar(rec))


def _chains(rec: P.Recording, n: int = CHAINS_DRAWN) -> list[np.ndarray]:
    """The chains (each (K, 3), world frame) of the `n` strongest echoes: from the
    array centre through the first and last interaction back to the centre, then on
    to where the sensor sees it (its apparent position); none for a file without
    them."""
    truth = rec.truth
    if truth is None or not len(truth) or not truth.has_apparent:
        return []
    first_m, last_m, seen_m = (
        truth.first_point_m,
        truth.last_point_m,
        truth.apparent_position_world_m,
    )
    if first_m is None or last_m is None or seen_m is None:
        return []

    level = truth_level_db(truth)
    top = np.argsort(-level, kind="stable")[:n]
    top = top[np.isfinite(level[top])]
    centre = _pose(rec).to_world(rec.array.positions_m.mean(axis=0)[None])[0]
    out = []
    for j in top:
        first, last = first_m[j], last_m[j]
        pts = [centre, first] + ([last] if np.linalg.norm(last - first) > 1e-6 else [])
        out.append(np.array([*pts, centre, seen_m[j]]))
    return out


#: the sensor's sweep during a measurement is drawn when it turns or moves this much
SWEEP_MIN_RAD = np.deg2rad(0.5)
SWEEP_MIN_M = 0.05


def _sweep(rec: P.Recording):
    """The sensor's positions and axes over the recording's window if it moved or
    turned during it (``provenance.motion``), else None (nothing to smear)."""
    motion = rec.provenance.motion
    if motion is None:
        return None
    v = np.asarray(motion.velocity_m_s, float)
    w = np.asarray(motion.angular_velocity_rad_s, float)
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


def _world_points(rows: P.PeakTable) -> np.ndarray:
    """The peak rows' positions in the world frame (N, 3), m."""
    return np.array([[r.world_x_m, r.world_y_m, r.world_z_m] for r in rows], float).reshape(-1, 3)


def _frame_content(rec, img, options, sweep, moving, peaks=None):
    """What the 3D view of `rec` draws: the sensor at its pose, the traced reflectors,
    the peaks of `img` (`peaks`, world frame (N, 3), if found already), the sweep,
    the moving meshes' faces and the LiDAR scan."""
    pose = _pose(rec)
    truth_w, level = _truth_world(rec)
    return FrameContent(
        sensor_position=pose.position_m,
        sensor_axis=pose.rotation[:, 0],
        truth=truth_w,
        truth_level_db=level,
        chains=_chains(rec),
        peaks=peaks_in_world(rec, img, options.peak_threshold_db) if peaks is None else peaks,
        sweep=sweep,
        moving_triangles=moving,
        lidar=lidar_in_world(rec),
        sensor_rotation=pose.rotation,
    )


def _render(rec, imgs, triangles, path, options, moving=None, title=None):
    content = _frame_content(rec, imgs[drive_method(imgs)], options, _sweep(rec), moving)
    render_scene(
        path, content, triangles=triangles, truth_range_db=options.dynamic_range_db, title=title
    )
    return Path(path)


#: the animation's frame delay when the recordings carry no times (ms)
FRAME_DELAY_MS = 100


def frame_delay_ms(recordings: Sequence[P.Recording]) -> int:
    """The GIF's delay between frames (ms): the median time between the recordings'
    poses (the drive plays in real time), 20 ms to 1 s, else :data:`FRAME_DELAY_MS`.
    GIF stores hundredths of a second, so the delay is rounded to 10 ms."""
    times = [r.provenance.pose.time_s for r in recordings if r.provenance.pose is not None]
    step = np.median(np.diff(times)) if len(times) == len(recordings) > 1 else 0.0
    ms = step * 1e3 if step > 0 else FRAME_DELAY_MS
    return int(10 * round(min(max(ms, 20.0), 1000.0) / 10))


def _drive_marks(marks) -> set[str]:
    """The mark kinds a drive's legend lists (the same in every frame, so that the
    frames keep one size): the echoes' and, when a frame holds some, crosstalk."""
    if all(m is None for m in marks):
        return set()
    crosstalk = any(m is not None and np.any(m.mark == "crosstalk") for m in marks)
    return {"in", "off", "behind", "weak"} | ({"crosstalk"} if crosstalk else set())


def _animate(recordings, images, path, options, indices, scene, tables, view: DriveView):
    """The frames of :func:`drive_steps` (`scene`: the recordings' scene, or None),
    yielding ``(frames drawn, frames)``; the GIF written at the end."""
    dr = options.dynamic_range_db
    method = drive_method(images[0])
    limit = min(_range_limit(rec, options) for rec in recordings)
    marks = [_fan_marks(rec, imgs[method], limit, dr) for rec, imgs in zip(recordings, images)]
    # one fitted extent for the whole drive (the axes do not jump between frames)
    kept = [(imgs[method], m) for imgs, m in zip(images, marks) if imgs[method].range_m.size]
    extents = [common_extent([im], limit, dr, m.xy if m else None) for im, m in kept]
    ext = np.array(extents or [(1.0, -1.0, 0.0, 1.0)])
    extent = (ext[:, 0].max(), ext[:, 1].min(), ext[:, 2].min(), ext[:, 3].max())
    frames = []
    sweeps = [_sweep(rec) for rec in recordings]
    left = _left_panel(view, recordings, _scene_triangles(scene), scene, sweeps, marks, dr)
    figure = None
    try:
        for k, (rec, imgs) in enumerate(zip(recordings, images)):
            moving = _moving_triangles(scene, rec)
            peaks = None if tables is None else _world_points(tables[k][method])
            content = _frame_content(rec, imgs[method], options, sweeps[k], moving, peaks)
            drawn = left.frame(content)
            if figure is None:  # laid out once, on the first frame
                figure = DriveFigure(
                    first=imgs[method],
                    extent=extent,
                    max_range_m=limit,
                    dynamic_range_db=dr,
                    **left.figure_keywords(drawn),
                    # the same entries in every frame: the frames keep one size
                    marks=_drive_marks(marks),
                )
            title = _title(rec, indices[k], True)
            frames.append(figure.frame(drawn, imgs[method], marks[k], title))
            yield k + 1, len(recordings)
    finally:
        left.close()
        if figure is not None:
            figure.close()
    write_gif(path, frames, frame_delay_ms(recordings))


def _left_panel(view: DriveView, recordings, triangles, scene, sweeps, marks, dr):
    """The animation's left panel: :class:`_Plan` or :class:`_View3D`."""
    entries = legend_entries(
        with_truth=any(m is not None for m in marks),
        with_sweep=any(s is not None for s in sweeps),
        with_moving=scene is not None and any(m.moving for m in scene.meshes),
        truth_range_db=dr,
        with_lidar=any(rec.lidar is not None for rec in recordings),
    )
    if view == "plan":
        positions = [_pose(rec).position_m for rec in recordings]
        sensors = [rec.metadata.get("sensor") for rec in recordings]  # a rig's sonars
        track = drive_track(positions, sensors if any(sensors) else None)
        return _Plan(PlanScene(triangles=triangles, track=track), entries)
    renderer = SceneRenderer(
        triangles,
        window_size=(640, 480),
        with_truth=any(m is not None for m in marks),
        with_sweep=any(s is not None for s in sweeps),
        with_moving=scene is not None and any(m.moving for m in scene.meshes),
        truth_range_db=dr,
        with_lidar=any(rec.lidar is not None for rec in recordings),
        legend=False,  # below the frame, with the fan's
    ).antialiasing(1)  # none: a third of the render's time; the GIF's palette and the
    # view shrunk to its box (nearest pixel) cost it most of its effect
    return _View3D(renderer)


@dataclasses.dataclass(frozen=True)
class _Plan:
    """The plan view (:mod:`acousim.viz.plan`): each frame's content drawn by the
    figure itself."""

    scene: PlanScene
    entries: list

    def frame(self, content: FrameContent) -> FrameContent:
        return content

    def figure_keywords(self, drawn) -> dict:
        return {"left": self.scene, "entries": self.entries}

    def close(self) -> None:
        pass


@dataclasses.dataclass(frozen=True)
class _View3D:
    """The 3D chase view: each frame rendered offscreen (VTK), its pixels pasted."""

    renderer: SceneRenderer

    def frame(self, content: FrameContent) -> np.ndarray:
        return self.renderer.frame(content)

    def figure_keywords(self, drawn) -> dict:
        return {"left": drawn.shape[:2], "entries": self.renderer.entries}

    def close(self) -> None:
        self.renderer.close()


def _fan_marks(rec: P.Recording, image: P.Image, limit: float, dynamic_range_db: float):
    """The traced reflectors' marks on a recording's fan (None: no ground truth)."""
    truth = _truth_sensor(rec, dynamic_range_db, image)
    if truth is None:
        return None
    a = image.azimuth_rad
    span = (float(a.min()), float(a.max())) if a.size else (-np.pi / 2, np.pi / 2)
    return fan_marks(truth, limit, FAN_ELEVATION_BAND_RAD, span, dynamic_range_db)
