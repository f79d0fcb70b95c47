"""Resolution metrics of section IV of the paper.

* Angular resolution: the solid angle (steradians) of the -3 dB region of the point
  spread function, on the range slice that holds the image maximum: the cells
  connected to the peak (4-neighbourhood) whose level is within 3 dB of it, each
  weighted by its area on the unit sphere, ``d_az (sin(el_top) - sin(el_bottom))``
  (cells end half-way to their neighbours and at the ends of the grid).
* Range resolution: along the range slices, the profile of each slice's maximum;
  the distance between the -3 dB points around the strongest slice, linearly
  interpolated between slices where the crossing lies inside the kept bins, or the
  outermost kept slice of the connected run otherwise.
* Maximum attenuation between two sources: on a 1-D cut, the lower of the two
  source peaks over the deepest point between them, in dB (0 when they merge).
* Dynamic range: maximum over minimum of a spectrum, in dB.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import label

from processing.imaging.image import Image

__all__ = [
    "cell_solid_angles",
    "solid_angle_3db",
    "angular_resolution",
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


def solid_angle_3db(
    power: np.ndarray,
    elevation_rad: np.ndarray,
    azimuth_rad: np.ndarray,
    peak: tuple[int, int] | None = None,
) -> float:
    """-3 dB solid angle (sr) of the region connected to `peak` on a slice (E, A)."""
    p = np.asarray(power, dtype=float)
    if p.max() <= 0:
        raise ValueError("the spectrum has no energy: its -3 dB area is undefined")
    if peak is None:
        e, a = np.unravel_index(int(np.argmax(p)), p.shape)
        peak = (int(e), int(a))
    labels, _ = label(p >= HALF_POWER * p[peak])
    region = labels == labels[peak]
    return float(cell_solid_angles(elevation_rad, azimuth_rad)[region].sum())


def angular_resolution(image: Image) -> float:
    """-3 dB solid angle (sr) on the range slice of the image maximum."""
    if image.power.size == 0:
        raise ValueError("the image has no range bins: angular resolution is undefined")
    r, e, a = np.unravel_index(int(np.argmax(image.power)), image.power.shape)
    return solid_angle_3db(image.power[r], image.elevation_rad, image.azimuth_rad, (int(e), int(a)))


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
