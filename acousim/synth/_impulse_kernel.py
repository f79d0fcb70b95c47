"""Compiled impulse accumulation of :func:`acousim.synth.render._impulses` (numba;
optional: without numba the renderer builds the same sums as a sparse product).

For every microphone m and path n the kernel adds the 2 * taps tabulated
fractional-delay weights of the path, times each of its Q gains, into the rows of a
float64 accumulator, in the order the sparse product adds them (each row receives
its terms path by path), so both engines give the same bits; each microphone's rows are then
stored in the output's precision, and the rest of its rows zeroed (the output need
not be: a buffer can be reused without clearing it).  Nothing per tap is kept in
memory (the sparse product needs the M N 2 taps weights and row indices), and the
GIL is released, so the tracer's thread runs meanwhile.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def accumulate(start, phase, scale, gains, table, out):  # pragma: no cover - compiled
    """Sum of weighted impulses written into `out` (Q, M, B) (its contents before
    are not read: every element is written).

    start (M, N) int64: buffer index of each impulse's first tap; phase (M, N)
    intp: its row of `table` (P, K), the K tap weights; scale (M, N) times gains
    (M, N, Q), float64 (either may be a broadcast view): its Q gains, formed here.
    Row q of microphone m receives
    ``table[phase[m, n], j] * (scale[m, n] * gains[m, n, q])`` at ``start[m, n] + j``.
    """
    M, N = start.shape
    Q = gains.shape[2]
    K = table.shape[1]
    B = out.shape[2]
    acc = np.zeros((Q, B))
    for m in range(M):
        lo, hi = B, 0
        for n in range(N):
            s = start[m, n]
            row = table[phase[m, n]]
            for q in range(Q):  # taps innermost: contiguous, vectorised (2x faster)
                g = scale[m, n] * gains[m, n, q]
                if g == 0.0:  # e.g. an echo in the direct path's set: nothing to add
                    continue
                a = acc[q, s : s + K]
                for j in range(K):
                    a[j] += row[j] * g
            lo = min(lo, s)
            hi = max(hi, s + K)
        hi = max(hi, lo)
        for q in range(Q):  # slices: a vectorised copy (a loop of elements is not)
            out[q, m, :lo] = 0.0
            out[q, m, lo:hi] = acc[q, lo:hi]
            out[q, m, hi:] = 0.0
            acc[q, lo:hi] = 0.0
