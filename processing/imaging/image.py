"""3D acoustic images (range x elevation x azimuth) and their peaks."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter

from processing.base.kernels import optional_kernel
from processing.imaging.peak_table import PeakRow, PeakTable

__all__ = ["Image", "Peaks", "find_peaks", "to_db", "PEAK_THRESHOLD_DB", "on_grid_edge"]

#: peaks are kept within this many dB of each image's strongest cell: the default of
#: :meth:`Image.peaks`, the command line, its pictures and its files
PEAK_THRESHOLD_DB = -10.0


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
    """Local maxima of an image, strongest first.  P peaks.

    The arrays below, and rows: ``len(peaks)``, ``peaks[0]``, ``for row in peaks``
    give :class:`processing.PeakRow` s, the columns of ``peaks.csv`` (degrees, metres,
    dB; :meth:`table`); ``peaks.to_records()`` and ``peaks.as_dict()`` feed pandas or
    polars. An image alone has no recording: the sensor frame's origin is the array
    centre, the world frame is the sensor frame and there is no truth;
    :func:`acousim.peak_table` fills those from the recording.
    """

    azimuth_rad: np.ndarray
    """(P,) azimuth of each peak, rad."""
    elevation_rad: np.ndarray
    """(P,) elevation of each peak, rad."""
    range_m: np.ndarray
    """(P,) range of each peak, m."""
    level_db: np.ndarray
    """(P,) level of each peak, dB relative to the image's strongest cell: 0 for the
    strongest peak, at least :func:`find_peaks`' threshold for the others."""

    method: str = ""
    """The image's method (``""``: not known)."""
    on_grid_edge: np.ndarray | None = None
    """(P,) bool: on the first or last azimuth or elevation of the grid (a maximum
    there may be the flank of an echo from outside it); None: not known."""

    def __len__(self) -> int:
        return self.level_db.size

    def __repr__(self) -> str:
        return "Peaks" + repr(self.table()).removeprefix("PeakTable")

    def table(
        self,
        *,
        sensor_m: np.ndarray | None = None,
        world_m: np.ndarray | None = None,
        recording: int | None = None,
        provenance: str = "",
    ) -> PeakTable:
        """The peaks as rows (:class:`processing.PeakTable`). `sensor_m`, `world_m`
        (P, 3): the peaks in the sensor and world frames, m (default: from the origin
        as the array centre; the world frame the sensor frame); `recording`: the
        recording's index in its file; `provenance`: its kind (the columns of
        ``peaks.csv``; :func:`acousim.peak_table` fills them from a recording)."""
        edge = np.zeros(len(self), bool) if self.on_grid_edge is None else self.on_grid_edge
        if sensor_m is None:
            sensor_m = _unit_vectors(self.azimuth_rad, self.elevation_rad) * self.range_m[:, None]
        world_m = sensor_m if world_m is None else world_m
        sensor_m, world_m = np.asarray(sensor_m, float), np.asarray(world_m, float)
        rows = []
        for k in range(len(self)):
            s, w = sensor_m[k].tolist(), world_m[k].tolist()
            rows.append(
                PeakRow(
                    recording=recording,
                    method=self.method,
                    range_m=float(self.range_m[k]),
                    azimuth_deg=float(np.rad2deg(self.azimuth_rad[k])),
                    elevation_deg=float(np.rad2deg(self.elevation_rad[k])),
                    level_db=float(self.level_db[k]),
                    x_m=s[0],
                    y_m=s[1],
                    z_m=s[2],
                    world_x_m=w[0],
                    world_y_m=w[1],
                    world_z_m=w[2],
                    on_grid_edge=bool(edge[k]),
                    provenance=provenance,
                )
            )
        return PeakTable(rows)

    def __getitem__(self, k: int) -> PeakRow:
        """Peak `k` as a row (strongest first)."""
        return self.table()[k]

    def __iter__(self) -> Iterator[PeakRow]:
        return iter(self.table())

    def to_records(self) -> list[dict]:
        """One {column: value} dict per peak (:meth:`PeakTable.to_records`)."""
        return self.table().to_records()

    def as_dict(self) -> dict[str, list]:
        """{column: values} (:meth:`PeakTable.as_dict`)."""
        return self.table().as_dict()


def _unit_vectors(azimuth_rad: np.ndarray, elevation_rad: np.ndarray) -> np.ndarray:
    """Unit vectors (P, 3) of directions (sensor frame: x forward, y left, z up)."""
    ce = np.cos(elevation_rad)
    return np.column_stack(
        [ce * np.cos(azimuth_rad), ce * np.sin(azimuth_rad), np.sin(elevation_rad)]
    ).reshape(-1, 3)


def on_grid_edge(image: Image, azimuth_rad, elevation_rad) -> np.ndarray:
    """Whether each direction (azimuth_rad, elevation_rad: (P,), rad) lies on the first
    or last azimuth or elevation of the image's grid (P,) bool: a maximum there may be
    the flank of an echo from outside it.  A direction at a pole (elevation +-90
    degrees: one direction whatever the azimuth, the grid all round it) is not."""
    az = np.asarray(azimuth_rad, float).reshape(-1)
    el = np.asarray(elevation_rad, float).reshape(-1)
    out = np.zeros(az.size, bool)
    for axis, values in ((image.azimuth_rad, az), (image.elevation_rad, el)):
        if axis.size > 1:
            tol = 1e-9 + 1e-6 * abs(axis[1] - axis[0])
            out |= (np.abs(values - axis.min()) <= tol) | (np.abs(values - axis.max()) <= tol)
    return out & ~(np.abs(np.abs(el) - np.pi / 2) < 1e-9)


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
        Steering frequency, Hz, of a narrowband image.  A wideband (``-wb``) image
        sums several frequencies of the band; its value is the narrowband snapshot's
        frequency that selected its range bins.  A broadband (``-bb``) image is
        steered in time; its value is the centre of the call's band
        (docs/processing.md, "Images").
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

    def __repr__(self) -> str:
        """One line: method, shape, steering frequency and the axes' spans (not the
        power: ``image.power`` holds it)."""
        R, E, A = self.power.shape

        def span(values: np.ndarray, unit: str, scale: float = 1.0) -> str:
            if values.size == 0:
                return "none"
            lo, hi = float(values.min()) * scale, float(values.max()) * scale
            return f"{lo:.4g}..{hi:.4g} {unit}"

        deg = 180 / np.pi
        return (
            f"Image({self.method!r}, {R} x {E} x {A} (range x elevation x azimuth), "
            f"{self.frequency_hz:.0f} Hz, range {span(self.range_m, 'm')}, "
            f"elevation {span(self.elevation_rad, 'deg', deg)}, "
            f"azimuth {span(self.azimuth_rad, 'deg', deg)})"
        )

    def db(self, floor_db: float = -120.0) -> np.ndarray:
        """Image in dB relative to its maximum, shape (R, E, A)."""
        return to_db(self.power, floor_db=floor_db)

    def peaks(
        self, threshold_db: float = PEAK_THRESHOLD_DB, *, max_peaks: int | None = None
    ) -> Peaks:
        """Local maxima at least `threshold_db` (dB, default the command line's
        :data:`PEAK_THRESHOLD_DB`) relative to the maximum (:func:`find_peaks`)."""
        return find_peaks(self, threshold_db, max_peaks=max_peaks)

    def fan(self, elevation_rad: float = 0.0) -> np.ndarray:
        """Linear power on the azimuth-range plane at the elevation nearest to the
        given one, shape (R, A) (the top view of the paper's Figs. 13-14)."""
        e = int(np.argmin(np.abs(self.elevation_rad - elevation_rad)))
        return self.power[:, e, :]


#: :func:`to_db`'s floor in :func:`find_peaks` (dB)
_PEAK_FLOOR_DB = -120.0


def _local_maxima(p: np.ndarray, threshold_db: float, ref: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells of `p` (R, E, A) at least as large as every cell of their 3x3x3
    neighbourhood (clamped at the borders, as ``maximum_filter(mode="nearest")``)
    and within `threshold_db` of the maximum `ref` (``p.max()``): indices (N, 3) in
    index order and their levels (N,) in dB (:func:`to_db`).  Only the cells above
    the threshold are compared with their neighbours (a few of the image's)."""
    # a margin of 1 dB (the exact test below decides); at the floor every cell passes
    low = threshold_db - 1.0 <= _PEAK_FLOOR_DB
    lim = -np.inf if low else ref * 10 ** ((threshold_db - 1.0) / 10)
    kernel = optional_kernel("processing.imaging.peaks_kernel", "local_maxima")
    if kernel is not None and p.dtype == np.float64:  # the same cells, in one pass
        cand = kernel(p, lim)  # read in place: an image is a transposed view
        level = to_db(p[tuple(cand.T)], ref, _PEAK_FLOOR_DB)
        return cand[level >= threshold_db], level[level >= threshold_db]
    cand = np.argwhere(p == p) if low else np.argwhere(p >= lim)
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


def _pole_maxima(p: np.ndarray, pole: np.ndarray, threshold_db: float):
    """:func:`_local_maxima` of an image whose elevations (E,) `pole` are +-90 degrees:
    a pole is one cell, whose neighbours are the whole ring of the next elevation
    (the whole image filtered: such grids are the rare wide ones)."""
    local = maximum_filter(p, size=3, mode="nearest")
    for e_pole in np.flatnonzero(pole):
        ring = p[:, max(e_pole - 1, 0) : e_pole + 2, :].max(axis=(1, 2))
        local[:, e_pole, :] = maximum_filter(ring, size=3, mode="nearest")[:, None]
    level = to_db(p, float(p.max()), _PEAK_FLOOR_DB)
    idx = np.argwhere((p >= local) & (level >= threshold_db))
    return idx, level[tuple(idx.T)]


def find_peaks(
    image: Image, threshold_db: float = PEAK_THRESHOLD_DB, *, max_peaks: int | None = None
) -> Peaks:
    """Local maxima of the 3D image (a 3x3x3 neighbourhood) at least `threshold_db`
    (dB re the strongest cell; default :data:`PEAK_THRESHOLD_DB`), at most `max_peaks`.

    Plateaus count once (their first cell in index order).  At elevation +-90
    degrees every azimuth is the same direction: the pole is one cell, whose value is
    its row's maximum and whose neighbours are every azimuth of the next elevation,
    so an echo from the zenith or the nadir is one peak (at the grid's first azimuth).
    """
    p = image.power
    ref = float(p.max()) if p.size else 0.0
    if p.size == 0 or ref <= 0:
        e = np.empty(0)
        return Peaks(e, e, e, e, image.method, np.zeros(0, bool))
    pole = np.abs(np.abs(image.elevation_rad) - np.pi / 2) < 1e-9
    if pole.any() and image.azimuth_rad.size > 1:
        # every azimuth at +-90 degrees is one direction: one value, so one peak
        p = p.copy()
        p[:, pole, :] = p[:, pole, :].max(axis=2, keepdims=True)
        idx, level = _pole_maxima(p, pole, threshold_db)
    else:
        idx, level = _local_maxima(p, threshold_db, ref)
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
    az, el = image.azimuth_rad[idx[:, 2]], image.elevation_rad[idx[:, 1]]
    return Peaks(
        azimuth_rad=az,
        elevation_rad=el,
        range_m=image.range_m[idx[:, 0]],
        level_db=lv,
        method=image.method,
        on_grid_edge=on_grid_edge(image, az, el),
    )
