"""Compiled impulse accumulation of :func:`acousim.synth.render._impulses` (numba;
optional: without numba the renderer builds the same sums as a sparse product).

For every microphone m and path n the kernel adds the 2 * taps tabulated
fractional-delay weights of the path, times each of its Q gains, into the rows of
the output, in its precision (float32 for the renders by FFT in single precision:
the precision the impulses are stored and transformed in; float64 otherwise), in
the order the sparse product adds them (each row receives its terms path by path),
so both engines give the same bits.  Nothing per tap is kept in memory (the sparse
product needs the M N 2 taps weights and row indices), and the GIL is released, so
the tracer's thread runs meanwhile.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def accumulate(start, phase, scale, gains, table, out):  # pragma: no cover - compiled
    """Sum of weighted impulses written into `out` (Q, M, B) (its contents before
    are not read: every element is written).

    start (M, N) int64: buffer index of each impulse's first tap; phase (M, N)
    intp: its row of `table` (P, K), the K tap weights, of `out`'s dtype; scale
    (M, N) times gains (M, N, Q), float64 (either may be a broadcast view): its Q
    gains, formed here and rounded to `out`'s dtype.  Row q of microphone m
    receives ``table[phase[m, n], j] * (scale[m, n] * gains[m, n, q])`` at
    ``start[m, n] + j``, summed in `out`'s dtype.
    """
    M, N = start.shape
    Q = gains.shape[2]
    K = table.shape[1]
    for m in range(M):
        for q in range(Q):
            out[q, m, :] = 0.0
        for n in range(N):
            s = start[m, n]
            row = table[phase[m, n]]
            for q in range(Q):  # taps innermost: contiguous, vectorised (2x faster)
                g = out.dtype.type(scale[m, n] * gains[m, n, q])
                if g == 0.0:  # e.g. an echo in the direct path's set: nothing to add
                    continue
                a = out[q, m, s : s + K]
                for j in range(K):
                    a[j] += row[j] * g


@njit(cache=True, nogil=True)
def placed(d, phases, taps, n_span, nearest):  # pragma: no cover - compiled
    """Each impulse's first tap and table row: :func:`acousim.synth.render._taps`
    and the buffer layout of ``_impulses`` in one pass (the same operations: the
    same numbers).  d (M, N) float64: impulse positions, samples from the span's
    start; `phases`: the table's fractions (rows less one); `taps`: half the taps;
    `nearest`: one tap at the rounded position.  Returns start (M, N) int64, the
    buffer index of the first tap, and phase (M, N) intp, the row."""
    pad = taps + 1
    start = np.empty(d.shape, np.int64)
    phase = np.zeros(d.shape, np.intp)
    for m in range(d.shape[0]):
        for n in range(d.shape[1]):
            x = d[m, n]
            if nearest:
                start[m, n] = min(max(int(np.rint(x)), -pad), n_span + pad - 1) + pad
            else:
                n0 = np.floor(x)
                phase[m, n] = int(np.rint((x - n0) * phases))
                start[m, n] = min(max(int(n0), -1), n_span) + pad + 1 - taps
    return start, phase
