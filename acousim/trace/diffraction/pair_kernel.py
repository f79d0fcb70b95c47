"""Compiled edge-to-edge integral of :func:`acousim.trace.diffraction.pairs.pair_elements`
(numba; optional: without numba the same steps run on whole arrays in numpy).

Per pair: the shortest path by bisection on the profile's slope, the cuts of edge 1
by Newton's method on the profile, for each element of edge 1 the first-order
elements of edge 2 (equal excess steps, beta_2 integrated in eta, beta_1 at the
element), each summed straight into its bin of path length.  The two agree within
rounding (the order of the sums differs), which
``tests/acousim/trace/diffraction/test_pair_selection.py``
checks.  Compiled with numpy's error model: a division by zero gives inf or NaN, as
in the numpy path (an element whose amplitude is not finite is dropped), instead
of a check before every division.

For speed, the same elements in the same bins: the cuts of edge 1 in lockstep,
edge 2's elements in stages of independent loops (:func:`_side`), free of
branches and of calls so that they vectorize: log1p, expm1, log, exp, atan and the
taper's cos as inlined series (:mod:`acousim.trace.diffraction.math_kernel`, within a
few ulp of the library's; the integral's amplitudes within 1e-14 of those with the
library's); two beta terms of equal or opposite weights over one atan2 and one
division.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from acousim.trace.diffraction.math_kernel import (
    atan_any,
    cos_quarter,
    exp_pos,
    expm1_pos,
    log1p_pos,
    log_pos,
)

#: an element is evaluated if a bin within this of its path (m) is live (the path
#: from its excess level and from its points agree to rounding)
PATH_SLACK = 1e-6
#: a side's loops over its elements run over a multiple of this many (the widest
#: vector of doubles, AVX-512's 8): whole vectors, no element left to a scalar
#: remainder loop; the elements past the side's last repeat its last level, and
#: none of them is read (:func:`_side`)
LANES = 8


@njit(cache=True, nogil=True, error_model="numpy")
def _apex(px, py, pz, r, s, a, length):  # pragma: no cover - compiled
    """First-order apex on an edge (start s, axis a, length) of p and r, clipped."""
    dsx, dsy, dsz = px - s[0], py - s[1], pz - s[2]
    zs = dsx * a[0] + dsy * a[1] + dsz * a[2]
    rs = math.sqrt(max((dsx * dsx + dsy * dsy + dsz * dsz) - zs * zs, 0.0))
    drx, dry, drz = r[0] - s[0], r[1] - s[1], r[2] - s[2]
    zr = drx * a[0] + dry * a[1] + drz * a[2]
    rr = math.sqrt(max((drx * drx + dry * dry + drz * drz) - zr * zr, 0.0))
    z = (rr * zs + rs * zr) / (rs + rr) if rs + rr > 0 else zs
    return min(max(z, 0.0), length)


@njit(cache=True, nogil=True, error_model="numpy")
def _profile(z1, pair):  # pragma: no cover - compiled
    """P1(z1) = m + min over edge 2 of (n + l), and its slope; pair: (source,
    receiver, start and axis of edge 1, start, axis and length of edge 2)."""
    src, rcv, s1, a1, s2, a2, len2 = pair
    x = s1[0] + z1 * a1[0]
    y = s1[1] + z1 * a1[1]
    w = s1[2] + z1 * a1[2]
    z2 = _apex(x, y, w, rcv, s2, a2, len2)
    qx, qy, qz = s2[0] + z2 * a2[0], s2[1] + z2 * a2[1], s2[2] + z2 * a2[2]
    d1x, d1y, d1z = x - src[0], y - src[1], w - src[2]
    dx, dy, dz = x - qx, y - qy, w - qz
    m = math.sqrt(d1x * d1x + d1y * d1y + d1z * d1z)
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    lx, ly, lz = rcv[0] - qx, rcv[1] - qy, rcv[2] - qz
    value = m + n + math.sqrt(lx * lx + ly * ly + lz * lz)
    slope = (d1x * a1[0] + d1y * a1[1] + d1z * a1[2]) / max(m, 1e-300)
    slope += (dx * a1[0] + dy * a1[1] + dz * a1[2]) / max(n, 1e-300)
    return value, slope


@njit(cache=True, nogil=True, error_model="numpy")
def shortest(src, rcv, geo, out):  # pragma: no cover - compiled
    """Per pair: z1 of the shortest path (60 halvings on the profile's slope) and its
    length, into out (N, 2); geo (N, 14): start1, axis1, length1, start2, axis2,
    length2 (the first 14 columns of :func:`pair_bins`' geo).  A halving that leaves
    (lo, hi) as they were (the interval down to adjacent doubles) ends the loop:
    each later one would repeat it, so z1 is that of all 60."""
    for k in range(geo.shape[0]):
        g = geo[k]
        pair = (src, rcv, g[0:3], g[3:6], g[7:10], g[10:13], g[13])
        lo, hi = 0.0, g[6]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if _profile(mid, pair)[1] > 0:
                if hi == mid:  # (lo, hi) as before: every later halving the same
                    break
                hi = mid
            else:
                if lo == mid:
                    break
                lo = mid
        z = 0.5 * (lo + hi)
        out[k, 0] = z
        out[k, 1] = _profile(z, pair)[0]


@njit(cache=True, nogil=True, error_model="numpy")
def _cuts(n, ends, pair, work):  # pragma: no cover - compiled
    """The cuts of edge 1 into work[0][0, :n] where the profile reaches the targets
    work[0][1, :n] (m), between the apex and z_end (ends): Newton's method from
    z_end (monotone on a convex function), all the cuts in lockstep (each one's
    iterates as alone; the processor overlaps them); work[1]: scratch (n,) bool."""
    cut, active = work
    z_apex, z_end = ends
    lo, hi = min(z_apex, z_end), max(z_apex, z_end)
    for j in range(n):
        cut[0, j] = z_end
        active[j] = True
    for _ in range(40):
        more = False
        for j in range(n):
            if not active[j]:
                continue
            value, slope = _profile(cut[0, j], pair)
            gap = value - cut[1, j]
            if abs(gap) < 1e-13 + 1e-12 * abs(cut[1, j]) or abs(slope) <= 1e-12:
                active[j] = False
            else:
                cut[0, j] = min(max(cut[0, j] - gap / slope, lo), hi)
                more = True
        if not more:
            return


@njit(cache=True, nogil=True, error_model="numpy")
def _scratch(cfg):  # pragma: no cover - compiled
    """:func:`pair_bins`' scratch: the inner template's levels below the excess kept
    (and one more), rows for one side of edge 2's elements (12, n) and their bins
    (n,), one side of edge 1's cuts and targets (2, n_o) and flags (n_o,)."""
    n_max = _count_below(cfg[4], cfg[1], int(cfg[3])) + 2
    levels = np.empty(n_max)
    for j in range(n_max):
        levels[j] = _level_value(j, cfg[1], int(cfg[3]))
    n_out = _count_below(cfg[4], cfg[0], int(cfg[2])) + 2
    # room for a side's elements padded to whole vectors (:func:`_side`)
    out = (np.empty((12, n_max + LANES)), np.empty(n_max + LANES, np.int64))
    return levels, out[0], out[1], np.empty((2, n_out)), np.empty(n_out, np.bool_)


@njit(cache=True, nogil=True, error_model="numpy")
def _spheroid_form(src, rcv, s, a):  # pragma: no cover - compiled
    """:func:`_on_spheroid`'s constants of a line and two foci: (c^2, y0u, eu, y0e, |y0|^2)."""
    cx, cy, cz = 0.5 * (src[0] + rcv[0]), 0.5 * (src[1] + rcv[1]), 0.5 * (src[2] + rcv[2])
    fx, fy, fz = rcv[0] - src[0], rcv[1] - src[1], rcv[2] - src[2]
    c = 0.5 * math.sqrt(fx * fx + fy * fy + fz * fz)
    if c > 0:
        ux, uy, uz = fx / (2 * c), fy / (2 * c), fz / (2 * c)
    else:
        ux, uy, uz = 0.0, 0.0, 0.0
    yx, yy, yz = s[0] - cx, s[1] - cy, s[2] - cz
    y0u = yx * ux + yy * uy + yz * uz
    eu = a[0] * ux + a[1] * uy + a[2] * uz
    y0e = yx * a[0] + yy * a[1] + yz * a[2]
    return c * c, y0u, eu, y0e, yx * yx + yy * yy + yz * yz


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _on_spheroid(form, path, upper):  # pragma: no cover - compiled
    """z along the line where |src - x| + |x - rcv| = path (the larger root if
    upper; `form`: :func:`_spheroid_form`): a spheroid with foci src and rcv meets
    the line at the roots of a quadratic in z."""
    cc, y0u, eu, y0e, yy = form
    a2 = (0.5 * path) ** 2
    b2 = _clip(a2 - cc, 0.0, math.inf)
    q2 = b2 * eu * eu + a2 * (1 - eu * eu)
    q1 = 2 * (b2 * y0u * eu + a2 * (y0e - y0u * eu))
    q0 = b2 * y0u * y0u + a2 * (yy - y0u * y0u) - a2 * b2
    root = math.sqrt(_clip(q1 * q1 - 4 * q2 * q0, 0.0, math.inf))
    return (-q1 + (root if upper else -root)) / (2 * q2)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _clip(z, lo, hi):  # pragma: no cover - compiled
    """min(max(z, lo), hi) for lo <= hi, as selects (loops of it vectorize)."""
    return lo if z < lo else (hi if z > hi else z)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _eta_s(z, rs, zs, rr, zr, z_mid):  # pragma: no cover - compiled
    """e^eta - 1 at the point z on edge 2 (eta: the acosh of the first-order cosh
    eta, from its well-conditioned form; see :func:`_log1p`)."""
    a, b = z - zs, z - zr
    ml = math.sqrt((rs * rs + a * a) * (rr * rr + b * b))
    arg = ((rs + rr) * (z - z_mid)) ** 2 / ((ml - a * b + rs * rr) * rs * rr)
    arg = _clip(arg, 0.0, math.inf)
    return arg + math.sqrt(arg * (arg + 2))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _log1p(s):  # pragma: no cover - compiled
    """log1p(s) for s >= 0 (:func:`log1p_pos`; inf and NaN as they are)."""
    return log1p_pos(s) if s < math.inf else s


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _tanh_uv(e, nu):  # pragma: no cover - compiled
    """tanh(nu e / 2) as u / v: u = expm1(nu e) (:func:`expm1_pos`), v = u + 2; 1 and
    1 past nu e = 40, where tanh rounds to 1; NaN for NaN.  As selects (loops of
    it vectorize)."""
    x = nu * e
    u = expm1_pos(x if x < 40.0 else 40.0)
    u = u if x == x else x
    return (1.0, 1.0) if x > 40.0 else (u, u + 2.0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _prim(u, v, form, c):  # pragma: no cover - compiled
    """The primitive of beta_2 in eta at the eta of t = tanh(nu eta / 2) = u / v
    (:func:`_tanh_uv`): sum_i w_i atan2(t hc_i, hs_i), each atan2 taken as
    atan2(u hc_i, v hs_i) (v > 0).  form: :func:`_terms` of beta_2 (c: the pair's
    consts): two terms of equal (or opposite) weights as the argument of the
    product of their complex numbers (hs_i >= 0: each angle within [-pi/2, pi/2],
    their sum within [-pi, pi])."""
    mode, w, a, b, k = form
    if mode == 1:
        return w * _atan2(u * k, v * a)
    if mode == 2:
        return w * _atan2(u * v * k, a * v * v - u * u * b)
    out = 0.0
    for i in range(4):
        if c[5, i] != 0:
            out += _atan2(u * c[4, i], v * c[3, i]) * c[5, i]
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _prims(n, uv, form, c):  # pragma: no cover - compiled
    """:func:`_prim` of the first n of uv = (u, v) (n,) each into u, one loop per form
    (so that each loop is free of branches and vectorizes)."""
    u, v = uv
    if form[0] == 1:
        for j in range(n):
            u[j] = _prim(u[j], v[j], (1, form[1], form[2], form[3], form[4]), c)
    elif form[0] == 2:
        for j in range(n):
            u[j] = _prim(u[j], v[j], (2, form[1], form[2], form[3], form[4]), c)
    else:
        for j in range(n):
            u[j] = _prim(u[j], v[j], form, c)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _atan2(y, x):  # pragma: no cover - compiled
    """atan2(y, x) as atan(y / x) (:func:`atan_any`), plus pi of y's sign for x < 0
    (within an ulp of pi); for x = 0 (+-0) the library's values: pi / 2 of y's sign,
    and for y = 0 +-0 (x = +0) or +-pi (x = -0).  As selects (loops of it vectorize)."""
    q = atan_any(y / x)
    q = q + math.copysign(math.pi, y) if x < 0 else q
    if x == 0:
        at_zero = math.copysign(math.pi, y) if math.copysign(1.0, x) < 0 else math.copysign(0.0, y)
        q = at_zero if y == 0 else (math.copysign(0.5 * math.pi, y) if y == y else y)
    return q


@njit(cache=True, nogil=True, error_model="numpy")
def _merge(c):  # pragma: no cover - compiled
    """Equal beta terms summed into one (in place): c (3, 4), the sines, cosines and
    weights of a wedge's four terms.  A point on a face plane of the wedge (edge 2
    for edge 1, edge 1 for edge 2: always so in edge to edge) makes them equal two
    by two (angles that differ by 0 or 2 pi): two terms are left (:func:`_terms`)."""
    merged = np.zeros(4, np.bool_)
    for j in range(1, 4):
        for i in range(j):
            if merged[j] or merged[i]:
                continue
            if abs(c[0, i] - c[0, j]) <= 1e-12 and abs(c[1, i] - c[1, j]) <= 1e-12:
                c[2, i] += c[2, j]
                c[2, j] = 0.0
                merged[j] = True


@njit(cache=True, nogil=True, error_model="numpy")
def _terms(w):  # pragma: no cover - compiled
    """(how, i0, i1) for a beta sum's four weights w: how 1: one term (i0), 2: two
    of equal weights (i0, i1), 3: two of opposite weights, 0: else."""
    i0, i1, n = -1, -1, 0
    for i in range(4):
        if w[i] != 0:
            n += 1
            if i0 < 0:
                i0 = i
            else:
                i1 = i
    if n == 1:
        return 1, i0, i0
    if n == 2 and w[i1] == w[i0]:
        return 2, i0, i1
    if n == 2 and w[i1] == -w[i0]:
        return 3, i0, i1
    return 0, i0, i1


@njit(cache=True, nogil=True, error_model="numpy")
def _forms(c):  # pragma: no cover - compiled
    """The merged forms of one pair's beta sums (c (6, 4): its consts): beta_1's
    (how, w, s0, c0, s1, c1: w (s0 / (B - c0) + s1 / (B - c1)), s1 negated for
    opposite weights) and the primitive of beta_2's (how, w, a, b, k) as
    :func:`_prim` reads it (how 1: a = hs, k = hc; 2: the product of the two terms
    (hs_0 + i t hc_0) (hs_1 +- i t hc_1) times v^2 is a v^2 - u^2 b + i u v k)."""
    how1, i0, i1 = _terms(c[2])
    sign1 = -1.0 if how1 == 3 else 1.0
    beta1 = (min(how1, 2), c[2, max(i0, 0)], c[0, max(i0, 0)], c[1, max(i0, 0)],
             sign1 * c[0, max(i1, 0)], c[1, max(i1, 0)])  # fmt: skip
    how2, j0, j1 = _terms(c[5])
    j0, j1 = max(j0, 0), max(j1, 0)
    hs0, hc0, hs1, hc1 = c[3, j0], c[4, j0], c[3, j1], c[4, j1]
    if how2 == 1:
        prim = (1, c[5, j0], hs0, 0.0, hc0)
    elif how2 == 2:
        prim = (2, c[5, j0], hs0 * hs1, hc0 * hc1, hc0 * hs1 + hc1 * hs0)
    elif how2 == 3:
        prim = (2, c[5, j0], hs0 * hs1, -(hc0 * hc1), hc0 * hs1 - hc1 * hs0)
    else:
        prim = (0, 0.0, 0.0, 0.0, 0.0)
    return beta1, prim


@njit(cache=True, nogil=True, error_model="numpy")
def _level_value(j, step, refine):  # pragma: no cover - compiled
    """The j-th excess level of the element template (0, step 2^-refine, ..., step)."""
    if j == 0:
        return 0.0
    if j <= refine:
        return step * 0.5 ** (refine - j + 1)
    return step * (j - refine)


@njit(cache=True, nogil=True, error_model="numpy")
def _count_below(e_end, step, refine):  # pragma: no cover - compiled
    """How many template levels lie below e_end."""
    j = 0
    while _level_value(j, step, refine) < e_end:
        j += 1
    return j


@njit(cache=True, nogil=True, error_model="numpy")
def pair_bins(src, rcv, geo, consts, cfg, out, live, rows):  # pragma: no cover - compiled
    """The elements of the pairs `rows` (int indices) summed into their bins (see
    the module docstring).

    src, rcv (3,); geo (N, 25): per pair start1 (0-2), axis1 (3-5), length1 (6),
    start2 (7-9), axis2 (10-12), length2 (13), nu1, nu2 (14, 15), r and z of the
    source about edge 1 (16, 17), of the receiver about edge 2 (18, 19), sides (20),
    taper (21: 1 if the edges reach beyond the excess kept), the shortest path (22),
    its z1 (23) and the longest path kept (24); consts (N, 6, 4): sin and cos of nu1
    phi_i of beta_1, its weights, the halved sines and cosines of nu2 phi_i of
    beta_2 (sine >= 0) and its weights (equal terms merged here, :func:`_merge`);
    cfg (8,): outer step, inner step, outer and inner refinements, excess kept,
    longest path (not used: geo 24), bin width (m), bins per pair.  Adds into the
    rows `rows` of out: (acc (N, B, 9): per bin the sum of amplitudes, |amplitude|,
    |amplitude| times the path, and times the point on edge 1 (3) and edge 2 (3);
    count (N, B): elements per bin).  live (N, B): the bins to fill (others'
    elements skipped before their beta terms; the bins filled as in the whole
    integral).  A pair's bins depend on it alone: calls on disjoint rows may run at
    once on the same arrays.
    """
    step_o, ref_o = cfg[0], int(cfg[2])
    excess = cfg[4]
    acc, count = out
    levels, buf, bins, cut, active = _scratch(cfg)
    for k in rows:
        g = geo[k]
        len1 = g[6]
        pair = (src, rcv, g[0:3], g[3:6], g[7:10], g[10:13], g[13])
        p_min, z_apex = g[22], g[23]
        limit = min(p_min + excess, g[24])
        last = -1  # the last live bin
        for b in range(live.shape[1]):
            if live[k, b]:
                last = b
        ck = consts[k].copy()
        _merge(ck[0:3])
        _merge(ck[3:6])
        c = (ck,) + _forms(ck)
        work = (acc[k], count[k], live[k], buf, bins, levels, last)
        for side in range(2):
            z_end = 0.0 if side == 0 else len1
            real_end = _profile(z_end, pair)[0] - p_min
            e_end = min(real_end, limit - p_min)
            if not (abs(z_end - z_apex) > 0 and e_end > 0):
                continue
            n_in = min(_count_below(e_end, step_o, ref_o), active.size)
            for j in range(n_in):
                lev = e_end if j + 1 >= n_in else _level_value(j + 1, step_o, ref_o)
                cut[1, j] = p_min + lev
            _cuts(n_in, (z_apex, z_end), pair, (cut, active))
            za = z_apex
            for j in range(n_in):
                zb = cut[0, j]
                if _bin(_profile(0.5 * (za + zb), pair)[0] - p_min - PATH_SLACK, cfg) > last:
                    break  # every path of this element and the ones after: past the live bins
                dz = abs(zb - za)
                if dz > 0:
                    _edge2((0.5 * (za + zb), dz), (src, rcv), g, c, limit, cfg, work)
                za = zb


@njit(cache=True, nogil=True, error_model="numpy")
def _edge2(element, ends, g, c, limit, cfg, out):  # pragma: no cover - compiled
    """The first-order elements of edge 2 with the source at z1 on edge 1 (element:
    (z1, its length)), times beta_1 and the outer weight, into the pair's bins out:
    (acc (B, 9), count (B,), live (B,): the bins to fill, scratch (12, n) and (n,),
    the inner element template's levels); ends: (source, receiver); c: the pair's
    consts and :func:`_forms`."""
    z1, dz1 = element
    src, rcv = ends
    s1, a1 = g[0:3], g[3:6]
    s2, a2, len2 = g[7:10], g[10:13], g[13]
    nu1, nu2, rr, zr = g[14], g[15], g[18], g[19]
    x = (s1[0] + z1 * a1[0], s1[1] + z1 * a1[1], s1[2] + z1 * a1[2])
    m = math.sqrt((x[0] - src[0]) ** 2 + (x[1] - src[1]) ** 2 + (x[2] - src[2]) ** 2)
    d0, d1, d2 = x[0] - s2[0], x[1] - s2[1], x[2] - s2[2]
    zs = d0 * a2[0] + d1 * a2[1] + d2 * a2[2]
    rs = math.sqrt(max(d0 * d0 + d1 * d1 + d2 * d2 - zs * zs, 0.0))
    if not (rs > 1e-9 * max(max(rs, rr), len2)):
        return
    z_mid = (rr * zs + rs * zr) / (rs + rr)
    z_apex = min(max(z_mid, 0.0), len2)
    l_apex = math.hypot(rs, z_apex - zs) + math.hypot(rr, z_apex - zr)
    # the outer weight with beta_2's -(nu2 / (4 pi)) (2 / nu2)
    outer = (-nu1 / (4 * math.pi)) * 0.5 * g[20] * dz1 / m
    outer *= -(nu2 / (4 * math.pi)) * (2 / nu2)
    form = _spheroid_form(x, rcv, s2, a2)
    source = (x, m, z1, outer)
    legs = (rs, zs, rr, zr, z_mid, l_apex)
    for side in range(2):
        z_end = 0.0 if side == 0 else len2
        real_end = math.hypot(rs, z_end - zs) + math.hypot(rr, z_end - zr) - l_apex
        e_end = min(real_end, limit - m - l_apex)
        if abs(z_end - z_apex) > 0 and e_end > 0:
            _side((z_apex, z_end, e_end), (source, legs, form), g, c, cfg, out)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _side(ends, at, g, c, cfg, out):  # pragma: no cover - compiled
    """The elements of edge 2 from its apex z_apex to z_end, up to excess e_end
    (ends); at: (the source point x on edge 1, m, z1, the outer weight), (rs, zs,
    rr, zr, z_mid, l_apex) about edge 2, the spheroid form of x and the receiver.
    In stages over the side's elements, each stage's elements independent of each
    other (so that the processor overlaps them; the same numbers as element by
    element): the ends, the bins (:func:`_live_bins`), eta and the primitive at the
    ends of the live elements, their amplitudes (:func:`_amplitudes`), their sums."""
    z_apex, z_end, e_end = ends
    (x, m, z1, outer), legs, form = at
    rs, zs, rr, zr, z_mid, l_apex = legs
    nu2 = g[15]
    upper = z_end > z_apex
    lo, hi = min(z_apex, z_end), max(z_apex, z_end)
    buf = out[3]
    lev, zb, eta, prim, vv = buf[0], buf[1], buf[2], buf[3], buf[9]
    levels = out[5]  # the template's levels, below the excess kept (and one more)
    n = 0
    while n < levels.size - 1 and levels[n] < e_end:
        lev[n] = levels[n]
        n += 1
    lev[n] = e_end
    n = _before_last_bin(n, lev, m + l_apex - g[22], cfg, out[6])
    # the loops run over `pad` elements, whole vectors: the ones past n repeat the
    # last level (elements of no length; their numbers are never read, and each
    # element's numbers are its own: the first n's are as without them)
    pad = (n + LANES - 1) // LANES * LANES
    for j in range(n + 1, pad + 1):
        lev[j] = lev[n]
    zb[0] = z_apex
    for j in range(1, pad + 1):
        zb[j] = _clip(_on_spheroid(form, l_apex + lev[j], upper), lo, hi)
    _live_bins((n, pad), (m, l_apex, (form, upper, lo, hi), legs), g, cfg, out)
    eta[0] = 0.0 if z_apex == z_mid else _eta_s(z_apex, rs, zs, rr, zr, z_mid)
    for j in range(1, pad + 1):  # e^eta - 1 at every end (a loop that vectorizes)
        eta[j] = _eta_s(zb[j], rs, zs, rr, zr, z_mid)
    for j in range(pad + 1):  # eta at every end (only those of live elements are read)
        eta[j] = _log1p(eta[j])
    for j in range(pad + 1):  # the primitive of beta_2 there
        prim[j], vv[j] = _tanh_uv(eta[j], nu2)
    _prims(pad + 1, (prim, vv), c[2], c[0])
    _amplitudes(pad, (x, m, z1, outer), g, c, cfg, out)
    _sums(n, (x, m), g, out)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _before_last_bin(n, lev, base, cfg, last):  # pragma: no cover - compiled
    """How many of a side's n elements (excess levels lev (n + 1,), their excess
    beyond the pair's shortest path base + the level (m)) come before the first
    one past the pair's last live bin `last` (one bin beyond its mid excess, the
    test of :func:`_live_bins`, with a margin): the elements after it are not live
    (their excess grows with the level), and each element's numbers are its own,
    so leaving them out changes none of the others.  n if the last bin (open:
    it holds every larger excess) is live."""
    top = int(cfg[7]) - 1
    if last >= top:
        return n
    inv_w = 1.0 / cfg[6]
    past = last + 1 + PATH_SLACK * inv_w + 1e-6 + 1e-9  # q - slack > last + 1 - rounding
    for j in range(n):
        if (base + 0.5 * (lev[j] + lev[j + 1])) * inv_w >= past:
            return j
    return n


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _live_bins(counts, at, g, cfg, out):  # pragma: no cover - compiled
    """The bin of each of the n elements of a side (out[4]; -1 if not live), its
    point zc, n and l (out[3] rows 4-6; of every element and of the padding, in a
    loop that vectorizes); counts: (n, n padded: :func:`_side`); at: (m, l_apex,
    (the spheroid form of the source point and the receiver, the root, the clip),
    (rs, zs, rr, zr, ...)).  An element is first
    tested on its mid path m + l_apex + its mid excess (its point lies on that
    spheroid): within PATH_SLACK of a live bin (a margin of 1e-6 bin over
    floor((ex -+ PATH_SLACK) / width) keeps this a superset of those bins), then
    on its path's bin."""
    n, pad = counts
    m, l_apex, (form, upper, lo, hi), legs = at
    rs, zs, rr, zr = legs[0], legs[1], legs[2], legs[3]
    live, buf, bins = out[2], out[3], out[4]
    lev, zc, nn, ll, quot = buf[0], buf[4], buf[5], buf[6], buf[11]
    p_min, width = g[22], cfg[6]
    for j in range(pad):
        z = _clip(_on_spheroid(form, l_apex + 0.5 * (lev[j] + lev[j + 1]), upper), lo, hi)
        zc[j] = z
        nn[j] = math.sqrt(rs * rs + (z - zs) ** 2)
        ll[j] = math.sqrt(rr * rr + (z - zr) ** 2)
        quot[j] = (m + nn[j] + ll[j] - p_min) / width
    inv_w = 1.0 / width
    slack = PATH_SLACK * inv_w + 1e-6
    top = int(cfg[7]) - 1
    base = m + l_apex - p_min
    for j in range(n):
        bins[j] = -1
        q = (base + 0.5 * (lev[j] + lev[j + 1])) * inv_w
        b0 = min(max(int(math.floor(q - slack)), 0), top)
        b1 = min(max(int(math.floor(q + slack)), 0), top)
        if live[b0] or live[b1]:
            b = min(max(int(math.floor(quot[j])), 0), top)  # _bin of its path
            if live[b]:
                bins[j] = b


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _amplitudes(n, at, g, c, cfg, out):  # pragma: no cover - compiled
    """The amplitude of each live element of the n of a side (out[3] row 7; 0:
    none; n: padded to whole vectors, :func:`_side`, the amplitudes past the side's
    last element never read): the mean of beta_2 over it (the primitive's step
    over eta's) times dz / (n l), the outer weight, beta_1 at its point and the
    taper; at: (x, m, z1, outer weight)."""
    x, m, z1, outer = at
    buf, bins = out[3], out[4]
    zb, eta, prim, zc, nn, ll = buf[1], buf[2], buf[3], buf[4], buf[5], buf[6]
    amps, ey1 = buf[7], buf[8]
    # the pair's numbers as scalars (not loads that a store to the buffers might alias)
    d0, d1, d2 = g[7] - g[0], g[8] - g[1], g[9] - g[2]  # edge 2's start from edge 1's
    a0, a1, a2 = g[10], g[11], g[12]  # edge 2's axis
    b0, b1, b2 = g[3], g[4], g[5]  # edge 1's
    nu1, rs1, zs1, p_min = g[14], g[16], g[17], g[22]
    half = 0.5 * cfg[4]
    for j in range(n):  # e^eta of beta_1 at every element's point (vectorizes)
        e0 = d0 + zc[j] * a0
        e1 = d1 + zc[j] * a1
        e2 = d2 + zc[j] * a2
        z21 = e0 * b0 + e1 * b1 + e2 * b2
        r21 = math.sqrt(_clip(e0 * e0 + e1 * e1 + e2 * e2 - z21 * z21, 0.0, math.inf))
        ratio = ((z1 - zs1) * (z1 - z21) + m * nn[j]) / (rs1 * r21)
        ey1[j] = _acosh_y(ratio if r21 > 0 else math.inf)
    for j in range(n):  # 0 where not live (selects: the loops vectorize)
        deta = abs(eta[j + 1] - eta[j])
        pa, pb = prim[j], prim[j + 1]
        amp = outer * (abs(zb[j + 1] - zb[j]) * (pb - pa)) / (deta * (nn[j] * ll[j]))
        amps[j] = amp if bins[j] >= 0 and deta > 0 and pb != pa else 0.0
    for j in range(n):  # beta_1: y^nu (every element's; inf past 1e304), the sum
        y = ey1[j]
        v = nu1 * log_pos(y if y < math.inf else 1.0)
        ey1[j] = exp_pos(v) if y < math.inf and v <= 700.0 else math.inf
    _betas1(n, amps, ey1, c)
    taper = g[21] > 0
    for j in range(n):  # the taper (1 up to half the excess kept), finite ones
        ex = m + nn[j] + ll[j] - p_min
        cq = cos_quarter(_clip((ex - half) / half, 0.0, 1.0))
        amp = amps[j] * (cq * cq) if taper and ex > half else amps[j]  # 0.5 (1 + cos(pi t))
        amps[j] = amp if math.isfinite(amp) else 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sums(n, at, g, out):  # pragma: no cover - compiled
    """The live elements of a side with an amplitude (out[3] row 7) summed into
    their bins (out: acc, count), in order; at: (the point x on edge 1, m)."""
    x, m = at
    acc, count, buf, bins = out[0], out[1], out[3], out[4]
    zc, nn, ll, amps = buf[4], buf[5], buf[6], buf[7]
    s2, a2 = g[7:10], g[10:13]
    for j in range(n):
        amp = amps[j]
        if amp == 0:
            continue
        b = bins[j]
        path = m + nn[j] + ll[j]
        w = abs(amp)
        acc[b, 0] += amp
        acc[b, 1] += w
        acc[b, 2] += w * path
        for i in range(3):
            acc[b, 3 + i] += w * x[i]
            acc[b, 6 + i] += w * (s2[i] + zc[j] * a2[i])
        count[b] += 1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _betas1(n, amps, yn, c):  # pragma: no cover - compiled
    """amps[:n] times :func:`_beta1` at their cosh(nu acosh) of yn (y^nu), one loop
    per form, as selects (the loops vectorize; an amplitude of 0 stays 0, or is
    NaN, which the taper's loop zeroes)."""
    how, w, s0, c0, s1, c1 = c[1]
    if how == 2:
        for j in range(n):
            big = _cosh_nu_of(yn[j])
            d0, d1 = big - c0, big - c1
            den = d0 * d1
            one = w * (s0 * d1 + s1 * d0) / den
            amps[j] = amps[j] * (one if den < 1e300 else w * (s0 / d0 + s1 / d1))
    elif how == 1:
        for j in range(n):
            amps[j] = amps[j] * (w * s0 / (_cosh_nu_of(yn[j]) - c0))
    else:
        for j in range(n):
            amps[j] = amps[j] * _beta1(_cosh_nu_of(yn[j]), c)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _beta1(big, c):  # pragma: no cover - compiled
    """beta_1's sum of sin_i / (big - cos_i) times the weights (c: the pair's consts
    and :func:`_forms`): two terms over one division while their product of
    denominators stays below 1e300."""
    how, w, s0, c0, s1, c1 = c[1]
    if how == 1:
        return w * s0 / (big - c0)
    if how == 2:
        d0, d1 = big - c0, big - c1
        den = d0 * d1
        if den < 1e300:
            return w * (s0 * d1 + s1 * d0) / den
        return w * (s0 / d0 + s1 / d1)
    beta = 0.0
    for i in range(4):
        if c[0][2, i] != 0:
            beta += c[0][2, i] * c[0][0, i] / (big - c[0][1, i])
    return beta


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _cosh_nu_of(yn):  # pragma: no cover - compiled
    """cosh(nu acosh(x)) = (y^nu + y^-nu) / 2 from yn = y^nu (y = :func:`_acosh_y`
    of x; inf: inf)."""
    return 0.5 * (yn + 1.0 / yn) if yn < math.inf else math.inf


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _acosh_y(x):  # pragma: no cover - compiled
    """y = x + sqrt(x^2 - 1) = e^acosh(x) (x below 1 taken as 1; inf from x = 1e300
    on, and for NaN), as selects (loops of it vectorize)."""
    x1 = _clip(x, 1.0, math.inf)
    y = x1 + math.sqrt((x1 - 1.0) * (x1 + 1.0))
    return y if x < 1e300 else math.inf


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bin(ex, cfg):  # pragma: no cover - compiled
    """The bin of excess path ex (m): cfg[6] wide, cfg[7] of them, the last open."""
    return min(max(int(math.floor(ex / cfg[6])), 0), int(cfg[7]) - 1)
