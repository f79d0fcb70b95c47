"""Compiled sum of :mod:`acousim.synth.timedomain` (numba; optional: without numba
the same sums run as numpy products, :func:`acousim.synth.timedomain._add_numpy`).

Per microphone m and path n, the path's filtered call (a row of `calls`) is passed
through the path's 2 * taps fractional-delay weights into a short buffer (each tap a
scaled copy of the call, contiguous and vectorised), and the buffer is added to the
microphone's signal at the path's first tap.  The copies are summed in single
precision (the calls are stored so; 1.4x faster than double, the rounding about
-140 dB of the signal, as the FFT sum's float32 spectra) and added in double.
The GIL is released.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def add_delayed(first, phase, gain, table, calls, row, out):  # pragma: no cover - compiled
    """Add every path's delayed, scaled filtered call into `out` (M, T), in place.

    first (M, N) int64: the output sample of each copy's first sample (may lie
    outside [0, T): the samples outside are dropped); phase (M, N) intp: its row of
    `table` (P, K), the K tap weights; gain (M, N) float64; calls (C, L) float32,
    the filtered calls; row (N,) intp: each path's row of `calls`.  Microphone m
    receives ``gain[m, n] * table[phase[m, n], j] * calls[row[n], i]`` at sample
    ``first[m, n] + j + i``.
    """
    M, N = first.shape
    L = calls.shape[1]
    K = table.shape[1]
    T = out.shape[1]
    buf = np.empty(L + K - 1, np.float32)
    for m in range(M):
        o = out[m]
        for n in range(N):
            g = gain[m, n]
            s = first[m, n]
            i0 = max(0, -s)
            i1 = min(L + K - 1, T - s)
            if g == 0.0 or i1 <= i0:
                continue
            w = table[phase[m, n]]
            f = calls[row[n]]
            buf[:] = 0.0
            for j in range(K):  # one scaled copy per tap: contiguous, vectorised
                c = np.float32(g * w[j])
                b = buf[j : j + L]
                for i in range(L):
                    b[i] += c * f[i]
            for i in range(i0, i1):
                o[s + i] += buf[i]
