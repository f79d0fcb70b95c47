"""Compiled steps 3-4 of the first-order integral
(:func:`acousim.trace.diffraction.btm._integrate`; numba, optional: without numba
the numpy form there runs).

The arithmetic around the transcendental functions, one pass over the K elements
each: :func:`eta_argument` (cosh(eta) - 1 and the argument of the log of
``acosh(1 + x)``) before numpy's log1p, and :func:`impulses` (each element's
integral, weight and amplitude, the elements kept, their points) after numpy's
tanh and arctan2.  Those three stay numpy's (its vectorised log1p, tanh and
arctan2 differ from the C library's by an ulp in some arguments); the rest are
the same operations in the same order as the numpy form (+, -, *, /, sqrt,
hypot: correctly rounded or the same C function), so the elements are the same
bit for bit (``tests/acousim/trace/diffraction/test_element_kernel.py``).
``error_model="numpy"``: a division by zero gives inf or nan as in numpy.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_jit = njit(cache=True, nogil=True, error_model="numpy")


@_jit
def eta_argument(z_end, z_start, first, edge, per_edge, out):  # pragma: no cover - compiled
    """``x + sqrt(x (x + 2))`` (np.maximum(x, 0) first) into out (K + F,), x =
    cosh(eta) - 1 without cancellation at every element's end z_end (K,) (edge
    `edge` (K,)), then at the start z_start (K,) of each element first (F,
    indices); per_edge (7, E): rS, rR, zS, zR, z_mid, rS + rR, rS rR."""
    n_k = z_end.size
    for i in range(out.size):
        if i < n_k:
            z, k = z_end[i], edge[i]
        else:
            j = first[i - n_k]
            z, k = z_start[j], edge[j]
        rs, rr, zs, zr = per_edge[0, k], per_edge[1, k], per_edge[2, k], per_edge[3, k]
        a, b = z - zs, z - zr
        ml = math.hypot(rs, a) * math.hypot(rr, b)
        v = per_edge[5, k] * (z - per_edge[4, k])
        x = (v * v) / ((ml - a * b + per_edge[6, k]) * rs * rr)
        if not (x >= 0.0 or x != x):  # np.maximum(x, 0.0)
            x = 0.0
        out[i] = x + math.sqrt(x * (x + 2.0))


@_jit
def impulses(eta, prim, cuts, edge_rows, out):  # pragma: no cover - compiled
    """Each element's amplitude, legs and point, the kept ones (deta > 0, amplitude
    not 0) packed at the front of out; returns their number.

    eta, prim (K + F,): eta and the weighted primitive at every element's end, then
    at the start of each first element; cuts: (first (K,) bool, za, zb, zc, taper
    (K,), edge (K,)); edge_rows: (rS, rR, zS, zR, nu (E,), start, axis (E, 3));
    out: (amp, m, l (K,), point (K, 3), edge (K,))."""
    first, za, zb, zc, taper, edge = cuts
    rs_e, rr_e, zs_e, zr_e, nu_e, start, axis = edge_rows
    amp_o, m_o, l_o, pts_o, edge_o = out
    n_k = za.size
    f = 0
    kept = 0
    for i in range(n_k):
        if first[i]:
            ea, pa = eta[n_k + f], prim[n_k + f]
            f += 1
        else:
            ea, pa = eta[i - 1], prim[i - 1]
        k = edge[i]
        nu = nu_e[k]
        integral = (2 / nu) * (prim[i] - pa)
        deta = abs(eta[i] - ea)
        m_c = math.hypot(rs_e[k], zc[i] - zs_e[k])
        l_c = math.hypot(rr_e[k], zc[i] - zr_e[k])
        ok = deta > 0
        w = abs(zb[i] - za[i]) / deta if ok else 0.0
        weight = w / (m_c * l_c)
        amp = -(nu / (4 * np.pi)) * weight * integral * taper[i]
        if ok and amp != 0:
            amp_o[kept], m_o[kept], l_o[kept], edge_o[kept] = amp, m_c, l_c, k
            for c in range(3):
                pts_o[kept, c] = start[k, c] + zc[i] * axis[k, c]
            kept += 1
    return kept


@_jit
def _clip(x, lo, hi):  # pragma: no cover - compiled
    """np.clip of one number (nan stays nan)."""
    if x == x:
        x = x if x > lo else lo
    if x == x:
        x = x if x < hi else hi
    return x


@_jit
def _root(line, path, upper):  # pragma: no cover - compiled
    """btm._spheroid_roots of one line (8,) and path (m)."""
    c2, eu2, one_eu2, y0u, eu, y0e_u, y0u2, y0y0_u = line
    half = 0.5 * path
    a2 = half * half
    b2 = a2 - c2
    if not (b2 >= 0.0 or b2 != b2):  # np.maximum(b2, 0.0)
        b2 = 0.0
    q2 = b2 * eu2 + a2 * one_eu2
    q1 = 2 * (b2 * y0u * eu + a2 * y0e_u)
    q0 = b2 * y0u2 + a2 * y0y0_u - a2 * b2
    d = q1 * q1 - 4 * q2 * q0
    if not (d >= 0.0 or d != d):
        d = 0.0
    root = math.sqrt(d)
    return (-q1 + (root if upper else -root)) / (2 * q2)


@_jit
def cut_points(steps, sides, lines, apex, max_excess_m, out):  # pragma: no cover - compiled
    """The ends, centres and starts along the edge and the taper of K elements
    (btm._cut's step 2 after the excess steps) into out (za, zb, zc, taper (K,)).

    steps: (side (K,), index within the side (K,), start and end excess (K,));
    sides: (edge of each side (S,), its span lo and hi (S,), cut (S,) bool);
    lines (8, E): btm._spheroid_lines; apex: (path at the apex, z of the apex (E,))."""
    side_of, j, ea_ex, eb_ex = steps
    side_edge, lo, hi, cut = sides
    l_apex, z_apex = apex
    za, zb, zc, taper = out
    half = max_excess_m / 2
    for i in range(side_of.size):
        s = side_of[i]
        k = side_edge[s]
        mid = 0.5 * (ea_ex[i] + eb_ex[i])
        upper = (s % 2) == 1
        line = (
            lines[0, k], lines[1, k], lines[2, k], lines[3, k],
            lines[4, k], lines[5, k], lines[6, k], lines[7, k],
        )  # fmt: skip
        zb[i] = _clip(_root(line, l_apex[k] + eb_ex[i], upper), lo[s], hi[s])
        zc[i] = _clip(_root(line, l_apex[k] + mid, upper), lo[s], hi[s])
        if j[i] == 0:
            za[i] = z_apex[k]
        else:
            za[i] = zb[i - 1]
        if cut[s]:
            x = _clip((mid - half) / half, 0.0, 1.0)
            taper[i] = 0.5 * (1 + math.cos(np.pi * x))
        else:
            taper[i] = 1.0
