"""Compiled Newton solve of :func:`acousim.kinematics.retarded._newton_by_axis` (numba;
optional: without numba the same iteration runs on whole arrays in numpy).

Per microphone m (a row), Newton on ``f(t) = t - t_r - |m(t) - A| / c`` for every
path at once, the microphone's position and velocity polynomials in the normalised
time evaluated by Horner's rule with the paths innermost (vectorised by the
compiler), until the row's largest step falls below `stop` (the array version
stops when the whole array's does: the two agree within the stated Newton error,
not to the bit).  The GIL is released, so the renderer's thread runs meanwhile.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def newton(t_r, A, guess, poly, poly_v, mid, half, c, stop, out):  # pragma: no cover - compiled
    """Reception times into `out` (M, N).

    t_r (M, N): when the sound leaves the anchor (s); A (M or 1, 3, N): the anchors
    (m); guess (M, N): starting times (s); poly (M, D + 1, 3) and poly_v (M, D, 3):
    each microphone's position (m) and velocity (m/s) as polynomials in
    ``x = (t - mid) / half`` (coefficients of x^0 first).
    """
    M, N = out.shape
    D = poly.shape[1] - 1
    t = np.empty(N)
    x = np.empty(N)
    p = np.empty((3, N))
    v = np.empty((3, N))
    step = np.empty(N)
    for m in range(M):
        a = 0 if A.shape[0] == 1 else m
        for n in range(N):
            t[n] = guess[m, n]
        for _ in range(20):
            for n in range(N):
                x[n] = (t[n] - mid) / half
            for i in range(3):
                for n in range(N):
                    p[i, n] = poly[m, D, i]
                    v[i, n] = poly_v[m, D - 1, i]
                for k in range(D - 1, -1, -1):
                    ck = poly[m, k, i]
                    for n in range(N):
                        p[i, n] = p[i, n] * x[n] + ck
                for k in range(D - 2, -1, -1):
                    ck = poly_v[m, k, i]
                    for n in range(N):
                        v[i, n] = v[i, n] * x[n] + ck
            for n in range(N):
                dx = p[0, n] - A[a, 0, n]
                dy = p[1, n] - A[a, 1, n]
                dz = p[2, n] - A[a, 2, n]
                dist = np.sqrt(dx * dx + dy * dy + dz * dz)
                slope = 1.0 - (v[0, n] * dx + v[1, n] * dy + v[2, n] * dz) / (max(dist, 1e-12) * c)
                step[n] = (t[n] - t_r[m, n] - dist / c) / slope
                t[n] -= step[n]
            largest = 0.0
            for n in range(N):
                largest = max(largest, abs(step[n]))
            if largest < stop:
                break
        for n in range(N):
            out[m, n] = t[n]


@njit(cache=True, nogil=True)
def newton_pieces(t_r, A, guess, bounds, mid, half, poly, poly_v, c, stop, out):  # pragma: no cover
    """:func:`newton` for motion in pieces (:class:`acousim.kinematics.sensor.Pieces`):
    each iterate evaluates the polynomials of the piece its time falls in.

    bounds (P - 1,), mid (P,), half (P,) (s); poly (P, M, D + 1, 3) and poly_v
    (P, M, D, 3); the rest as :func:`newton`.
    """
    M, N = out.shape
    P = mid.size
    D = poly.shape[2] - 1
    t = np.empty(N)
    x = np.empty(N)
    j = np.empty(N, np.int64)
    p = np.empty((3, N))
    v = np.empty((3, N))
    for m in range(M):
        a = 0 if A.shape[0] == 1 else m
        for n in range(N):
            t[n] = guess[m, n]
        for _ in range(20):
            for n in range(N):
                k = 0
                while k < P - 1 and t[n] >= bounds[k]:
                    k += 1
                j[n] = k
                x[n] = (t[n] - mid[k]) / half[k]
            for i in range(3):
                for n in range(N):
                    p[i, n] = poly[j[n], m, D, i]
                    v[i, n] = poly_v[j[n], m, D - 1, i]
                for k in range(D - 1, -1, -1):
                    for n in range(N):
                        p[i, n] = p[i, n] * x[n] + poly[j[n], m, k, i]
                for k in range(D - 2, -1, -1):
                    for n in range(N):
                        v[i, n] = v[i, n] * x[n] + poly_v[j[n], m, k, i]
            largest = 0.0
            for n in range(N):
                dx = p[0, n] - A[a, 0, n]
                dy = p[1, n] - A[a, 1, n]
                dz = p[2, n] - A[a, 2, n]
                dist = np.sqrt(dx * dx + dy * dy + dz * dz)
                slope = 1.0 - (v[0, n] * dx + v[1, n] * dy + v[2, n] * dz) / (max(dist, 1e-12) * c)
                step = (t[n] - t_r[m, n] - dist / c) / slope
                t[n] -= step
                largest = max(largest, abs(step))
            if largest < stop:
                break
        for n in range(N):
            out[m, n] = t[n]


def solve_pieces(t_r, A, guess, pieces, c, stop) -> np.ndarray:
    """:func:`newton_pieces` into a new array (M, N)."""
    out = np.empty(np.shape(guess))
    newton_pieces(
        t_r,
        A,
        guess,
        pieces.bounds,
        pieces.mid,
        pieces.half,
        pieces.mic_poly,
        pieces.mic_poly_v,
        float(c),
        float(stop),
        out,
    )
    return out


def solve(t_r, A, guess, poly, poly_v, mid, half, c, stop) -> np.ndarray:
    """:func:`newton` into a new array (M, N)."""
    out = np.empty(np.shape(guess))
    newton(t_r, A, guess, poly, poly_v, float(mid), float(half), float(c), float(stop), out)
    return out
