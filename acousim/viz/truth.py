"""Ray-traced echoes marked in the pictures where the sensor sees them, so that
every bright spot can be told apart: an echo shown in the picture's slice, one from
outside the slice that leaks in, or one from behind the array.

Each echo is marked at its apparent position (:attr:`processing.GroundTruth.
apparent_position_sensor_m`): along the direction it arrives from, at half its path
length, where an imaging sonar puts it.  A first-order echo is so marked at its
reflection point; a two-bounce echo (across a hallway and back) beyond its last
reflection, where the image shows it.  A recording written before apparent positions
existed is marked at its paths' last reflections.

A planar array (microphones in the y-z plane) cannot tell front from back: an echo
arriving from sensor-frame (x, y, z) with x < 0 is heard exactly as from its mirror
(-x, y, z).  Such echoes are drawn at their mirror, with their own marker.

Three marks (:data:`MARKS`), in every picture's legend:

- ``in``: in front of the array and inside the picture's slice (the fan's elevation
  band; an elevation-azimuth map's angular grid at its range slice);
- ``off``: in front, outside the slice (a floor point 60 degrees down leaks into the
  fan at its slant range straight ahead; on a map it is drawn at the grid's edge
  nearest its direction);
- ``behind``: behind the array, drawn at its mirror (then placed as above).

Marks never hide the image: only echoes within the picture's dynamic range of the
strongest traced echo are drawn, at most one per resolved cell of the image (the
strongest; :attr:`Reflectors.cell`, the image's range and angular resolution) and
none nearer another than a picture's spacing (:meth:`TruthMarks.thinned`), hollow and
thin.
The direct path is not an echo.  Positions are relative to the array's centre (where
the images' ranges start), sensor frame, m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "MARGIN_DB",
    "MARKS",
    "Reflectors",
    "TruthMarks",
    "as_reflectors",
    "echo_points",
    "elaz_marks",
    "fan_marks",
    "legend_handles",
    "one_per_cell",
    "own_sonar",
    "spaced",
    "seen_positions",
    "shown_paths",
    "truth_level_db",
]

#: matplotlib marker style of each mark (drawn over the inferno colour map)
MARKS = {
    "in": {"marker": "o", "label": "traced echo, where it shows, in this slice"},
    "off": {"marker": "^", "label": "traced echo off the slice"},
    "behind": {"marker": "D", "label": "traced echo from behind the array (at its mirror)"},
    "crosstalk": {
        "marker": "s",
        "label": "another sonar's call (crosstalk), where it shows",
        "color": "#33ddff",
    },
}
EDGE_COLOR = "white"
#: the imaging commands once marked echoes this much below a picture's dynamic range
#: small (dB); they mark none below it now (kept for scripts that pass it)
MARGIN_DB = 10.0
WEAK_SCALE = 0.3  # area of a weak reflector's mark re a strong one's


@dataclass(frozen=True)
class Reflectors:
    """Traced echoes to mark: points_m (N, 3) where the sensor sees them (their
    apparent positions) in the sensor frame from the array centre (m), level_db (N,)
    re the strongest traced echo; the strongest first.  cell: the image's
    resolution (range m, angle rad): at most one mark per resolved cell (None: no
    such limit)."""

    points_m: np.ndarray
    level_db: np.ndarray
    cell: tuple[float, float] | None = None
    crosstalk: np.ndarray | None = None
    """(N,) bool: another sonar's call (a rig's recording); None: none is."""

    def __len__(self) -> int:
        return len(self.level_db)

    def names(self, inside: np.ndarray, behind: np.ndarray) -> np.ndarray:
        """The mark of each (N,): ``"crosstalk"``, else ``"behind"``, ``"in"`` the
        slice (`inside` (N,)) or ``"off"``."""
        out = np.where(behind, "behind", np.where(inside, "in", "off"))
        if self.crosstalk is not None:
            out = np.where(self.crosstalk, "crosstalk", out)
        return out


def as_reflectors(truth) -> Reflectors:
    """Reflectors as given, or bare points (N, 3) at 0 dB."""
    if isinstance(truth, Reflectors):
        return truth
    p = np.asarray(truth, float).reshape(-1, 3)
    return Reflectors(p, np.zeros(len(p)))


@dataclass(frozen=True)
class TruthMarks:
    """Reflectors placed in a picture: xy (N, 2) in the picture's axes' units, mark
    (N,) one of ``"in"``, ``"off"``, ``"behind"``; weak (N,) below the picture's
    dynamic range (drawn small)."""

    xy: np.ndarray
    mark: np.ndarray
    weak: np.ndarray

    def __len__(self) -> int:
        return len(self.mark)

    def thinned(self, min_separation: float) -> TruthMarks:
        """No two marks nearer than `min_separation` (the axes' units): each kept
        in order (:func:`echo_points` puts the strongest first) unless a mark kept
        before it is that near (:func:`spaced`), so that a floor's hundreds of
        scatter points neither hide the picture nor overlap."""
        if not len(self) or min_separation <= 0:
            return self
        keep = spaced(self.xy, min_separation)
        return TruthMarks(self.xy[keep], self.mark[keep], self.weak[keep])

    def draw(self, ax, size: float = 30.0, min_separation: float = 0.0) -> set[str]:
        """Scatter the marks on a matplotlib axis (hollow, thin, white; crosstalk
        cyan), thinned to `min_separation`; returns the marks drawn (for the legend)."""
        marks = self.thinned(min_separation) if min_separation > 0 else self
        drawn = set()
        for name, style in MARKS.items():
            for weak, scale, width in ((False, 1.0, 0.6), (True, WEAK_SCALE, 0.5)):
                k = (marks.mark == name) & (marks.weak == weak)
                if k.any():
                    ax.scatter(
                        marks.xy[k, 0],
                        marks.xy[k, 1],
                        s=size * scale,
                        marker=style["marker"],
                        facecolors="none",
                        edgecolors=style.get("color", EDGE_COLOR),
                        linewidths=width,
                        clip_on=True,
                    )
                    drawn.add(name)
                    if weak:
                        drawn.add("weak")
        return drawn


def own_sonar(rec) -> str | None:
    """The sonar whose recording `rec` is, when its ground truth names the emitter of
    every path (a rig's: :attr:`processing.GroundTruth.emitter`); else None."""
    t = rec.truth
    if t is None or getattr(t, "emitter", None) is None:
        return None
    return rec.metadata.get("sensor")


def shown_paths(truth, own: str | None = None) -> np.ndarray:
    """Which paths (N,) of a ground truth an image shows: every one but the direct
    path (of a rig's recording, its sonar `own`'s: another sonar's call heard
    straight is crosstalk, shown where it is heard)."""
    shown = np.asarray(truth.kind) != "direct"
    emitter = getattr(truth, "emitter", None)
    if own is not None and emitter is not None:
        shown |= np.asarray(emitter) != own
    return shown


def truth_level_db(truth, own: str | None = None) -> np.ndarray:
    """Level (N,) of each ray-traced path of a ground truth in dB re the strongest
    echo; -inf for the direct path (not a reflector) and for a path of no strength.
    `own`: a rig's recording's sonar (:attr:`processing.GroundTruth.emitter`): only
    its own direct path is left out; another sonar's call heard straight is
    crosstalk the image shows, levelled re the same echo (often above it)."""
    amp = np.abs(np.asarray(truth.amplitude, float))
    direct = np.asarray(truth.kind) == "direct"
    shown = shown_paths(truth, own) & (amp > 0)
    level = np.full(amp.shape, -np.inf)
    if shown.any():
        echoes = amp[shown & ~direct]
        ref = echoes.max() if echoes.size else amp[shown].max()
        level[shown] = 20 * np.log10(amp[shown] / ref)
    return level


def seen_positions(truth, centre_sensor_m: np.ndarray) -> np.ndarray:
    """Where each path (N,) of a ground truth shows in an image, from the array
    centre (N, 3), sensor frame, m: its apparent position, or for a file written
    before apparent positions existed, its last reflection (as such files were
    matched and drawn)."""
    p = truth.apparent_position_sensor_m if truth.has_apparent else truth.position_sensor_m
    return np.asarray(p, float) - np.asarray(centre_sensor_m, float)


def echo_points(
    truth,
    array_centre_m: np.ndarray,
    range_db: float,
    cell: tuple[float, float] | None = None,
    own: str | None = None,
) -> Reflectors:
    """The traced echoes (a recording's ground truth) worth drawing, where the sensor
    sees them (apparent positions; a file without them: the last reflections): those
    within `range_db` of the strongest echo, the direct path left out; the strongest
    first.  `cell`: the image's resolution (range m, angle rad), one mark per cell.
    `own`: a rig's recording's sonar: the other sonars' calls it heard (their echoes
    and their calls heard straight) are crosstalk (:attr:`Reflectors.crosstalk`),
    where its image shows them; the levels re the strongest echo of any call."""
    if truth is None or not len(truth):
        return Reflectors(np.zeros((0, 3)), np.zeros(0), cell)
    rig = own is not None and getattr(truth, "emitter", None) is not None
    level = truth_level_db(truth, own if rig else None)
    keep = np.nonzero(level >= -range_db)[0]
    keep = keep[np.argsort(-level[keep], kind="stable")]
    pts = seen_positions(truth, array_centre_m)[keep]
    crosstalk = (np.asarray(truth.emitter) != own)[keep] if rig else None
    return Reflectors(pts, level[keep], cell, crosstalk)


def spaced(points: np.ndarray, distance: float) -> np.ndarray:
    """Indices (K,), in order, of the points (N, D) kept by taking them in order and
    dropping each one within `distance` of a point kept before it (greedy; a k-d
    tree finds the neighbours)."""
    from scipy.spatial import cKDTree

    points = np.asarray(points, float)
    near = cKDTree(points).query_ball_point(points, distance * (1 - 1e-12))
    dropped = np.zeros(len(points), bool)
    for i, others in enumerate(near):
        if not dropped[i]:
            dropped[[j for j in others if j > i]] = True
    return np.flatnonzero(~dropped)


def one_per_cell(keys: np.ndarray) -> np.ndarray:
    """Indices (K,) of the first row of each distinct row of integer `keys` (N, D), in
    their order (the strongest of each cell when the rows are strongest first)."""
    if not len(keys):
        return np.zeros(0, int)
    _, first = np.unique(np.asarray(keys), axis=0, return_index=True)
    return np.sort(first)


def _mirrored(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points with those behind the array (x < 0) mirrored to the front, behind (N,))."""
    p = np.array(points, float).reshape(-1, 3)
    behind = p[:, 0] < 0
    p[behind, 0] *= -1
    return p, behind


def _angles(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(range (N,), azimuth (N,), elevation (N,)) of sensor-frame points, m and rad."""
    r = np.linalg.norm(p, axis=1)
    az = np.arctan2(p[:, 1], p[:, 0])
    el = np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1]))
    return r, az, el


def fan_marks(
    truth,
    max_range_m: float,
    elevation_band_rad: float,
    azimuth_span_rad: tuple[float, float],
    dynamic_range_db: float = np.inf,
) -> TruthMarks:
    """Marks on a fan (top view, range x azimuth; elevation collapsed over
    |elevation| <= `elevation_band_rad`): each reflector where the fan shows its
    echo, at its slant range along its azimuth, as (y, x) in m; those beyond
    `max_range_m` or outside the azimuth span are not drawn.  `truth`:
    :class:`Reflectors` (or points (N, 3) at 0 dB); weak below `dynamic_range_db`."""
    t = as_reflectors(truth)
    p, behind = _mirrored(t.points_m)
    r, az, el = _angles(p)
    shown = (r <= max_range_m) & (az >= azimuth_span_rad[0]) & (az <= azimuth_span_rad[1])
    shown &= t.level_db >= -dynamic_range_db
    inside = np.abs(el) <= elevation_band_rad
    xy = np.column_stack([r * np.sin(az), r * np.cos(az)])
    weak = t.level_db < -dynamic_range_db
    keep = np.flatnonzero(shown)
    if t.cell is not None:  # one per resolved (range, azimuth) cell: the strongest
        dr, da = (max(v, 1e-9) for v in t.cell)
        keep = keep[one_per_cell(np.floor(np.column_stack([r / dr, az / da])[keep]))]
    return TruthMarks(xy[keep], t.names(inside, behind)[keep], weak[keep])


def elaz_marks(
    truth,
    range_m: float,
    tolerance_m: float,
    azimuth_span_rad: tuple[float, float],
    elevation_span_rad: tuple[float, float],
    dynamic_range_db: float = np.inf,
) -> TruthMarks:
    """Marks on an elevation-azimuth map at the range slice `range_m`: reflectors
    within `tolerance_m` of it, as (azimuth, elevation) in degrees; one outside the
    angular grid is drawn at the grid's edge nearest its direction ("off").  `truth`
    as for :func:`fan_marks`."""
    t = as_reflectors(truth)
    p, behind = _mirrored(t.points_m)
    r, az, el = _angles(p)
    near = (np.abs(r - range_m) <= tolerance_m) & (t.level_db >= -dynamic_range_db)
    a = np.clip(az, *azimuth_span_rad)
    e = np.clip(el, *elevation_span_rad)
    inside = (a == az) & (e == el)
    xy = np.rad2deg(np.column_stack([a, e]))
    weak = t.level_db < -dynamic_range_db
    keep = np.flatnonzero(near)
    if t.cell is not None:  # one per resolved direction: the strongest
        da = max(t.cell[1], 1e-9)
        keep = keep[one_per_cell(np.floor(np.column_stack([a, e])[keep] / da))]
    return TruthMarks(xy[keep], t.names(inside, behind)[keep], weak[keep])


def legend_handles(drawn: set[str], dynamic_range_db: float | None = None) -> list:
    """Legend entries (matplotlib Line2D) of the marks drawn (and of the small weak
    ones, "weak" in `drawn`), black on the legend's white."""
    from matplotlib.lines import Line2D

    out = [
        Line2D(
            [],
            [],
            ls="none",
            mfc="none",
            mec=s.get("color", "black"),
            label=s["label"],
            marker=s["marker"],
        )
        for name, s in MARKS.items()
        if name in drawn
    ]
    if "weak" in drawn and dynamic_range_db is not None:
        lo, hi = dynamic_range_db, dynamic_range_db + MARGIN_DB
        out.append(
            Line2D(
                [],
                [],
                ls="none",
                mfc="none",
                mec="black",
                marker="o",
                markersize=6 * WEAK_SCALE**0.5,
                label=f"small: {lo:g} to {hi:g} dB below the strongest traced echo",
            )
        )
    return out
