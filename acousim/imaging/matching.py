"""Image peaks matched to the traced reflectors within the image's resolution, so that
peaks can be scored against truth without our code (``peaks.csv``), and the peaks
that may not be peaks (a maximum on the grid's edge) flagged.

Resolution of an image (:class:`Resolution`):

- range: the STFT window as a range, ``c * window / (2 fs)`` (an echo spreads over
  the bins whose window holds it); a broadband image's range bin;
- angle: the array's Rayleigh limit at the steering frequency, ``c / (f D)`` rad with
  D the largest distance between two microphones, and at least the grid step.

A traced reflector matches a peak when its range from the array centre is within
half the range resolution of the peak's and its direction within the angular
resolution; one behind the array (x < 0 in the sensor frame) is heard as its mirror
(-x, y, z) and matched as such.  Of several, the strongest is the match.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import processing as P
from acousim.viz.truth import truth_level_db

__all__ = ["Match", "Resolution", "image_resolution", "match_peaks", "on_grid_edge"]


@dataclass(frozen=True)
class Resolution:
    """An image's resolution: range_m (m) and angle_rad (rad)."""

    range_m: float
    angle_rad: float


def image_resolution(rec: P.Recording, image: P.Image, window_samples: int) -> Resolution:
    """The resolution of `image` of `rec` (see the module docstring); `window_samples`
    is the STFT window of the processing settings."""
    c, fs = rec.speed_of_sound_m_s, rec.sample_rate_hz
    rng = c * window_samples / (2 * fs)
    if P.parse_method(image.method).family == "broadband":
        rng = max(image.bin_range_m, c / (2 * fs))
    pos = np.asarray(rec.array.positions_m, float)
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1).max() if len(pos) > 1 else 0.0
    f = image.frequency_hz if image.frequency_hz > 0 else max(rec.waveform.band_hz)
    angle = c / (f * d) if d > 0 else np.pi
    step = _grid_step(image)
    return Resolution(float(rng), float(min(max(angle, step), np.pi)))


def _grid_step(image: P.Image) -> float:
    steps = [np.min(np.diff(a)) for a in (image.azimuth_rad, image.elevation_rad) if a.size > 1]
    return float(max(steps)) if steps else 0.0


def on_grid_edge(image: P.Image, peaks: P.Peaks) -> np.ndarray:
    """Whether each peak (N,) lies on the first or last azimuth or elevation of the
    grid: a maximum there may be the flank of an echo from outside the grid."""
    if peaks.on_grid_edge is not None:
        return np.asarray(peaks.on_grid_edge, bool)
    return P.on_grid_edge(image, peaks.azimuth_rad, peaks.elevation_rad)


@dataclass(frozen=True)
class Match:
    """The traced reflector matched to each of N peaks; index -1 where none.

    index (N,) into the recording's ground truth; position_sensor_m (N, 3) the
    reflector as traced (sensor frame, m; NaN where none); behind (N,) heard as its
    mirror; offset_rad (N,) angle between the peak and the (mirrored) reflector;
    level_db (N,) the reflector's level re the strongest traced echo; kind (N,).
    """

    index: np.ndarray
    position_sensor_m: np.ndarray
    behind: np.ndarray
    offset_rad: np.ndarray
    level_db: np.ndarray
    kind: np.ndarray


def match_peaks(rec: P.Recording, peaks: P.Peaks, resolution: Resolution) -> Match:
    """Each peak's traced reflector within `resolution` (see the module docstring)."""
    n = len(peaks)
    empty = Match(
        np.full(n, -1),
        np.full((n, 3), np.nan),
        np.zeros(n, bool),
        np.full(n, np.nan),
        np.full(n, np.nan),
        np.full(n, "", dtype=object),
    )
    t = rec.truth
    if t is None or not len(t) or not n:
        return empty
    level = truth_level_db(t)  # -inf: the direct path
    echo = np.isfinite(level)
    if not echo.any():
        return empty
    p = np.asarray(t.position_sensor_m, float) - rec.array.positions_m.mean(axis=0)
    behind = p[:, 0] < 0
    m = p.copy()
    m[behind, 0] *= -1
    r_t = np.linalg.norm(m, axis=1)
    u_t = m / np.maximum(r_t, 1e-12)[:, None]
    ce = np.cos(peaks.elevation_rad)
    u_p = np.column_stack(
        [
            ce * np.cos(peaks.azimuth_rad),
            ce * np.sin(peaks.azimuth_rad),
            np.sin(peaks.elevation_rad),
        ]
    )
    offset = np.arccos(np.clip(u_p @ u_t.T, -1.0, 1.0))  # (N, paths)
    ok = (
        echo[None]
        & (np.abs(r_t[None] - np.asarray(peaks.range_m)[:, None]) <= resolution.range_m / 2)
        & (offset <= resolution.angle_rad)
    )
    idx = np.where(ok.any(axis=1), np.argmax(np.where(ok, level[None], -np.inf), axis=1), -1)
    hit = idx >= 0
    j = idx[hit]
    pos, off, lvl, kind = (
        empty.position_sensor_m.copy(),
        empty.offset_rad.copy(),
        empty.level_db.copy(),
        empty.kind.copy(),
    )
    pos[hit] = np.asarray(t.position_sensor_m, float)[j]
    off[hit] = offset[np.nonzero(hit)[0], j]
    lvl[hit] = level[j]
    kind[hit] = np.asarray(t.kind)[j]
    bh = np.zeros(n, bool)
    bh[hit] = behind[j]
    return Match(idx, pos, bh, off, lvl, kind)
