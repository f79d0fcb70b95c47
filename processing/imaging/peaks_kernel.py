"""Compiled helper of :func:`processing.imaging.image.find_peaks` (numba; optional).

:func:`local_maxima` finds, in one pass over an image, the cells at or above a level
that are at least as large as every cell of their 3x3x3 neighbourhood (clamped at
the borders), stopping at the first larger neighbour: numpy needs a boolean image,
its indices and 27 gathers of the candidates' neighbours.  The same cells, in the
same order, as the numpy twin in :func:`processing.imaging.image._local_maxima`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def local_maxima(p, lim):
    """Indices (N, 3) int64, in C index order, of the cells of `p` (R, E, A)
    float64 (any strides: an image's transposed view is read in place) with
    ``p >= lim`` and ``p >= q`` for every cell q of their clamped 3x3x3
    neighbourhood.

    A candidate is compared with its two azimuth neighbours first (the same row, in
    cache; most candidates fall there), then with the rest of its neighbourhood until
    one is larger: the same cells as comparing all 27."""
    n_r, n_e, n_a = p.shape
    out = np.empty((64, 3), np.int64)
    n = 0
    for r in range(n_r):
        r0, r1 = max(r - 1, 0), min(r + 2, n_r)
        for e in range(n_e):
            e0, e1 = max(e - 1, 0), min(e + 2, n_e)
            for a in range(n_a):
                v = p[r, e, a]
                if not v >= lim:
                    continue
                if a > 0 and not v >= p[r, e, a - 1]:
                    continue
                if a + 1 < n_a and not v >= p[r, e, a + 1]:
                    continue
                if _exceeded(p, v, r0, r1, e0, e1, max(a - 1, 0), min(a + 2, n_a)):
                    continue
                if n == out.shape[0]:
                    grown = np.empty((2 * n, 3), np.int64)
                    grown[:n] = out
                    out = grown
                out[n, 0], out[n, 1], out[n, 2] = r, e, a
                n += 1
    return out[:n]


@njit(cache=True, inline="always")
def _exceeded(p, v, r0, r1, e0, e1, a0, a1):
    """Whether a cell of p[r0:r1, e0:e1, a0:a1] is not at most v (larger, or NaN)."""
    for rr in range(r0, r1):
        for ee in range(e0, e1):
            for aa in range(a0, a1):
                if not v >= p[rr, ee, aa]:
                    return True
    return False
