"""Compression of the Doppler renderer's gain sets (:mod:`acousim.synth.doppler`):
the K x Q products of Doppler terms and path-response terms, per group of paths,
to the few sets their sum needs (a real SVD from Gram matrices)."""

from __future__ import annotations

import numpy as np

__all__ = ["compress"]


def compress(gl, V, W, WW, U, path_direct, set_direct, tolerance):
    """Sets of impulse gains and their filters: ``sum_(j,q) h(g l_j v_q) * b_jq``
    with fewer sets.

    gl (K, N, M) path gains times the Doppler terms (term j, path n, microphone m:
    the Chebyshev polynomials of :func:`acousim.synth.doppler._chebyshev_terms`),
    V (N, Q) response terms; the filters ``b_jq(f) = W_j(f) U_q(f)`` from the
    template spectra W (K, F), their products WW (:func:`acousim.synth.doppler._products`)
    and the response terms U (F, Q); path_direct (N,) and set_direct (Q,) which paths
    and response terms belong to the direct path.  Per group of paths (the direct
    path, the echoes), with G (paths x S) the gains and B (F x S) the filters
    (S = K Q' sets): ``G B^T = U' D``, ``G = U' L^(1/2) E^T`` (eigendecomposition of
    the Gram matrix G^T G, formed from the factors without G), ``D = L^(1/2) E^T
    B^T``; the real SVD of D (real and imaginary parts side by side, from its Gram
    matrix) truncated where the discarded energy falls below `tolerance`^2 of the
    total gives real gains ``G E L^(-1/2) Y_r`` and filters ``Y_r^T D``.  Returns
    (gains (M, N, R), filters (F, R)).
    """
    K, N, M = gl.shape
    A = gl.transpose(1, 0, 2)  # (N, K, M)
    # per path, sum over microphones of g^2 l_j l_k: (N, K, K), for every group
    X = np.matmul(A, A.transpose(0, 2, 1))
    out_p, out_f = [], []
    for group in (True, False):
        paths = path_direct == group
        terms = set_direct == group
        if not paths.any() or not terms.any():
            continue
        Vp = np.where(paths[:, None], V[:, terms], 0.0)  # (N, Q'): zero off the group
        Q = Vp.shape[1]
        # Gram matrix of G[(m, n), (j, q)] = g l_j(a_mn) v_nq, from its factors
        VV = Vp[:, :, None] * Vp[:, None, :]  # (n, q, r)
        gram = (X.reshape(-1, K * K).T @ VV.reshape(-1, Q * Q)).reshape(K, K, Q, Q)
        gram = gram.transpose(0, 2, 1, 3).reshape(K * Q, K * Q)
        lam, E = np.linalg.eigh(gram)
        keep = lam > 1e-13 * max(lam.max(), 1e-300)
        if not keep.any():
            continue
        lam, E = lam[keep], E[:, keep]
        Uq = U[:, terms]
        S = np.sqrt(lam)[:, None] * E.T  # D = S B^T, (s, F)
        BB = _filter_gram(WW, Uq, K)
        s2, Y = np.linalg.eigh(S @ BB @ S.T)
        s2, Y = np.maximum(s2[::-1], 0.0), Y[:, ::-1]
        tail = np.cumsum(s2[::-1])[::-1]  # energy from index r on
        r = max(1, int(np.sum(tail > tolerance**2 * tail[0])))
        T = ((E / np.sqrt(lam)) @ Y[:, :r]).reshape(K, Q, r)
        out_p.append((Vp @ T.transpose(1, 0, 2).reshape(Q, K * r)).reshape(N, K, r))
        Tf = (Y[:, :r].T @ S).T  # (K Q, r): filters sum_jq W_j U_q Tf[(j, q)]
        WU = (W.T[:, :, None] * Uq[:, None, :]).reshape(-1, K * Q)  # (F, K Q)
        out_f.append(WU @ Tf)
    # the new gains of all groups at once: g_new[m, n] = gl[:, n, m] P[n], stored
    # (M, N, R), the sets innermost as the impulse sums take them
    P = np.concatenate(out_p, axis=2)  # (N, K, R)
    g_new = np.empty((M, N, P.shape[2]))
    np.matmul(gl.transpose(1, 2, 0), P, out=g_new.transpose(1, 0, 2))
    return g_new, np.concatenate(out_f, axis=1)


def _filter_gram(WW: np.ndarray, Uq: np.ndarray, K: int) -> np.ndarray:
    """Re(B^T conj(B)) (K Q, K Q) of the filters ``b_jq = W_j U_q`` from the template
    products WW (:func:`acousim.synth.doppler._products`) and the response terms
    Uq (F, Q): both symmetric, the upper triangles only."""
    Q = Uq.shape[1]
    qa, qb = np.triu_indices(Q)
    part = WW @ (Uq[:, qa] * Uq[:, qb])
    full = np.empty((K, K, Q, Q))
    ja, jb = np.triu_indices(K)
    for c, (a, b) in enumerate(zip(qa, qb)):
        full[ja, jb, a, b] = full[jb, ja, a, b] = part[:, c]
        full[ja, jb, b, a] = full[jb, ja, b, a] = part[:, c]
    return full.transpose(0, 2, 1, 3).reshape(K * Q, K * Q)
