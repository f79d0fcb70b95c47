"""Compiled parts of the first-order integral and of its bound (numba, optional:
without numba the numpy forms run): the element ends of
:func:`acousim.trace.diffraction.btm._cut` (:func:`cut_points`), steps 3-4 of
:func:`acousim.trace.diffraction.btm._integrate` and
:func:`acousim.trace.diffraction.first_order.edge_bound`.

The arithmetic around the transcendental functions, one pass over the K elements
(or R edges) each: :func:`eta_argument` (cosh(eta) - 1 and the argument of the
log of ``acosh(1 + x)``) before numpy's log1p, :func:`impulses` (each element's
integral, weight and amplitude, the elements kept, their points) after numpy's
tanh and arctan2; :func:`bound_argument` before numpy's arccosh and cosh,
:func:`bound_rest` after.  Those stay numpy's (its vectorised log1p, tanh,
arctan2, cosh and arccosh differ from the C library's by an ulp in some
arguments); the rest are the same operations in the same order as the numpy
forms (+, -, *, /, sqrt, hypot, sin, cos: correctly rounded or the same C
function; clip, maximum and minimum as numpy's, nan kept; a sum of four terms
left to right as numpy's), so the results are the same bit for bit
(``tests/acousim/trace/diffraction/test_element_kernel.py``).
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


@_jit
def _maximum(a, b):  # pragma: no cover - compiled
    """np.maximum of two numbers (nan if either is)."""
    return a if (a >= b or a != a) else b


@_jit
def _minimum(a, b):  # pragma: no cover - compiled
    """np.minimum of two numbers (nan if either is)."""
    return a if (a <= b or a != a) else b


@_jit
def _apex_legs(rs, zs, rr, zr, length):  # pragma: no cover - compiled
    """first_order.edge_bound's apex (unclipped, clipped), a, b, m and l of one edge."""
    z_mid = (rr * zs + rs * zr) / (rs + rr)
    z_apex = _clip(z_mid, 0.0, length)
    a, b = z_apex - zs, z_apex - zr
    return z_mid, z_apex, a, b, math.hypot(rs, a), math.hypot(rr, b)


@_jit
def bound_argument(source, receiver, length, out):  # pragma: no cover - compiled
    """first_order.edge_bound's cosh(eta) - 1 at the apex of each edge (before
    numpy's arccosh and cosh) into out (R,); source, receiver: (r, theta, z) (R,)."""
    rs_, _, zs_ = source
    rr_, _, zr_ = receiver
    for k in range(out.size):
        rs, zs, rr, zr = rs_[k], zs_[k], rr_[k], zr_[k]
        z_mid, z_apex, a, b, m, l_ = _apex_legs(rs, zs, rr, zr, length[k])
        v = (rs + rr) * (z_apex - z_mid)
        out[k] = (v * v) / ((m * l_ - a * b + rs * rr) * rs * rr)


@_jit
def bound_rest(source, receiver, edge, cosh_nu, step, out):  # pragma: no cover - compiled
    """first_order.edge_bound of each edge into out (R,), after cosh(nu eta) at the
    apex, cosh_nu (R,); source, receiver: (r, theta, z) (R,); edge: (length, nu
    (R,), term weights |w| (R, 4)); step: the element step (m)."""
    rs_, ts_, zs_ = source
    rr_, tr_, zr_ = receiver
    length_, nu_, w = edge
    for k in range(out.size):
        rs, ts, zs, rr, tr, zr = rs_[k], ts_[k], zs_[k], rr_[k], tr_[k], zr_[k]
        length, nu, ch = length_[k], nu_[k], cosh_nu[k]
        z_mid, z_apex, a, b, m, l_ = _apex_legs(rs, zs, rr, zr, length)
        total = 0.0
        for i in range(4):
            q = ts + tr if i == 0 else ts - tr if i == 1 else -ts + tr if i == 2 else -ts - tr
            nu_phi = 2 * (nu * (np.pi + q) / 2)
            gap = ch - math.cos(nu_phi)
            term = abs(math.sin(nu_phi)) / gap if gap > 1e-12 * ch else math.inf
            part = w[k, i] * term if w[k, i] > 0 else 0.0
            total = part if i == 0 else total + part
        c = nu / (4 * np.pi) * total
        slope = abs(a / m + b / l_) * (1.0 if z_apex != z_mid else 0.0)
        far_s = _maximum(math.hypot(rs, zs), math.hypot(rs, length - zs))
        far_r = _maximum(math.hypot(rr, zr), math.hypot(rr, length - zr))
        u, v = rs / far_s, rr / far_r
        kappa = u * u / far_s + v * v / far_r
        span = _minimum(_minimum(length, math.sqrt(2 * step / kappa)), step / slope)
        d = math.hypot(rs, zs - _clip(zs, 0.0, length))
        d = d * math.hypot(rr, zr - _clip(zr, 0.0, length))
        bound = c * span / d
        bound = bound * 1.01
        out[k] = math.inf if bound != bound else bound
