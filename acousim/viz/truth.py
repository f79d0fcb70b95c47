"""Ray-traced reflectors placed in the pictures, so that every bright spot can be told
apart: an echo from a reflector in the picture's slice, one from outside the slice
that leaks in, or one from behind the array.

A planar array (microphones in the y-z plane) cannot tell front from back: a
reflector at sensor-frame (x, y, z) with x < 0 is heard exactly as its mirror
(-x, y, z).  Such reflectors are drawn at their mirror, with their own marker.

Three marks (:data:`MARKS`), in every picture's legend:

- ``in``: in front of the array and inside the picture's slice (the fan's elevation
  band; an elevation-azimuth map's angular grid at its range slice);
- ``off``: in front, outside the slice (a floor point 60 degrees down leaks into the
  fan at its slant range straight ahead; on a map it is drawn at the grid's edge
  nearest its direction);
- ``behind``: behind the array, drawn at its mirror (then placed as above).

Only reflectors within the picture's dynamic range of the strongest traced echo are
drawn (a weaker one cannot show); the direct path is not a reflector.  Positions are
relative to the array's centre (where the images' ranges start), sensor frame, m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MARKS", "TruthMarks", "echo_points", "elaz_marks", "fan_marks", "legend_handles"]

#: matplotlib marker style of each mark (drawn over the inferno colour map)
MARKS = {
    "in": {"marker": "o", "label": "traced reflector in this slice"},
    "off": {"marker": "^", "label": "traced reflector off the slice"},
    "behind": {"marker": "D", "label": "traced reflector behind the array (at its mirror)"},
}
EDGE_COLOR = "white"


@dataclass(frozen=True)
class TruthMarks:
    """Reflectors placed in a picture: xy (N, 2) in the picture's axes' units, mark
    (N,) one of ``"in"``, ``"off"``, ``"behind"``."""

    xy: np.ndarray
    mark: np.ndarray

    def __len__(self) -> int:
        return len(self.mark)

    def draw(self, ax, size: float = 45.0) -> set[str]:
        """Scatter the marks on a matplotlib axis (hollow, white); returns the marks
        drawn (for the legend)."""
        drawn = set()
        for name, style in MARKS.items():
            k = self.mark == name
            if k.any():
                ax.scatter(
                    self.xy[k, 0],
                    self.xy[k, 1],
                    s=size,
                    marker=style["marker"],
                    facecolors="none",
                    edgecolors=EDGE_COLOR,
                    linewidths=0.9,
                    clip_on=True,
                )
                drawn.add(name)
        return drawn


def echo_points(
    truth, array_centre_m: np.ndarray, dynamic_range_db: float
) -> tuple[np.ndarray, np.ndarray]:
    """The traced reflectors worth drawing: (points (N, 3) relative to the array
    centre in the sensor frame, m; level (N,) in dB re the strongest echo), those
    within `dynamic_range_db` of the strongest, the direct path left out."""
    if truth is None or not len(truth):
        return np.zeros((0, 3)), np.zeros(0)
    amp = np.abs(np.asarray(truth.amplitude, float))
    echo = (np.asarray(truth.kind) != "direct") & (amp > 0)
    if not echo.any():
        return np.zeros((0, 3)), np.zeros(0)
    level = np.full(amp.shape, -np.inf)
    level[echo] = 20 * np.log10(amp[echo] / amp[echo].max())
    keep = level >= -dynamic_range_db
    pts = np.asarray(truth.position_sensor_m, float)[keep] - np.asarray(array_centre_m, float)
    return pts, level[keep]


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


def _marks(inside: np.ndarray, behind: np.ndarray) -> np.ndarray:
    return np.where(behind, "behind", np.where(inside, "in", "off"))


def fan_marks(
    points: np.ndarray,
    max_range_m: float,
    elevation_band_rad: float,
    azimuth_span_rad: tuple[float, float],
) -> TruthMarks:
    """Marks on a fan (top view, range x azimuth; elevation collapsed over
    |elevation| <= `elevation_band_rad`): each reflector where the fan shows its
    echo, at its slant range along its azimuth, as (y, x) in m; those beyond
    `max_range_m` or outside the azimuth span are not drawn."""
    p, behind = _mirrored(points)
    r, az, el = _angles(p)
    shown = (r <= max_range_m) & (az >= azimuth_span_rad[0]) & (az <= azimuth_span_rad[1])
    inside = np.abs(el) <= elevation_band_rad
    xy = np.column_stack([r * np.sin(az), r * np.cos(az)])
    return TruthMarks(xy[shown], _marks(inside, behind)[shown])


def elaz_marks(
    points: np.ndarray,
    range_m: float,
    tolerance_m: float,
    azimuth_span_rad: tuple[float, float],
    elevation_span_rad: tuple[float, float],
) -> TruthMarks:
    """Marks on an elevation-azimuth map at the range slice `range_m`: reflectors
    within `tolerance_m` of it, as (azimuth, elevation) in degrees; one outside the
    angular grid is drawn at the grid's edge nearest its direction ("off")."""
    p, behind = _mirrored(points)
    r, az, el = _angles(p)
    near = np.abs(r - range_m) <= tolerance_m
    a = np.clip(az, *azimuth_span_rad)
    e = np.clip(el, *elevation_span_rad)
    inside = (a == az) & (e == el)
    xy = np.rad2deg(np.column_stack([a, e]))
    return TruthMarks(xy[near], _marks(inside, behind)[near])


def legend_handles(drawn: set[str]) -> list:
    """Legend entries (matplotlib Line2D) of the marks drawn, black on the legend's
    white."""
    from matplotlib.lines import Line2D

    return [
        Line2D([], [], ls="none", mfc="none", mec="black", label=s["label"], marker=s["marker"])
        for name, s in MARKS.items()
        if name in drawn
    ]
