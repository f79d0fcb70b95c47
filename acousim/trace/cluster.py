"""Stage 5 of the tracer: scattered contributions clustered into point reflectors.

1. Group the contributions by surface and order.
2. Bin each group by path length, anchored at its nearest contribution so that a
   compact glint is never split in two: bins one range resolution wide on curved
   surfaces, ``DIFFUSE_BIN_FACTOR`` times that for the Lambert tail of planar walls.
3. Each bin becomes one point reflector: intensities add, at the intensity-weighted
   centroid of its contributions.
"""

from __future__ import annotations

import numpy as np

from .paths import KIND, TracedPaths
from .scatter import Contributions

__all__ = ["cluster", "DIFFUSE_BIN_FACTOR"]

#: diffuse (Lambert) contributions of planar walls are binned this many range
#: resolutions wide (see BENCHMARKS.md for the time it saves and the error it costs)
DIFFUSE_BIN_FACTOR = 4


def cluster(c: Contributions, receiver: np.ndarray, resolution_m: float) -> TracedPaths:
    """Point reflectors (paths of kind "scatter") for contributions `c`."""
    if len(c) == 0:
        return TracedPaths.empty()
    inten = c.intensity
    total = c.first_leg_m + c.last_leg_m
    # 1. groups
    _, group = np.unique(c.surface.astype(np.int64) * 16 + c.order, return_inverse=True)
    group = group.ravel()
    # 2. bins
    start = np.full(group.max() + 1, np.inf)
    np.minimum.at(start, group, total)
    width = np.where(c.lambert, DIFFUSE_BIN_FACTOR * resolution_m, resolution_m)
    bins = np.floor((total - start[group]) / width).astype(np.int64)
    _, inv = np.unique(group.astype(np.int64) * (bins.max() + 1) + bins, return_inverse=True)
    inv = inv.ravel()
    n = inv.max() + 1
    # 3. one reflector per bin
    w = np.bincount(inv, inten, n)

    def mean(v):
        return (
            np.stack([np.bincount(inv, inten * v[:, k], n) for k in range(v.shape[1])], axis=1)
            / w[:, None]
        )

    pos = mean(c.point_m)
    first = np.bincount(inv, inten * c.first_leg_m, n) / w
    d = mean(c.departure)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ordr = np.bincount(inv, c.order, n) // np.bincount(inv, None, n)
    r_c = np.linalg.norm(receiver - pos, axis=1)
    return TracedPaths(
        pos, first, np.sqrt(w) * r_c, pos, ordr.astype(int), np.full(n, KIND["scatter"]), d
    )
