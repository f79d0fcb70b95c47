"""An image's peaks as :class:`Peak` (degrees at this boundary: the report's JSON), and
two images' peaks paired one to one by position (:func:`match_peaks`,
:func:`scipy.optimize.linear_sum_assignment`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

import processing as P

__all__ = ["MatchTolerance", "Peak", "image_peaks", "match_peaks", "peak_array"]


@dataclass(frozen=True)
class Peak:
    """One image peak: range (m), azimuth and elevation (degrees), level (dB re the
    image's maximum)."""

    range_m: float
    azimuth_deg: float
    elevation_deg: float
    level_db: float


def image_peaks(peaks: P.Peaks) -> list[Peak]:
    """An image's peaks (:meth:`processing.Image.peaks`) as :class:`Peak`, in their order."""
    return [
        Peak(float(r), float(np.rad2deg(a)), float(np.rad2deg(e)), float(lv))
        for r, a, e, lv in zip(
            peaks.range_m, peaks.azimuth_rad, peaks.elevation_rad, peaks.level_db
        )
    ]


def peak_array(peaks: Sequence[Peak]) -> np.ndarray:
    """Peaks as a table (N, 4): range (m), azimuth, elevation (degrees), level (dB)."""
    return np.array(
        [[p.range_m, p.azimuth_deg, p.elevation_deg, p.level_db] for p in peaks]
    ).reshape(-1, 4)


@dataclass(frozen=True)
class MatchTolerance:
    """How far apart two paired peaks may be: the cost of a pair is its range
    difference over `range_m` (m) plus its angle difference over `angle_deg`
    (degrees); pairs costing more than 2 are not made."""

    range_m: float = 0.3
    angle_deg: float = 15.0


def match_peaks(
    a: np.ndarray, b: np.ndarray, tol: MatchTolerance = MatchTolerance()
) -> tuple[list[tuple[int, int]], list[int], list[int]]:
    """One-to-one matching of peak tables (N, 4) (:func:`peak_array`: range, az, el,
    level): pairs, only-a, only-b."""
    if len(a) == 0 or len(b) == 0:
        return [], list(range(len(a))), list(range(len(b)))
    cost = (
        np.abs(a[:, None, 0] - b[None, :, 0]) / tol.range_m
        + np.hypot(a[:, None, 1] - b[None, :, 1], a[:, None, 2] - b[None, :, 2]) / tol.angle_deg
    )
    ia, ib = linear_sum_assignment(cost)
    pairs = [(int(i), int(j)) for i, j in zip(ia, ib) if cost[i, j] <= 2.0]
    ma = {i for i, _ in pairs}
    mb = {j for _, j in pairs}
    return (
        pairs,
        [i for i in range(len(a)) if i not in ma],
        [j for j in range(len(b)) if j not in mb],
    )
