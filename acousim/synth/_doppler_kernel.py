"""Compiled placement of the Doppler renderer's impulses
(:func:`acousim.synth.doppler.plan_doppler`; numba, optional: without numba the same
operations run in numpy, one array at a time).

One pass over the paths and microphones computes each impulse's position, the
Doppler factor mapped onto the Chebyshev interval and the positions' range, with
the operations of the numpy form in its order (the same bits).  The GIL is released.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def place(delay, rate, pivot, fs, shift, start, offset, half, d, s):  # pragma: no cover
    """d (M, N) <- ``((delay + pivot (1 / rate - 1)) fs + shift) + start``; s (M, N)
    <- ``(rate - offset) / half`` (when s has the shape of d); returns (d.min(),
    d.max())."""
    M, N = delay.shape
    lo, hi = np.inf, -np.inf
    factor = s.shape == d.shape
    for n in range(N):
        for m in range(M):
            a = rate[m, n]
            x = ((delay[m, n] + pivot * (1.0 / a - 1.0)) * fs + shift) + start
            d[m, n] = x
            lo, hi = min(lo, x), max(hi, x)
            if factor:
                s[m, n] = (a - offset) / half
    return lo, hi
