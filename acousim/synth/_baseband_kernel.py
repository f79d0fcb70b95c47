"""Compiled accumulation of :mod:`acousim.synth.baseband` (numba; optional: without
numba the renderer builds the same sums with numpy)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def accumulate(q, gains, turn, scale, table, offset, out):  # pragma: no cover - compiled
    """Sum of complex weighted kernels into `out` (R, M, B) complex, which must be zero.

    q (M, N): impulse positions (samples of the full rate); gains (M, N, R) float64;
    turn: the centre frequency in radians per sample (each impulse is turned by
    ``exp(-i turn q)``); scale: coarse points per sample; table (P + 1, W): the
    kernel's tap weights at P + 1 fractions of a coarse point; offset: buffer index of
    coarse point 0 less (W // 2 - 1).  Impulse (m, n) adds
    ``table[p, j] exp(-i turn q) gains[m, n, r]`` to row r of microphone m at
    ``floor(u) + offset + j``, u = q scale, p the nearest tabulated fraction of u.
    """
    M, N = q.shape
    R = gains.shape[2]
    P = table.shape[0] - 1
    W = table.shape[1]
    for m in range(M):
        for n in range(N):
            x = q[m, n]
            u = x * scale
            i0 = np.floor(u)
            row = table[int(np.rint((u - i0) * P))]
            s = int(i0) + offset
            z = np.cos(turn * x) - 1j * np.sin(turn * x)
            for r in range(R):
                g = gains[m, n, r]
                if g == 0.0:
                    continue
                a = z * g
                o = out[r, m, s : s + W]
                for j in range(W):
                    o[j] += row[j] * a
