"""Imaging recordings (simulated or real) and writing the pictures people look at:
fan images, elevation-azimuth maps, 3D renders of the scene, drive animations."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import processing as P

__all__ = ["ImagingOptions", "image_recordings", "peaks_in_world", "write_pictures"]


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
    step_deg: float = 2.0
    energy_fraction: float = P.ProcessingSettings.energy_fraction  # one declaration
    min_range_m: float = P.ProcessingSettings.range_limits_m[0]
    max_range_m: float | None = None
    peak_threshold_db: float = -10.0
    grid: P.Grid = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for m in self.methods:
            if m not in P.METHODS:
                raise ValueError(f"unknown method {m!r}; choose from {', '.join(P.METHODS)}")
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
        if rec.array.n_mics and not rec.array.is_ura:
            smooth = [m for m in options.methods if P.requires_ura(m)]
            if smooth:
                raise ValueError(
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

    p = rec.metadata.get("pose")
    if not p:
        return Pose(np.zeros(3))
    return Pose(
        p["position_m"],
        *np.deg2rad([p["yaw_deg"], p["pitch_deg"], p["roll_deg"]]),
        time_s=p.get("time_s", 0.0),
    )


def peaks_in_world(rec: P.Recording, image: P.Image, threshold_db: float) -> np.ndarray:
    """Image peaks as world points (N, 3): (az, el, range) from the array centre."""
    pk = image.peaks(threshold_db)
    centre = rec.array.positions_m.mean(axis=0)
    d = np.column_stack(
        [
            np.cos(pk.elevation_rad) * np.cos(pk.azimuth_rad),
            np.cos(pk.elevation_rad) * np.sin(pk.azimuth_rad),
            np.sin(pk.elevation_rad),
        ]
    )
    return _pose(rec).to_world(centre + pk.range_m[:, None] * d)


def _scene_triangles(rec: P.Recording) -> np.ndarray | None:
    file = rec.metadata.get("scene_file")
    if not file or not Path(file).is_file():
        return None
    from acousim.scene import load_scene
    from acousim.trace.geometry import build_world

    scene = load_scene(file)
    return build_world(scene).triangles if scene.meshes else None


def write_pictures(
    recordings: Sequence[P.Recording],
    images: Sequence[dict[str, P.Image]],
    out_dir: str | Path,
    options: ImagingOptions,
    *,
    render_3d: bool = True,
    animation: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> list[Path]:
    """Fan images and elevation-azimuth maps of the first recording, its 3D render,
    and for several recordings (a trajectory) an animated GIF of the drive."""
    from acousim.viz import elaz_figure, fan_figure

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    first, imgs = recordings[0], images[0]
    truth_sensor = _truth_sensor(first)
    written.append(fan_figure(imgs, out / "fan.png", truth=truth_sensor, title=_title(first, 0)))
    for m, img in imgs.items():
        if img.power.size:
            written.append(elaz_figure(img, out / f"elaz_{m}.png"))
    triangles = _scene_triangles(first) if render_3d or animation else None
    if render_3d:
        written.append(_render(first, imgs, triangles, out / "scene3d.png", options))
    if animation and len(recordings) > 1:
        written.append(
            _animate(recordings, images, triangles, out / "drive.gif", options, progress)
        )
    return written


def _sharpest(imgs: dict[str, P.Image]) -> str:
    """The method drawn in the 3D view and the animation: a smoothed one if imaged."""
    for m in ("music-fbss", "capon-fbss", "music-fss", "capon-fss"):
        if m in imgs:
            return m
    return next(iter(imgs))


def _title(rec: P.Recording, i: int) -> str:
    p = rec.metadata.get("pose")
    where = f", t = {p['time_s']:.1f} s" if p else ""
    kind = "simulated" if rec.metadata.get("simulated") else "real"
    return f"{rec.metadata.get('scene', kind)} — recording {i}{where}"


def _truth_sensor(rec: P.Recording) -> np.ndarray | None:
    t = rec.metadata.get("truth")
    if not t:
        return None
    pts = np.asarray(t["position_sensor_m"], float).reshape(-1, 3)
    kind = np.asarray(t["kind"])
    amp = np.asarray(t["amplitude"], float)
    echo = kind != "direct"
    if not echo.any():
        return None
    strong = echo & (amp >= amp[echo].max() * 10 ** (-20 / 20))
    return pts[strong]


def _render(rec, imgs, triangles, path, options):
    from acousim.viz.render3d import render_scene

    pose = _pose(rec)
    method = _sharpest(imgs)
    truth = rec.metadata.get("truth")
    truth_w = None
    if truth:
        pts = np.asarray(truth["position_world_m"], float).reshape(-1, 3)
        truth_w = pts[np.asarray(truth["kind"]) != "direct"]
    render_scene(
        path,
        triangles=triangles,
        sensor_position=pose.position_m,
        sensor_axis=pose.rotation[:, 0],
        truth=truth_w,
        peaks=peaks_in_world(rec, imgs[method], options.peak_threshold_db),
    )
    return Path(path)


def _animate(recordings, images, triangles, path, options, progress):
    import imageio.v2 as imageio
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acousim.viz.fan import draw_fan
    from acousim.viz.render3d import SceneRenderer

    method = _sharpest(images[0])
    max_range = max(float(im[method].range_m.max()) for im in images if im[method].range_m.size)
    frames = []
    renderer = SceneRenderer(triangles, window_size=(560, 420))
    try:
        for i, (rec, imgs) in enumerate(zip(recordings, images)):
            pose = _pose(rec)
            view = renderer.frame(
                pose.position_m,
                pose.rotation[:, 0],
                peaks=peaks_in_world(rec, imgs[method], options.peak_threshold_db),
            )
            fig, (a, b) = plt.subplots(
                1, 2, figsize=(10, 4.2), gridspec_kw={"width_ratios": [1.35, 1]}
            )
            a.imshow(view)
            a.axis("off")
            a.set_title(_title(rec, i), fontsize=9)
            draw_fan(b, imgs[method], max_range, 30.0, pixels=500)  # ~400 px in the frame
            b.set_title(f"{method}, top view (dB)", fontsize=9)
            fig.canvas.draw()
            frames.append(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
            plt.close(fig)
            if progress:
                progress(i + 1, len(recordings))
    finally:
        renderer.close()
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.part.gif")
    imageio.mimsave(tmp, frames, duration=0.1, loop=0)
    os.replace(tmp, path)
    return path
