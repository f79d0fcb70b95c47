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
    d.max()).  Row by row (the arrays' C order: each a loop that vectorises), the
    range in a pass of its own."""
    M, N = delay.shape
    factor = s.shape == d.shape
    for m in range(M):
        dm, am, tm = d[m], rate[m], delay[m]
        for n in range(N):
            dm[n] = ((tm[n] + pivot * (1.0 / am[n] - 1.0)) * fs + shift) + start
        if factor:
            sm = s[m]
            for n in range(N):
                sm[n] = (am[n] - offset) / half
    lo, hi = np.inf, -np.inf
    for m in range(M):
        dm = d[m]
        for n in range(N):
            x = dm[n]
            if x < lo:
                lo = x
            if x > hi:
                hi = x
    return lo, hi
