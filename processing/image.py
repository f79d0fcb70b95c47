"""3D acoustic images (range x elevation x azimuth) and their peaks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Image", "Peaks", "find_peaks", "to_db"]


def to_db(
    power: np.ndarray, reference: float | None = None, floor_db: float = -120.0
) -> np.ndarray:
    """``10 log10(power / reference)`` clipped below at `floor_db`.

    `reference` defaults to the maximum of `power`; an all-zero input gives `floor_db`
    everywhere (never NaN or inf).
    """
    p = np.asarray(power, dtype=float)
    ref = float(p.max()) if reference is None and p.size else reference
    if not ref or ref <= 0:
        return np.full(p.shape, floor_db)
    with np.errstate(divide="ignore"):
        db = 10 * np.log10(np.maximum(p, 0) / ref)
    return np.maximum(db, floor_db)


@dataclass(frozen=True, eq=False)
class Peaks:
    """Local maxima of an image, strongest first.  P peaks."""

    azimuth_rad: np.ndarray
    """(P,) azimuth of each peak, rad."""
    elevation_rad: np.ndarray
    """(P,) elevation of each peak, rad."""
    range_m: np.ndarray
    """(P,) range of each peak, m."""
    level_db: np.ndarray
    """(P,) level of each peak, dB relative to the image's strongest cell: 0 for the
    strongest peak, at least :func:`find_peaks`' threshold for the others."""

    def __len__(self) -> int:
        return self.level_db.size


@dataclass(frozen=True, eq=False)
class Image:
    """An acoustic image.

    Attributes
    ----------
    power : ndarray, shape (R, E, A)
        Linear spectrum of each kept range bin (power, or MUSIC pseudo-power).
    range_m : ndarray, shape (R,)
    elevation_rad : ndarray, shape (E,)
    azimuth_rad : ndarray, shape (A,)
    method : str
    frequency_hz : float
        Steering frequency.
    bin_range_m : float
        Spacing of the STFT time bins as a range (kept bins may have gaps).
    """

    power: np.ndarray
    range_m: np.ndarray
    elevation_rad: np.ndarray
    azimuth_rad: np.ndarray
    method: str
    frequency_hz: float
    bin_range_m: float = 0.0

    def __post_init__(self) -> None:
        R, E, A = self.power.shape
        if (R, E, A) != (self.range_m.size, self.elevation_rad.size, self.azimuth_rad.size):
            raise ValueError(
                f"image power shape {self.power.shape} does not match its axes "
                f"({self.range_m.size}, {self.elevation_rad.size}, {self.azimuth_rad.size})"
            )

    def db(self, floor_db: float = -120.0) -> np.ndarray:
        """Image in dB relative to its maximum, shape (R, E, A)."""
        return to_db(self.power, floor_db=floor_db)

    def peaks(self, threshold_db: float = -20.0, *, max_peaks: int | None = None) -> Peaks:
        """Local maxima at least `threshold_db` relative to the maximum."""
        return find_peaks(self, threshold_db, max_peaks=max_peaks)

    def fan(self, elevation_rad: float = 0.0) -> np.ndarray:
        """Linear power on the azimuth-range plane at the elevation nearest to the
        given one, shape (R, A) (the top view of the paper's Figs. 13-14)."""
        e = int(np.argmin(np.abs(self.elevation_rad - elevation_rad)))
        return self.power[:, e, :]


#: :func:`to_db`'s floor in :func:`find_peaks` (dB)
_PEAK_FLOOR_DB = -120.0


def _local_maxima(p: np.ndarray, threshold_db: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells of `p` (R, E, A) at least as large as every cell of their 3x3x3
    neighbourhood (clamped at the borders, as ``maximum_filter(mode="nearest")``)
    and within `threshold_db` of the maximum: indices (N, 3) in index order and their
    levels (N,) in dB (:func:`to_db`).  Only the cells above the threshold are
    compared with their neighbours (a few of the image's)."""
    ref = float(p.max())
    if threshold_db - 1.0 <= _PEAK_FLOOR_DB:  # the floor passes: every cell is a candidate
        cand = np.argwhere(p == p)
    else:  # a margin of 1 dB: the exact test below decides
        cand = np.argwhere(p >= ref * 10 ** ((threshold_db - 1.0) / 10))
    level = to_db(p[tuple(cand.T)], ref, _PEAK_FLOOR_DB)
    cand, level = cand[level >= threshold_db], level[level >= threshold_db]
    value = p[tuple(cand.T)]
    top = np.array(p.shape) - 1
    local = np.full(value.shape, -np.inf)
    for step in np.ndindex(3, 3, 3):
        n = np.clip(cand + (np.array(step) - 1), 0, top)
        local = np.maximum(local, p[tuple(n.T)])
    peak = value >= local
    return cand[peak], level[peak]


def find_peaks(image: Image, threshold_db: float = -20.0, *, max_peaks: int | None = None) -> Peaks:
    """Local maxima of the 3D image (a 3x3x3 neighbourhood) above a threshold.

    Plateaus count once (their first cell in index order).  At elevation +-90
    degrees every azimuth is the same direction: those cells take their row's
    maximum first, so a source at the zenith is one peak.
    """
    p = image.power
    if p.size == 0 or p.max() <= 0:
        e = np.empty(0)
        return Peaks(e, e, e, e)
    pole = np.abs(np.abs(image.elevation_rad) - np.pi / 2) < 1e-9
    if pole.any() and image.azimuth_rad.size > 1:
        # every azimuth at +-90 degrees is one direction: one value, so one peak
        p = p.copy()
        p[:, pole, :] = p[:, pole, :].max(axis=2, keepdims=True)
    idx, level = _local_maxima(p, threshold_db)
    # drop later cells of a plateau: a neighbour earlier in index order with equal value
    keep = []
    seen = np.zeros(p.shape, bool)
    for n, (r, e, a) in enumerate(idx):
        sl = tuple(slice(max(i - 1, 0), i + 2) for i in (r, e, a))
        if not seen[sl].any():
            keep.append(n)
        seen[r, e, a] = True
    idx, lv = idx[keep].reshape(-1, 3), level[keep]
    order = np.argsort(-lv, kind="stable")
    if max_peaks is not None:
        order = order[:max_peaks]
    idx, lv = idx[order], lv[order]
    return Peaks(
        azimuth_rad=image.azimuth_rad[idx[:, 2]],
        elevation_rad=image.elevation_rad[idx[:, 1]],
        range_m=image.range_m[idx[:, 0]],
        level_db=lv,
    )
