"""Image peaks matched to the traced reflectors within the image's resolution, so that
peaks can be scored against truth without our code (``peaks.csv``), and the peaks
that may not be peaks (a maximum on the grid's edge) flagged.

Resolution of an image (:class:`Resolution`):

- range: the STFT window as a range, ``c * window / (2 fs)`` (an echo spreads over
  the bins whose window holds it); a broadband image's range bin;
- angle: the array's Rayleigh limit at the steering frequency, ``c / (f D)`` rad with
  D the largest distance between two microphones, and at least the grid step.

A traced path matches a peak when it shows in the peak's resolution cell: its
apparent position (where the sensor sees it: along its arrival direction at half
its path length, :attr:`processing.GroundTruth.apparent_position_sensor_m`) lies
within half the range resolution of the peak's range and within half the angular
resolution of its direction (the cell of one resolution's width centred on the
peak: a path farther off belongs to the next cell, or for a peak on the grid's
edge, outside the grid).  A two-bounce echo is thus matched where the image
shows it, not at its last reflection.  One behind the array (x < 0 in the sensor
frame) is heard as its mirror (-x, y, z) and matched as such.  Of several, the
strongest is the match; a peak with none is unmatched and says why
(:attr:`Match.note`), a peak on the grid's edge too (its echo may lie outside the
grid: it is not matched to a path beyond its cell).  A file written before the
apparent positions existed is matched at its paths' last reflections.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

import processing as P
from acousim.viz.truth import own_sonar, seen_positions, truth_level_db

__all__ = [
    "Match",
    "Resolution",
    "image_resolution",
    "match_peaks",
    "on_grid_edge",
    "peak_directions",
    "seen_positions",
]


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
    grid: a maximum there may be the flank of an echo from outside the grid.  A peak
    at a pole (elevation +-90 degrees, one direction whatever the azimuth) is not."""
    if peaks.on_grid_edge is not None:
        return np.asarray(peaks.on_grid_edge, bool)
    return P.on_grid_edge(image, peaks.azimuth_rad, peaks.elevation_rad)


#: why a peak has no match (:attr:`Match.note`)
NO_TRUTH = "no ground truth"
NOT_IN_CELL = "no traced path within the resolution cell"
EDGE_NOT_IN_CELL = "on the grid's edge; no traced path within the resolution cell"


@dataclass(frozen=True)
class Match:
    """The traced path matched to each of N peaks; index -1 where none.

    index (N,) into the recording's ground truth; position_sensor_m (N, 3) where the
    path shows in the image (its apparent position, sensor frame, m; for a file
    without apparent positions, its last reflection; NaN where none); behind (N,)
    heard as its mirror; offset_rad (N,) angle between the peak and the
    (mirrored) path; range_offset_m (N,) the path's apparent range less the peak's;
    level_db (N,) the path's level re the strongest traced echo; kind (N,), order
    (N,) (-1 where none), object (N,) its object's name ("" where none or not known);
    note (N,) why a peak has no match ("" where it has one); emitter (N,) the sonar
    whose call the path carries (a rig's recording; "" otherwise or where none).
    """

    index: NDArray[np.int_]
    position_sensor_m: NDArray[np.float64]
    behind: NDArray[np.bool_]
    offset_rad: NDArray[np.float64]
    level_db: NDArray[np.float64]
    kind: NDArray[np.object_]
    order: NDArray[np.int_] | None = None
    object: NDArray[np.object_] | None = None
    range_offset_m: NDArray[np.float64] | None = None
    note: NDArray[np.object_] | None = None
    emitter: NDArray[np.object_] | None = None


def _empty(n: int, note: str) -> Match:
    return Match(
        np.full(n, -1),
        np.full((n, 3), np.nan),
        np.zeros(n, bool),
        np.full(n, np.nan),
        np.full(n, np.nan),
        np.full(n, "", dtype=object),
        np.full(n, -1),
        np.full(n, "", dtype=object),
        np.full(n, np.nan),
        np.full(n, note, dtype=object),
        np.full(n, "", dtype=object),
    )


def peak_directions(peaks: P.Peaks) -> np.ndarray:
    """Unit directions (N, 3) of peaks, sensor frame (a pole is one direction)."""
    ce = np.cos(peaks.elevation_rad)
    return np.column_stack(
        [
            ce * np.cos(peaks.azimuth_rad),
            ce * np.sin(peaks.azimuth_rad),
            np.sin(peaks.elevation_rad),
        ]
    ).reshape(-1, 3)


def match_peaks(
    rec: P.Recording,
    peaks: P.Peaks,
    resolution: Resolution,
    edge: np.ndarray | None = None,
) -> Match:
    """Each peak's traced path within `resolution` (see the module docstring): the
    strongest whose apparent position lies in the peak's resolution cell.  `edge`
    (N,): the peaks on the grid's edge (:func:`on_grid_edge`), for the note of
    those left unmatched."""
    n = len(peaks)
    t = rec.truth
    if t is None or not len(t) or not n:
        return _empty(n, NO_TRUTH if t is None or not len(t) else "")
    # -inf: the direct path (a rig's: its own sonar's; another's call is crosstalk)
    level = truth_level_db(t, own_sonar(rec))
    echo = np.isfinite(level)
    if not echo.any():
        return _empty(n, NO_TRUTH)
    p = seen_positions(t, rec.array.positions_m.mean(axis=0))
    behind = p[:, 0] < 0
    m = p.copy()
    m[behind, 0] *= -1
    r_t = np.linalg.norm(m, axis=1)
    u_t = m / np.maximum(r_t, 1e-12)[:, None]
    offset = np.arccos(np.clip(peak_directions(peaks) @ u_t.T, -1.0, 1.0))  # (N, paths)
    dr = r_t[None] - np.asarray(peaks.range_m)[:, None]
    in_cell = (np.abs(dr) <= resolution.range_m / 2) & (offset <= resolution.angle_rad / 2)
    ok = echo[None] & in_cell
    idx = np.where(ok.any(axis=1), np.argmax(np.where(ok, level[None], -np.inf), axis=1), -1)
    hit = idx >= 0
    edge = np.zeros(n, bool) if edge is None else np.asarray(edge, bool)
    out = _empty(n, "")
    out.note[~hit] = np.where(edge[~hit], EDGE_NOT_IN_CELL, NOT_IN_CELL)
    j, rows = idx[hit], np.nonzero(hit)[0]
    out.index[hit] = j
    out.position_sensor_m[hit] = p[j] + rec.array.positions_m.mean(axis=0)
    out.offset_rad[hit] = offset[rows, j]
    out.range_offset_m[hit] = dr[rows, j]
    out.level_db[hit] = level[j]
    out.kind[hit] = np.asarray(t.kind)[j]
    out.order[hit] = t.order[j]
    out.object[hit] = t.object_name()[j]
    out.behind[hit] = behind[j]
    if t.emitter is not None:
        out.emitter[hit] = np.asarray(t.emitter)[j]
    return out
