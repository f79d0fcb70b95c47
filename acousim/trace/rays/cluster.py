"""Stage 5 of the tracer: scattered contributions clustered into point reflectors.

Scattered contributions are many (one per ray and bounce); the renderer wants few
paths.  A cluster adds the intensities of contributions that the sonar cannot tell
apart, and keeps their delay and direction:

1. Group the contributions.  The lobes of curved surfaces (``lambert`` false:
   second order and up) form one group per surface and order; the Lambert tail (of
   planar walls, and of rough curved surfaces) one group per order and direction
   cell (seen from the receiver) of about ``DIFFUSE_CELL_DEG`` times the order,
   whatever the surface: a ring of equal delay is many directions, and it must not
   collapse onto its axis, while two surfaces in one direction at one delay are one
   echo to the sonar.  With frequency-dependent materials, contributions with
   different material interactions are in different groups (their spectra differ).
2. Bin each group by path length, anchored at the group's nearest contribution:
   glints in bins one range resolution wide (the call's ``c / bandwidth`` of path),
   so that a compact glint is never split in two (two paths at one delay add
   coherently in the renderer: a split glint would come out louder); the Lambert
   tail in bins ``DIFFUSE_BIN_FACTOR`` times the order as wide (a smooth tail: fewer
   paths, see BENCHMARKS.md for their cost).
3. Each bin becomes one point reflector: its intensity is the sum of its
   contributions', its path length and its direction (from the receiver) their
   intensity-weighted means, at the contributions' mean distance from the receiver.
   So a contribution's delay is kept within its bin's width (for a first-order
   Lambert tail at the default 25-50 kHz call: 5.5 cm of path, 2.7 cm of range, well
   inside an image's range bin) and its direction within its cell.  (Placing a bin
   at the centroid of its contributions, as before, put the ring of contributions
   that a wall returns at one delay much nearer than they are, and on its axis.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.trace.paths import KIND, TracedPaths
from acousim.trace.rays.scatter import Contributions
from processing.base.kernels import optional_kernel

__all__ = ["Cells", "cluster", "members", "DIFFUSE_CELL_DEG", "DIFFUSE_BIN_FACTOR"]

#: direction cells (deg, seen from the receiver, times the order) of the Lambert tail
DIFFUSE_CELL_DEG = 10.0
#: ... and its bins are this many range resolutions (times the order) long
DIFFUSE_BIN_FACTOR = 4.0


@dataclass(frozen=True)
class Cells:
    """How finely the Lambert tail is clustered (steps 1 and 2)."""

    cell_deg: float = DIFFUSE_CELL_DEG
    """direction cells seen from the receiver, deg, times the order."""
    bin_factor: float = DIFFUSE_BIN_FACTOR
    """the tail's bins are this many range resolutions long, times the order."""


def _dense(v: np.ndarray) -> tuple[np.ndarray, int]:
    """Each integer of `v` (K,) as its rank among the distinct values (ascending:
    ``np.unique``'s inverse), and how many distinct values there are; by a table
    of the values' span when it is at most a few times K (no sort)."""
    if v.size == 0:
        return np.zeros(0, np.intp), 0
    lo = v.min()
    span = int(v.max() - lo) + 1
    if span > 4 * v.size + 4096:
        _, inv = np.unique(v, return_inverse=True)
        inv = inv.ravel()
        return inv, int(inv.max()) + 1
    present = np.zeros(span, bool)
    shifted = v - lo
    present[shifted] = True
    rank = np.cumsum(present) - 1
    return rank[shifted], int(rank[-1]) + 1


def members(
    c: Contributions, receiver: np.ndarray, resolution_m: float, cells: Cells = Cells()
) -> tuple[np.ndarray, int]:
    """Steps 1 and 2: the cluster (K,) of every contribution, and the number of
    clusters; the receiver (3,) in metres, the range resolution as a path length (m).
    Compiled (:mod:`.cluster_kernel`) or, without numba, in numpy: the same."""
    kernel = optional_kernel("acousim.trace.rays.cluster_kernel", "members")
    if kernel is not None:
        signature = None
        if c.interactions is not None and c.interactions.shape[1]:
            _, signature = np.unique(c.interactions, axis=0, return_inverse=True)
            signature = signature.ravel().astype(np.int64)
        return kernel(
            c.first_leg_m,
            c.last_leg_m,
            c.point_m,
            np.asarray(receiver, float),
            c.lambert,
            c.surface,
            c.order,
            signature,
            float(np.deg2rad(cells.cell_deg)),
            float(cells.bin_factor),
            float(resolution_m),
        )
    total = c.first_leg_m + c.last_leg_m
    u = (c.point_m - receiver) / c.last_leg_m[:, None]  # direction from the receiver
    # 1. groups: surface and order, and a direction cell for the Lambert tail
    surface = np.where(c.lambert, -1, c.surface.astype(np.int64))  # a tail: any surface
    group, n_group = _dense((surface + 1) * 64 + c.order)
    if c.interactions is not None and c.interactions.shape[1]:
        _, signature = np.unique(c.interactions, axis=0, return_inverse=True)
        signature = signature.ravel().astype(np.int64)
        group, n_group = _dense(group.astype(np.int64) * (signature.max() + 1) + signature)
    if c.lambert.any():
        q = np.round(u / (np.deg2rad(cells.cell_deg) * c.order[:, None])).astype(np.int64)
        span = int(np.abs(q).max()) * 2 + 1
        cell = ((q[:, 0] * span + q[:, 1]) * span + q[:, 2]) + 1
        cell = np.where(c.lambert, cell, 0)
        group, n_group = _dense(group.astype(np.int64) * (span**3 + 2) + cell)
    # 2. bins anchored at each group's nearest contribution
    start = np.full(n_group, np.inf)
    np.minimum.at(start, group, total)
    width = np.where(c.lambert, cells.bin_factor * c.order * resolution_m, resolution_m)
    bins = np.floor((total - start[group]) / width).astype(np.int64)
    return _dense(group.astype(np.int64) * (int(bins.max()) + 1) + bins)


def _reflectors(c: Contributions, inv: np.ndarray, n: int, receiver: np.ndarray) -> tuple:
    """Step 3 for the contributions `c` in clusters `inv` (K,) of `n`: per cluster the
    summed intensity, the intensity-weighted mean path length and last leg (m),
    direction from the receiver and departure (unit, (n, 3)) and order (compiled,
    :func:`.cluster_kernel.reflectors`, or in numpy: the same sums)."""
    kernel = optional_kernel("acousim.trace.rays.cluster_kernel", "reflectors")
    if kernel is not None:
        args = (c.intensity, c.first_leg_m, c.last_leg_m, c.point_m)
        return kernel(inv, n, *args, np.asarray(receiver, float), c.departure, c.order)
    inten = c.intensity
    u = (c.point_m - receiver) / c.last_leg_m[:, None]
    w = np.bincount(inv, inten, n)

    def mean(v: np.ndarray) -> np.ndarray:
        if v.ndim == 1:
            return np.bincount(inv, inten * v, n) / w
        return np.stack([mean(v[:, k]) for k in range(v.shape[1])], axis=1)

    length = mean(c.first_leg_m + c.last_leg_m)
    last = mean(c.last_leg_m)
    direction = mean(u)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    dep = mean(c.departure)
    dep /= np.linalg.norm(dep, axis=1, keepdims=True)
    order = np.rint(mean(c.order.astype(float))).astype(int)
    return w, length, last, direction, dep, order


def cluster(
    c: Contributions, receiver: np.ndarray, resolution_m: float, cells: Cells = Cells()
) -> TracedPaths:
    """Point reflectors (paths of kind "scatter") for contributions `c`; the receiver
    (3,) in metres, the range resolution as a path length (m)."""
    if len(c) == 0:
        return TracedPaths.empty()
    inv, n = members(c, receiver, resolution_m, cells)
    # 3. one reflector per bin: summed intensity at the mean path length and direction
    w, length, last, direction, dep, order = _reflectors(c, inv, n, receiver)
    anchor = receiver + last[:, None] * direction
    counts = None
    if c.interactions is not None and c.interactions.shape[1]:
        counts = np.zeros((n, c.interactions.shape[1]), int)
        counts[inv] = c.interactions  # one signature per cluster (step 1)
    return TracedPaths(
        anchor,
        length - last,
        np.sqrt(w) * last,
        anchor,
        order,
        np.full(n, KIND["scatter"]),
        dep,
        counts,
    )
