"""Resolution metrics of section IV of the paper.

* Angular resolution: the solid angle (steradians) of the -3 dB region of the point
  spread function, on the range slice that holds the image maximum, resolved below
  one grid cell: the cells connected to the peak (4-neighbourhood) within 3 dB of it
  locate the region; around them the level is evaluated on a fine grid (the caller's
  spectrum function, or a piecewise biquadratic interpolation of the level in dB) and
  the fine points within 3 dB of the fine maximum, connected to it, are weighted by
  their area on the unit sphere, ``d_az (sin(el_top) - sin(el_bottom))``.  Readings
  narrower than one cell rest on the interpolation and are flagged (``sub_cell``).
* Range resolution: along the range slices, the profile of each slice's maximum;
  the distance between the -3 dB points around the strongest slice, linearly
  interpolated between slices where the crossing lies inside the kept bins, or the
  outermost kept slice of the connected run otherwise.
* Maximum attenuation between two sources: on a 1-D cut, the lower of the two
  source peaks over the deepest point between them, in dB (0 when they merge).
* Dynamic range: maximum over minimum of a spectrum, in dB.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import label

from processing.imaging.image import Image

__all__ = [
    "cell_solid_angles",
    "SolidAngle3dB",
    "solid_angle_3db",
    "solid_angle_detail",
    "angular_resolution",
    "angular_resolution_detail",
    "range_profile",
    "range_resolution",
    "max_attenuation",
    "dynamic_range_db",
]

HALF_POWER = 10 ** (-3 / 10)


def _cell_widths(x: np.ndarray) -> np.ndarray:
    """Width of each grid cell: between midpoints, end cells stop at the grid's ends."""
    if x.size == 1:
        return np.ones(1)
    edges = np.concatenate([[x[0]], (x[1:] + x[:-1]) / 2, [x[-1]]])
    return np.diff(edges)


def _cell_edges(x: np.ndarray) -> np.ndarray:
    """Cell edges: midpoints between grid values; end cells stop at the grid's ends
    (a single value gets a cell of width 1 centred on it)."""
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    return np.concatenate([[x[0]], (x[1:] + x[:-1]) / 2, [x[-1]]])


def cell_solid_angles(elevation_rad: np.ndarray, azimuth_rad: np.ndarray) -> np.ndarray:
    """Area on the unit sphere of each grid cell, shape (E, A), in steradians:
    ``d_az (sin(el_top) - sin(el_bottom))`` between the cell's edges (exact for
    every cell, also those at +-90 degrees, where cos(el) at the centre is 0)."""
    el_edges = np.clip(_cell_edges(np.asarray(elevation_rad, float)), -np.pi / 2, np.pi / 2)
    band = np.diff(np.sin(el_edges))
    d_az = _cell_widths(azimuth_rad)
    return band[:, None] * d_az[None, :]


@dataclass(frozen=True)
class SolidAngle3dB:
    """The -3 dB solid angle of a peak (:func:`solid_angle_detail`).

    `solid_angle_sr`: steradians.  `sub_cell`: the region is narrower than one grid
    step along elevation or azimuth, so the value rests on the interpolation between
    samples (exact for a beam whose level in dB is locally quadratic, e.g. Gaussian)
    rather than on samples inside the region; always False when a `spectrum` function
    was evaluated on the fine grid.  `truncated`: the region reaches the grid's edge,
    so the value is a lower bound.  `cells`: the plain sum of the whole grid cells
    within 3 dB (the metric before refinement; it cannot go below one cell)."""

    solid_angle_sr: float
    sub_cell: bool
    truncated: bool
    cells: float


#: points per axis of the fine grid the -3 dB region is measured on
FINE_POINTS = 256
#: a fine region spanning fewer points than this along an axis is measured again on
#: a window zoomed around it, at most ZOOMS times
ZOOM_BELOW = 64
ZOOMS = 3
#: levels (dB under the peak) below this are clamped before interpolation
_DB_FLOOR = -3000.0

SpectrumFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``spectrum(elevation_rad (E,), azimuth_rad (A,)) -> power (E, A)``."""


def solid_angle_3db(
    power: np.ndarray,
    elevation_rad: np.ndarray,
    azimuth_rad: np.ndarray,
    peak: tuple[int, int] | None = None,
    *,
    spectrum: SpectrumFn | None = None,
) -> float:
    """-3 dB solid angle (sr) of the region connected to `peak` on a slice (E, A),
    resolved below one grid cell (see :func:`solid_angle_detail`)."""
    return solid_angle_detail(
        power, elevation_rad, azimuth_rad, peak, spectrum=spectrum
    ).solid_angle_sr


def solid_angle_detail(
    power: np.ndarray,
    elevation_rad: np.ndarray,
    azimuth_rad: np.ndarray,
    peak: tuple[int, int] | None = None,
    *,
    spectrum: SpectrumFn | None = None,
) -> SolidAngle3dB:
    """-3 dB solid angle of the region connected to `peak` on a slice (E, A).

    The grid cells within 3 dB of the peak (4-neighbourhood) give the region's
    bounding box; around it, padded by one cell, the level is evaluated on a fine
    grid of :data:`FINE_POINTS` per axis: by `spectrum` (the caller's function, in
    the units of `power`) when given, else by a piecewise biquadratic interpolation
    of the level in dB through the samples.  The fine points within 3 dB of the fine
    maximum that are connected to it are weighted by their area on the unit sphere
    (cos(elevation) d_el d_az); a region spanning fewer than :data:`ZOOM_BELOW`
    fine points along an axis is measured again on a window zoomed around it.  Grids
    of one row or column give the whole cells.
    """
    p = np.asarray(power, dtype=float)
    el = np.asarray(elevation_rad, float)
    az = np.asarray(azimuth_rad, float)
    if p.max() <= 0:
        raise ValueError("the spectrum has no energy: its -3 dB area is undefined")
    if peak is None:
        e, a = np.unravel_index(int(np.argmax(p)), p.shape)
        peak = (int(e), int(a))
    labels, _ = label(p >= HALF_POWER * p[peak])
    region = labels == labels[peak]
    cells = float(cell_solid_angles(el, az)[region].sum())
    rows, cols = np.flatnonzero(region.any(1)), np.flatnonzero(region.any(0))
    truncated = bool(
        rows[0] == 0 or cols[0] == 0 or rows[-1] == el.size - 1 or cols[-1] == az.size - 1
    )
    if el.size < 2 or az.size < 2:
        return SolidAngle3dB(cells, True, truncated, cells)
    pad = 1
    while True:  # widen the window until the fine region does not touch its sides
        el_f, az_f, fine, edge, level_db = _fine_region(p, el, az, rows, cols, pad, spectrum)
        if not edge or pad > max(el.size, az.size):
            break
        pad *= 2
    for _ in range(ZOOMS):  # a region of few fine points: measured again, zoomed in
        el_f, az_f, fine, done = _zoomed(el_f, az_f, fine, level_db)
        if done:
            break
    area = float(cell_solid_angles(el_f, az_f)[fine].sum())
    width_el = np.ptp(el_f[fine.any(1)]) + (el_f[1] - el_f[0])
    width_az = np.ptp(az_f[fine.any(0)]) + (az_f[1] - az_f[0])
    sub_cell = spectrum is None and bool(
        width_el < np.min(np.diff(el)) or width_az < np.min(np.diff(az))
    )
    return SolidAngle3dB(area, sub_cell, truncated, cells)


def _within_3db(level_db: np.ndarray) -> np.ndarray:
    """The points of `level_db` (F, F) within 3 dB of its maximum, connected to it."""
    inside, _ = label(level_db >= level_db.max() - 10 * np.log10(1 / HALF_POWER))
    top = np.unravel_index(int(np.argmax(level_db)), level_db.shape)
    return inside == inside[top]


def _zoomed(el_f, az_f, fine, level_db):
    """(el_f, az_f, fine, done): when `fine` spans fewer than :data:`ZOOM_BELOW` points
    along an axis, the region measured again on a window around it (its extent plus
    half of it and three fine steps each side, inside the current window); `done`
    when it spans enough or the zoomed region reaches the new window's side."""
    ie, ia = np.flatnonzero(fine.any(1)), np.flatnonzero(fine.any(0))
    if min(ie.size, ia.size) >= ZOOM_BELOW:
        return el_f, az_f, fine, True

    def axis(x, idx):
        lo, hi, step = x[idx[0]], x[idx[-1]], x[1] - x[0]
        margin = 0.5 * (hi - lo) + 3 * step
        return np.linspace(max(lo - margin, x[0]), min(hi + margin, x[-1]), FINE_POINTS)

    el_z, az_z = axis(el_f, ie), axis(az_f, ia)
    zoom = _within_3db(level_db(el_z, az_z))
    if zoom[0].any() or zoom[-1].any() or zoom[:, 0].any() or zoom[:, -1].any():
        return el_f, az_f, fine, True
    return el_z, az_z, zoom, False


def _fine_region(p, el, az, rows, cols, pad, spectrum):
    """(el_f (F,), az_f (F,), fine (F, F) bool, whether `fine` reaches a side of the
    window that is not the grid's edge, the level function used): the fine points
    within 3 dB of the fine maximum, connected to it, over the bounding box of
    `rows` x `cols` widened by `pad` cells."""
    (e0, e1), (a0, a1) = _padded(rows, el.size, pad), _padded(cols, az.size, pad)
    el_f = np.linspace(el[e0], el[e1], FINE_POINTS)
    az_f = np.linspace(az[a0], az[a1], FINE_POINTS)
    if spectrum is not None:

        def level_db(e: np.ndarray, a: np.ndarray) -> np.ndarray:
            return _db(np.asarray(spectrum(e, a), float))
    else:
        level_db = _interpolated_db(p, el, az, rows, cols, pad + 2)
    fine = _within_3db(level_db(el_f, az_f))
    edge = (
        (e0 > 0 and fine[0].any())
        or (e1 < el.size - 1 and fine[-1].any())
        or (a0 > 0 and fine[:, 0].any())
        or (a1 < az.size - 1 and fine[:, -1].any())
    )
    return el_f, az_f, fine, bool(edge), level_db


def _padded(index: np.ndarray, n: int, pad: int) -> tuple[int, int]:
    """First and last index of `index` widened by `pad` and kept inside 0..n-1."""
    return max(int(index[0]) - pad, 0), min(int(index[-1]) + pad, n - 1)


def _db(p: np.ndarray) -> np.ndarray:
    """10 log10 of `p` over its maximum, clamped at :data:`_DB_FLOOR`."""
    top = p.max()
    if top <= 0:
        raise ValueError("the refined spectrum has no energy: its -3 dB area is undefined")
    return np.maximum(10 * np.log10(np.maximum(p, 0) / top + 1e-300), _DB_FLOOR)


def _interpolated_db(p, el, az, rows, cols, pad) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Piecewise biquadratic interpolation of the level in dB: at each point, the
    quadratic in elevation and in azimuth through the 3 x 3 samples around the
    nearest one (exact where the level in dB is quadratic, as for a Gaussian beam;
    local, so a null a few samples away does not bend the -3 dB contour)."""
    (e0, e1), (a0, a1) = _padded(rows, el.size, pad), _padded(cols, az.size, pad)
    sub = _db(p[e0 : e1 + 1, a0 : a1 + 1])
    xe, xa = el[e0 : e1 + 1], az[a0 : a1 + 1]

    def level(e: np.ndarray, a: np.ndarray) -> np.ndarray:
        ie, we = _stencil(xe, e)  # (F, 3) each
        ia, wa = _stencil(xa, a)
        block = sub[ie[:, :, None, None], ia[None, None, :, :]]  # (F, 3, G, 3)
        return np.einsum("fi,figj,gj->fg", we, block, wa)

    return level


def _stencil(x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices (T, 3) of the three samples of `x` around the one nearest each `t`
    (fewer samples: repeated, weight 0) and their Lagrange weights (T, 3)."""
    if x.size < 3:  # linear (or constant) interpolation
        j = np.clip(np.searchsorted(x, t) - 1, 0, max(x.size - 2, 0))
        k = np.minimum(j + 1, x.size - 1)
        span = np.where(k > j, x[k] - x[j], 1.0)
        f = np.clip((t - x[j]) / span, 0, 1) * (k > j)
        return np.stack([j, k, k], 1), np.stack([1 - f, f, 0 * f], 1)
    c = np.clip(np.abs(x[None, :] - t[:, None]).argmin(1), 1, x.size - 2)
    idx = np.stack([c - 1, c, c + 1], 1)
    xs = x[idx]
    w = np.ones_like(xs)
    for a in range(3):
        for b in range(3):
            if a != b:
                w[:, a] *= (t - xs[:, b]) / (xs[:, a] - xs[:, b])
    return idx, w


def angular_resolution(image: Image, *, spectrum: SpectrumFn | None = None) -> float:
    """-3 dB solid angle (sr) on the range slice of the image maximum (see
    :func:`solid_angle_detail`; `spectrum` evaluates that slice on other directions)."""
    return angular_resolution_detail(image, spectrum=spectrum).solid_angle_sr


def angular_resolution_detail(image: Image, *, spectrum: SpectrumFn | None = None) -> SolidAngle3dB:
    """:func:`solid_angle_detail` on the range slice of the image maximum."""
    if image.power.size == 0:
        raise ValueError("the image has no range bins: angular resolution is undefined")
    r, e, a = np.unravel_index(int(np.argmax(image.power)), image.power.shape)
    return solid_angle_detail(
        image.power[r], image.elevation_rad, image.azimuth_rad, (int(e), int(a)), spectrum=spectrum
    )


def range_profile(image: Image) -> np.ndarray:
    """Maximum of each range slice, shape (R,) (empty for an image of no range bins)."""
    R = image.power.shape[0]
    if R == 0:
        return np.zeros(0)
    return image.power.reshape(R, -1).max(axis=1)


def range_resolution(image: Image) -> float:
    """-3 dB extent (m) of the range profile around its maximum."""
    prof = range_profile(image)
    if prof.size == 0:
        raise ValueError("the image has no range bins: range resolution is undefined")
    if prof.max() <= 0:
        raise ValueError("the image has no energy: range resolution is undefined")
    rng = image.range_m
    step = image.bin_range_m or (np.median(np.diff(rng)) if rng.size > 1 else 0.0)
    i = int(np.argmax(prof))
    half = HALF_POWER * prof[i]

    def edge(direction: int) -> float:
        j = i
        while True:
            n = j + direction
            if n < 0 or n >= prof.size or abs(rng[n] - rng[j]) > 1.5 * step:
                return rng[j]  # run ends at the gate: its last kept slice
            if prof[n] < half:  # crossing between j and n
                frac = (prof[j] - half) / (prof[j] - prof[n])
                return rng[j] + frac * (rng[n] - rng[j])
            j = n

    return float(abs(edge(+1) - edge(-1)))


def max_attenuation(
    cut: np.ndarray, angles_rad: np.ndarray, source_a_rad: float, source_b_rad: float
) -> float:
    """Depth (dB) of the dip between two sources on a 1-D linear-power cut.

    The peak of each source is the maximum within half the spacing of its true
    angle; the attenuation is the lower of the two peaks over the minimum between
    them.  0 dB when both peaks are the same cell (merged).
    """
    p = np.asarray(cut, dtype=float)
    a, b = sorted((source_a_rad, source_b_rad))
    half = (b - a) / 2
    win_a = np.flatnonzero(np.abs(angles_rad - a) <= half)
    win_b = np.flatnonzero(np.abs(angles_rad - b) <= half)
    if win_a.size == 0 or win_b.size == 0:
        raise ValueError("the cut does not cover both sources")
    ia = win_a[np.argmax(p[win_a])]
    ib = win_b[np.argmax(p[win_b])]
    if ib <= ia:
        return 0.0
    dip = p[ia : ib + 1].min()
    top = min(p[ia], p[ib])
    if top <= 0:
        return 0.0
    return float(10 * np.log10(top / max(dip, top * 1e-30)))


def dynamic_range_db(power: np.ndarray) -> float:
    """Maximum over minimum of a spectrum, in dB (inf-free: floored at 300 dB)."""
    p = np.asarray(power, dtype=float)
    top = p.max()
    if top <= 0:
        return 0.0
    return float(min(10 * np.log10(top / max(p.min(), top * 1e-30)), 300.0))
