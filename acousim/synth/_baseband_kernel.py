"""Compiled accumulation of :mod:`acousim.synth.baseband` (numba; optional: without
numba the renderer builds the same sums with numpy)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def accumulate(q, gains, sets, table, spin, grid, out):  # pragma: no cover - compiled
    """Sum of complex weighted kernels into `out` (M, B, R, 2) float64 (the real and
    imaginary parts, the sets innermost: one impulse's writes are adjacent), zero.

    q (M, N): impulse positions (samples of the full rate); gains (M, N, S) float64,
    of which the R sets `sets` (R,) int64 are summed; grid (3,): turn, scale and
    offset, turn: the centre frequency in radians per sample (each impulse is turned by
    ``exp(-i turn q)``); scale: coarse points per sample; table (P + 1, W): the
    kernel's tap weights at P + 1 fractions of a coarse point; offset: buffer index of
    coarse point 0 less (W // 2 - 1).  Impulse (m, n) adds
    ``table[p, j] exp(-i turn q) gains[m, n, r]`` to row r of microphone m at
    ``floor(u) + offset + j`` (its real and imaginary parts), u = q scale, p the
    nearest tabulated fraction of u; spin (K, 2): cos and -sin of ``turn k`` for
    the whole samples k (K above every position).
    """
    turn, scale, offset = grid[0], grid[1], int(grid[2])
    M, N = q.shape
    R = sets.size
    P = table.shape[0] - 1
    W = table.shape[1]
    for m in range(M):
        for n in range(N):
            x = q[m, n]
            u = x * scale
            i0 = np.floor(u)
            row = table[int(np.rint((u - i0) * P))]
            s = int(i0) + offset
            # exp(-i turn x): the whole samples' turn looked up, the fraction's
            # (at most `turn` rad) by its Taylor series (error below 2e-7)
            k = int(np.floor(x))
            t = turn * (x - k)
            t2 = t * t
            c = 1.0 - t2 / 2 * (1.0 - t2 / 12 * (1.0 - t2 / 30 * (1.0 - t2 / 56)))
            sn = t * (1.0 - t2 / 6 * (1.0 - t2 / 20 * (1.0 - t2 / 42 * (1.0 - t2 / 72))))
            zr = spin[k, 0] * c + spin[k, 1] * sn
            zi = spin[k, 1] * c - spin[k, 0] * sn
            for r in range(R):
                g = gains[m, n, sets[r]]
                if g == 0.0:
                    continue
                ar, ai = zr * g, zi * g
                for j in range(W):
                    out[m, s + j, r, 0] += row[j] * ar
                    out[m, s + j, r, 1] += row[j] * ai
