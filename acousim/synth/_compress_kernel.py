"""Compiled sums of the gain-set compression (:mod:`acousim.synth.compress`; numba,
optional: without numba the same sums run as batched matrix products in numpy).

Both kernels form the path gains times the Chebyshev terms of their Doppler factors,
``t_p = g T_p(s)``, on the fly from g and s (M, N) by the three-term recurrence of
:func:`acousim.synth.compress.chebyshev_terms` (the same operations: the same
bits): :func:`term_gram` sums their products over the microphones per path (the
paths side by side in blocks: the sums vectorise; in the order of the microphones,
which may round differently from a matrix product's order), :func:`terms` stores
them path by path for the batched matrix product (numpy's: BLAS) that mixes them
into the compressed sets' gains.  The GIL is released.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: paths per block: the block's terms (K x BLOCK) and sums stay in the L1 cache
BLOCK = 256


@njit(cache=True, nogil=True)
def _terms(gain, s, m, n0, B, T):  # pragma: no cover - compiled
    """T[p, :B] <- gain[m, n0 + i] T_p(s[m, n0 + i]), p < K: the recurrence of
    :func:`acousim.synth.compress.chebyshev_terms`, its operations."""
    K = T.shape[0]
    g, x = gain[m, n0 : n0 + B], s[m, n0 : n0 + B]
    t0 = T[0]
    for i in range(B):
        t0[i] = g[i]
    if K > 1:
        t1 = T[1]
        for i in range(B):
            t1[i] = g[i] * x[i]
        for p in range(2, K):
            tp, ta, tb = T[p], T[p - 1], T[p - 2]
            for i in range(B):
                tp[i] = (x[i] * 2) * ta[i] - tb[i]


@njit(cache=True, nogil=True)
def term_gram(gain, s, out):  # pragma: no cover - compiled
    """out (K, K, N) <- ``sum_m t_j t_k`` per path n, t_p = gain[m, n] T_p(s[m, n]),
    summed in the order of m; gain, s (M, N) float64 (s unused when K = 1)."""
    M, N = gain.shape
    K = out.shape[0]
    T = np.empty((K, BLOCK))
    for n0 in range(0, N, BLOCK):
        B = min(BLOCK, N - n0)
        for j in range(K):
            for k in range(j, K):
                out[j, k, n0 : n0 + B] = 0.0
        for m in range(M):
            _terms(gain, s, m, n0, B, T)
            for j in range(K):
                tj = T[j]
                for k in range(j, K):
                    tk, o = T[k], out[j, k, n0 : n0 + B]
                    for i in range(B):
                        o[i] += tj[i] * tk[i]
        for j in range(K):
            for k in range(j):
                out[j, k, n0 : n0 + B] = out[k, j, n0 : n0 + B]


@njit(cache=True, nogil=True)
def terms(gain, s, out):  # pragma: no cover - compiled
    """out (N, K, M) <- t_p = gain[m, n] T_p(s[m, n]); gain, s (M, N) float64 (s
    unused when K = 1)."""
    M, N = gain.shape
    K = out.shape[1]
    for n in range(N):
        T = out[n]
        t0 = T[0]
        for m in range(M):
            t0[m] = gain[m, n]
        if K > 1:
            t1 = T[1]
            for m in range(M):
                t1[m] = gain[m, n] * s[m, n]
            for p in range(2, K):
                tp, ta, tb = T[p], T[p - 1], T[p - 2]
                for m in range(M):
                    tp[m] = (s[m, n] * 2) * ta[m] - tb[m]
