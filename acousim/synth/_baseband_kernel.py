"""Compiled passes of :mod:`acousim.synth.baseband` (numba; optional: without numba
the renderer builds the same sums with numpy).

:func:`accumulate` spreads the impulses over the coarse grids, one grid per gain set
and microphone, in the layout the coarse FFTs read (sets, microphones, points),
folding the kernel's taps that run past either end of a grid back onto its other
end (the grid is circular) and clearing the grids itself (its buffer need not be
zero: its memory is touched once, in cache).  :func:`band_products` sums the sets'
coarse spectra times their filters straight into the rows of the n-point real
spectra the inverse FFTs read, zero outside the band.  The GIL is released.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def accumulate(q, gains, sets, table, spin, grid, out):  # pragma: no cover - compiled
    """Sums of complex weighted kernels written into `out` (R, M, 2 nb): the real
    and imaginary parts of R x M coarse grids of nb points side by side (a complex
    array's float view, float32 or float64: the sums' precision); its contents
    before are not read (every element is written).

    q (M, N): impulse positions (samples of the full rate); gains (M, N, S) float64,
    of which the R sets `sets` (R,) int64 are summed; grid (3,): turn, scale and
    offset, turn: the centre frequency in radians per sample (each impulse is turned
    by ``exp(-i turn q)``); scale: coarse points per sample; offset: the coarse
    point of an impulse's first tap less ``floor(q scale)``, ``-(W // 2 - 1)``;
    table (P + 1, W): the kernel's tap weights at P + 1 fractions of a coarse point.
    Impulse (m, n) adds ``table[p, j] exp(-i turn q) gains[m, n, sets[r]]`` to grid
    (r, m) at point ``(floor(u) + offset + j) mod nb``, u = q scale, p the nearest
    tabulated fraction of u; spin (K, 2): cos and -sin of ``turn k`` for the whole
    samples k (K above every position).
    """
    turn, scale, offset = grid[0], grid[1], int(grid[2])
    M, N = q.shape
    R, nb = sets.size, out.shape[2] // 2
    P = table.shape[0] - 1
    W = table.shape[1]
    w = np.empty(2 * W, out.dtype)  # an impulse's taps turned: re, im, re, im, ...
    for m in range(M):
        for r in range(R):
            out[r, m, :] = 0.0
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
            for j in range(W):
                w[2 * j] = row[j] * zr
                w[2 * j + 1] = row[j] * zi
            inside = s >= 0 and s + W <= nb
            for r in range(R):
                g = out.dtype.type(gains[m, n, sets[r]])
                if g == 0.0:  # e.g. the direct path in an echoes' set
                    continue
                a = out[r, m]
                if inside:
                    b = 2 * s
                    for j in range(2 * W):  # contiguous: vectorised
                        a[b + j] += w[j] * g
                else:  # the taps past an end wrap round (a circular grid)
                    for j in range(W):
                        i = (s + j) % nb
                        a[2 * i] += w[2 * j] * g
                        a[2 * i + 1] += w[2 * j + 1] * g


@njit(cache=True, nogil=True)
def band_products(spectra, filters, half, b0, out):  # pragma: no cover - compiled
    """Rows `out` (M, F) complex written whole: bin ``b0 + i`` (0 <= i <= 2 half)
    the sum over the sets r of ``spectra[r, m, (i - half) mod nb] filters[r, i]``,
    every other bin zero.  spectra (R, M, nb): the sets' coarse spectra; filters (R,
    2 half + 1): the sets' filters over the band (divided by the kernel's
    transform)."""
    R, M, nb = spectra.shape
    K = filters.shape[1]
    for m in range(M):
        o = out[m]
        o[:b0] = 0.0
        o[b0 + K :] = 0.0
        for i in range(K):
            k = i - half
            if k < 0:
                k += nb
            acc = spectra[0, m, k] * filters[0, i]
            for r in range(1, R):
                acc += spectra[r, m, k] * filters[r, i]
            o[b0 + i] = acc


@njit(cache=True, nogil=True)
def set_energy(gains):  # pragma: no cover - compiled
    """The sum of squares (R,) of each set of `gains` (M, N, R) float64 over its
    microphones and paths."""
    M, N, R = gains.shape
    out = np.zeros(R)
    for m in range(M):
        for n in range(N):
            for r in range(R):
                out[r] += gains[m, n, r] * gains[m, n, r]
    return out
