"""Compression of the Doppler renderer's gain sets (:mod:`acousim.synth.doppler`):
the K x Q products of Doppler terms and path-response terms, per group of paths,
to the few sets their sum needs (a real SVD from Gram matrices)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from processing.base.kernels import optional_kernel

__all__ = ["compress", "ChebyshevGains", "chebyshev_terms", "coarse_products"]


def chebyshev_terms(s: np.ndarray, gain: np.ndarray, K: int) -> np.ndarray:
    """``gain T_p(s)`` (K, ...) for p < K (a three-term recurrence); s and gain
    (...) broadcast together (s, in [-1, 1], unused when K = 1)."""
    out = np.empty((K, *np.broadcast_shapes(np.shape(s), np.shape(gain))))
    out[0] = gain
    if K > 1:
        np.multiply(gain, s, out=out[1])
        s = s * 2
        for p in range(2, K):
            np.multiply(s, out[p - 1], out=out[p])
            out[p] -= out[p - 2]
    return out


@dataclass(frozen=True, eq=False)
class ChebyshevGains:
    """The path gains times the Chebyshev terms of their Doppler factors, held as
    their factors: ``t_p[m, n] = gain[m, n] T_p(s[m, n])``, p < K.

    gain (M, N) the path gains at the microphones; s (M, N) their Doppler factors
    mapped onto [-1, 1] (:func:`acousim.synth.doppler.plan_doppler`; None when K =
    1).  The compression needs two sums of them (:meth:`gram`, :meth:`times`): they
    run compiled (:mod:`._compress_kernel`) without storing the K x N x M terms, or
    without numba as matrix products of :meth:`dense`.
    """

    gain: np.ndarray
    s: np.ndarray | None
    K: int

    @property
    def n_paths(self) -> int:
        return self.gain.shape[1]

    def dense(self) -> np.ndarray:
        """The terms (K, N, M)."""
        s = None if self.s is None else self.s.T
        return chebyshev_terms(s, self.gain.T, self.K)

    def _args(self):
        gain = np.ascontiguousarray(self.gain, float)
        return gain, gain if self.s is None else np.ascontiguousarray(self.s, float)

    def gram(self) -> np.ndarray:
        """``X[j, k, n] = sum_m t_j[m, n] t_k[m, n]`` (K, K, N)."""
        kernel = _kernel("term_gram")
        if kernel is None:
            return _Dense(self.dense()).gram()
        out = np.empty((self.K, self.K, self.n_paths))
        kernel(*self._args(), out)
        return out

    def terms(self) -> np.ndarray:
        """The terms path by path (N, K, M)."""
        kernel = _kernel("terms")
        if kernel is None:
            return self.dense().transpose(1, 0, 2)
        out = np.empty((self.n_paths, self.K, self.gain.shape[0]))
        kernel(*self._args(), out)
        return out

    def times(self, P: np.ndarray) -> np.ndarray:
        """``g[m, n, r] = sum_p t_p[m, n] P[n, p, r]`` (M, N, R) from P (N, K, R)."""
        return _times(self.terms(), P)


def _times(A: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``g[m, n, r] = sum_p A[n, p, m] P[n, p, r]`` (M, N, R), stored (M, N, R), the
    sets innermost as the impulse sums take them: a batched matrix product."""
    N, K, M = A.shape
    out = np.empty((M, N, P.shape[2]))
    np.matmul(A.transpose(0, 2, 1), P, out=out.transpose(1, 0, 2))
    return out


def _kernel(name: str):
    """The compiled sum `name` of :mod:`._compress_kernel`, or None without numba."""
    return optional_kernel("acousim.synth._compress_kernel", name)


def compress(gl, V, W, WW, U, path_direct, set_direct, tolerance):
    """Sets of impulse gains and their filters: ``sum_(j,q) h(g l_j v_q) * b_jq``
    with fewer sets.

    gl (:class:`ChebyshevGains`, K terms, N paths, M microphones) path gains times
    the Doppler terms (term j, path n, microphone m: :func:`chebyshev_terms` of
    :func:`acousim.synth.doppler._chebyshev_argument`; or those terms as an array
    (K, N, M)), V (N, Q) response terms; the filters ``b_jq(f) = W_j(f) U_q(f)`` from the
    template spectra W (K, F), their products WW (:func:`acousim.synth.doppler._products`;
    or, when U is the linear interpolation of Uc (F', Q) from a coarse grid, the pair
    (:func:`coarse_products` of them, Uc): the filters' Gram matrix is formed there,
    the same sums over F' instead of F) and the response terms U (F, Q); path_direct
    (N,) and set_direct (Q,) which paths and response terms belong to the direct
    path.  Per group of paths (the direct path, the echoes), with G (paths x S) the
    gains and B (F x S) the filters (S = K Q' sets): ``G B^T = U' D``, ``G = U'
    L^(1/2) E^T`` (eigendecomposition of the Gram matrix G^T G, formed from the
    factors without G), ``D = L^(1/2) E^T B^T``; the real SVD of D (real and
    imaginary parts side by side, from its Gram matrix) truncated where the
    discarded energy falls below `tolerance`^2 of the total gives real gains ``G E
    L^(-1/2) Y_r`` and filters ``Y_r^T D``.  Returns (gains (M, N, R), filters (F,
    R)).
    """
    if isinstance(gl, np.ndarray):  # the terms themselves (K, N, M)
        gl = _Dense(gl)
    K, N = gl.K, gl.n_paths
    # per path, sum over microphones of g^2 l_j l_k: (K K, N), for every group
    X = gl.gram().reshape(K * K, N)
    Wr = np.ascontiguousarray(W, complex).view(float)  # (K, 2 F)
    out_p, out_f = [], []
    for group in (True, False):
        paths = path_direct == group
        terms = set_direct == group
        if not paths.any() or not terms.any():
            continue
        # a small group (the direct path) by its own paths, a large one on all
        # (zero off the group): the same sums
        few = np.flatnonzero(paths) if paths.sum() * 4 < N else slice(None)
        Vp = np.where(paths[few, None], V[few][:, terms], 0.0)  # (N', Q')
        found = _group_gram(X[:, few], Vp, K)
        if found is None:
            continue
        S, E_scaled = found
        if isinstance(WW, tuple):  # folded onto the coarse grid
            BB = _coarse_filter_gram(WW[0], WW[1][:, terms], K)
        else:
            BB = _filter_gram(WW, U[:, terms], K)
        s2, Y = np.linalg.eigh(S @ BB @ S.T)
        s2, Y = np.maximum(s2[::-1], 0.0), Y[:, ::-1]
        tail = np.cumsum(s2[::-1])[::-1]  # energy from index r on
        r = max(1, int(np.sum(tail > tolerance**2 * tail[0])))
        out_p.append(_group_gains(Vp, (E_scaled @ Y[:, :r]).reshape(K, -1, r), few, N))
        out_f.append(_group_filters((Y[:, :r].T @ S).T, Wr, U[:, terms]))
    # the new gains of all groups at once: g_new[m, n] = gl[:, n, m] P[n]
    P = np.concatenate(out_p, axis=2)  # (N, K, R)
    return gl.times(P), np.concatenate(out_f, axis=0).T


def _group_gram(X: np.ndarray, Vp: np.ndarray, K: int):
    """The Gram matrix G^T G of a group's gains ``G[(m, n), (j, q)] = g l_j(a_mn)
    v_nq`` from its factors: X (K K, N') and Vp (N', Q); its eigendecomposition
    ``L, E`` (the eigenvalues above 1e-13 of the largest): (``S = L^(1/2) E^T``,
    ``E L^(-1/2)``), or None when it has none."""
    Q = Vp.shape[1]
    VV = Vp[:, :, None] * Vp[:, None, :]  # (n, q, r)
    gram = (X @ VV.reshape(-1, Q * Q)).reshape(K, K, Q, Q)
    gram = gram.transpose(0, 2, 1, 3).reshape(K * Q, K * Q)
    lam, E = np.linalg.eigh(gram)
    keep = lam > 1e-13 * max(lam.max(), 1e-300)
    if not keep.any():
        return None
    lam, E = lam[keep], E[:, keep]
    return np.sqrt(lam)[:, None] * E.T, E / np.sqrt(lam)  # D = S B^T, (s, F)


def _group_gains(Vp: np.ndarray, T: np.ndarray, few, N: int) -> np.ndarray:
    """A group's P (N, K, r): ``P[n, j, s] = sum_q Vp[n, q] T[j, q, s]`` (T (K, Q,
    r)) on the group's paths `few` (indices, or all), zero elsewhere."""
    K, Q, r = T.shape
    Pg = (Vp @ T.transpose(1, 0, 2).reshape(Q, K * r)).reshape(-1, K, r)
    if isinstance(few, np.ndarray):  # zero off the group
        Pg, part = np.zeros((N, K, r)), Pg
        Pg[few] = part
    return Pg


def _group_filters(Tf: np.ndarray, Wr: np.ndarray, Uq: np.ndarray) -> np.ndarray:
    """A group's filters (r, F) ``sum_jq W_j U_q Tf[(j, q)] = sum_q U_q Z_q``, ``Z_q =
    sum_j W_j Tf[(j, q)]`` (F,) each: one real product with W's real and imaginary
    parts side by side, Wr (K, 2 F); Tf (K Q, r), Uq (F, Q)."""
    K, Q = Wr.shape[0], Uq.shape[1]
    r = Tf.shape[1]
    Z = (Tf.reshape(K, Q * r).T @ Wr).view(complex).reshape(Q, r, -1)  # (Q, r, F)
    filt = Z[0] * Uq[:, 0]
    for q in range(1, Q):
        filt += Z[q] * Uq[:, q]
    return filt


@dataclass(frozen=True, eq=False)
class _Dense:
    """Terms given as an array (K, N, M): :class:`ChebyshevGains`' sums in numpy."""

    terms: np.ndarray

    @property
    def K(self) -> int:
        return self.terms.shape[0]

    @property
    def n_paths(self) -> int:
        return self.terms.shape[1]

    def gram(self) -> np.ndarray:
        A = self.terms.transpose(1, 0, 2)  # (N, K, M)
        return np.matmul(A, A.transpose(0, 2, 1)).transpose(1, 2, 0)

    def times(self, P: np.ndarray) -> np.ndarray:
        return _times(self.terms.transpose(1, 0, 2), P)


def _filter_gram(WW: np.ndarray, Uq: np.ndarray, K: int) -> np.ndarray:
    """Re(B^T conj(B)) (K Q, K Q) of the filters ``b_jq = W_j U_q`` from the template
    products WW (:func:`acousim.synth.doppler._products`) and the response terms
    Uq (F, Q): both symmetric, the upper triangles only."""
    qa, qb = _triu(Uq.shape[1])
    return _symmetric_gram(WW @ (Uq[:, qa] * Uq[:, qb]), K, Uq.shape[1])


def _coarse_filter_gram(MM: np.ndarray, Uc: np.ndarray, K: int) -> np.ndarray:
    """:func:`_filter_gram` of the response terms interpolated from Uc (F', Q) on
    the coarse grid, from the template products folded onto it, MM
    (:func:`coarse_products`): ``Uc_q^T MM_jk Uc_r``."""
    J, C, _ = MM.shape
    Q = Uc.shape[1]
    qa, qb = _triu(Q)
    part = (MM.reshape(J * C, C) @ Uc).reshape(J, C, Q).transpose(0, 2, 1)  # MM_j Uc
    part = (part.reshape(J * Q, C) @ Uc).reshape(J, Q, Q)[:, qa, qb]
    return _symmetric_gram(part, K, Q)


def coarse_products(WW: np.ndarray, fb: np.ndarray, coarse: np.ndarray) -> np.ndarray:
    """The template products WW (J, F) folded onto a coarse grid: ``MM_j = L^T
    diag(WW_j) L`` (J, F', F'), L (F, F') the linear interpolation (np.interp's,
    the end values held beyond the grid) from `coarse` (F',) to the bins' frequencies
    `fb` (F,), so that ``sum_f WW_j(f) u(f) v(f) = u_c^T MM_j v_c`` for u = L u_c, v =
    L v_c (tridiagonal; per drive: the grid and the templates are shared by its
    poses)."""
    C = coarse.size
    J = WW.shape[0]
    if C < 2:
        return WW.sum(axis=1).reshape(J, 1, 1)
    i = np.clip(np.searchsorted(coarse, fb, side="right") - 1, 0, C - 2)
    t = np.clip((fb - coarse[i]) / (coarse[i + 1] - coarse[i]), 0.0, 1.0)
    a, b = 1 - t, t
    out = np.zeros((J, C * C))
    for idx, w in ((i * C + i, a * a), ((i + 1) * (C + 1), b * b), (i * C + i + 1, a * b)):
        for j in range(J):
            out[j] += np.bincount(idx, WW[j] * w, minlength=C * C)
    out = out.reshape(J, C, C)
    upper = np.arange(C - 1)
    out[:, upper + 1, upper] = out[:, upper, upper + 1]
    return out


@lru_cache(maxsize=64)
def _triu(k: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(k)``, read-only, computed once per k (a compression asks
    for a few, six times: 0.1 ms each)."""
    rows, cols = np.triu_indices(k)
    rows.flags.writeable = cols.flags.writeable = False
    return rows, cols


def _symmetric_gram(part: np.ndarray, K: int, Q: int) -> np.ndarray:
    """The Gram matrix (K Q, K Q) from its upper triangles in j <= k and q <= r,
    part (K (K + 1) / 2, Q (Q + 1) / 2) in the order of ``np.triu_indices``."""
    qa, qb = _triu(Q)
    full = np.empty((K, K, Q, Q))
    ja, jb = (i[:, None] for i in _triu(K))
    full[ja, jb, qa, qb] = full[jb, ja, qa, qb] = part
    full[ja, jb, qb, qa] = full[jb, ja, qb, qa] = part
    return full.transpose(0, 2, 1, 3).reshape(K * Q, K * Q)
