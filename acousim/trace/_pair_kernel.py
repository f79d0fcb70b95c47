"""Compiled edge-to-edge integral of :func:`acousim.trace.btm_pairs.pair_elements`
(numba; optional: without numba the same steps run on whole arrays in numpy).

Per pair: the shortest path by bisection on the profile's slope, the cuts of edge 1
by Newton's method on the profile, for each element of edge 1 the first-order
elements of edge 2 (equal excess steps, beta_2 integrated in eta, beta_1 at the
element), each summed straight into its bin of path length.  The two agree within
rounding (the order of the sums differs), which ``tests/test_edge_pair_selection.py``
checks.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: an element is evaluated if a bin within this of its path (m) is live (the path
#: from its excess level and from its points agree to rounding)
PATH_SLACK = 1e-6


@njit(cache=True, nogil=True)
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


@njit(cache=True, nogil=True)
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


@njit(cache=True, nogil=True)
def shortest(src, rcv, geo, out):  # pragma: no cover - compiled
    """Per pair: z1 of the shortest path (60 halvings on the profile's slope) and its
    length, into out (N, 2); geo (N, 14): start1, axis1, length1, start2, axis2,
    length2 (the first 14 columns of :func:`pair_bins`' geo)."""
    for k in range(geo.shape[0]):
        g = geo[k]
        pair = (src, rcv, g[0:3], g[3:6], g[7:10], g[10:13], g[13])
        lo, hi = 0.0, g[6]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if _profile(mid, pair)[1] > 0:
                hi = mid
            else:
                lo = mid
        z = 0.5 * (lo + hi)
        out[k, 0] = z
        out[k, 1] = _profile(z, pair)[0]


@njit(cache=True, nogil=True)
def _level(target, z_apex, z_end, pair):  # pragma: no cover - compiled
    """z between the apex and z_end where the profile reaches target (Newton from
    z_end: monotone on a convex function)."""
    lo, hi = min(z_apex, z_end), max(z_apex, z_end)
    z = z_end
    for _ in range(40):
        value, slope = _profile(z, pair)
        gap = value - target
        if abs(gap) < 1e-13 + 1e-12 * abs(target) or abs(slope) <= 1e-12:
            break
        z = min(max(z - gap / slope, lo), hi)
    return z


@njit(cache=True, nogil=True)
def _spheroid_form(src, rcv, s, a):  # pragma: no cover - compiled
    """The constants of :func:`_spheroid` for one line and two foci: (c^2, y0u, eu,
    y0e, |y0|^2)."""
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


@njit(cache=True, nogil=True, inline="always")
def _on_spheroid(form, path, upper):  # pragma: no cover - compiled
    """z along the line where |src - x| + |x - rcv| = path (the larger root if
    upper), from the constants `form` of :func:`_spheroid_form`: points of equal
    path lie on a spheroid with foci src and rcv, whose intersection with a line is
    a quadratic in z."""
    cc, y0u, eu, y0e, yy = form
    a2 = (0.5 * path) ** 2
    b2 = max(a2 - cc, 0.0)
    q2 = b2 * eu * eu + a2 * (1 - eu * eu)
    q1 = 2 * (b2 * y0u * eu + a2 * (y0e - y0u * eu))
    q0 = b2 * y0u * y0u + a2 * (yy - y0u * y0u) - a2 * b2
    root = math.sqrt(max(q1 * q1 - 4 * q2 * q0, 0.0))
    return (-q1 + (root if upper else -root)) / (2 * q2)


@njit(cache=True, nogil=True, inline="always")
def _eta(z, rs, zs, rr, zr, z_mid):  # pragma: no cover - compiled
    a, b = z - zs, z - zr
    ml = math.sqrt((rs * rs + a * a) * (rr * rr + b * b))
    arg = ((rs + rr) * (z - z_mid)) ** 2 / ((ml - a * b + rs * rr) * rs * rr)
    arg = max(arg, 0.0)
    return math.log1p(arg + math.sqrt(arg * (arg + 2)))


@njit(cache=True, nogil=True, inline="always")
def _prim(e, nu, hs, hc, w):  # pragma: no cover - compiled
    t = math.tanh(nu * e / 2)
    out = 0.0
    for i in range(4):
        if w[i] != 0:
            out += math.atan2(t * hc[i], hs[i]) * w[i]
    return out


@njit(cache=True, nogil=True)
def _level_value(j, step, refine):  # pragma: no cover - compiled
    """The j-th excess level of the element template (0, step 2^-refine, ..., step / 2,
    step, 2 step, ...)."""
    if j == 0:
        return 0.0
    if j <= refine:
        return step * 0.5 ** (refine - j + 1)
    return step * (j - refine)


@njit(cache=True, nogil=True)
def _count_below(e_end, step, refine):  # pragma: no cover - compiled
    """How many template levels lie below e_end."""
    j = 0
    while _level_value(j, step, refine) < e_end:
        j += 1
    return j


@njit(cache=True, nogil=True)
def pair_bins(src, rcv, geo, consts, cfg, acc, count, live):  # pragma: no cover - compiled
    """Every pair's elements summed into its bins (see the module docstring).

    src, rcv (3,); geo (N, 25): per pair start1 (0-2), axis1 (3-5), length1 (6),
    start2 (7-9), axis2 (10-12), length2 (13), nu1, nu2 (14, 15), r and z of the
    source about edge 1 (16, 17), of the receiver about edge 2 (18, 19), sides (20),
    taper (21: 1 if the edges reach beyond the excess kept), the shortest path (22),
    its z1 (23) and the longest path kept (24); consts (N, 6, 4): sin and cos of nu1
    phi_i of beta_1, its weights, the halved sines and cosines of nu2 phi_i of
    beta_2 (sine >= 0) and its weights; cfg (8,): outer step, inner step, outer and
    inner refinements, excess kept, longest path (not used: geo 24), bin width (m),
    bins per pair.  Adds into acc (N, B, 9): per bin the sum of amplitudes, of
    |amplitude|, and of |amplitude| times the path, the point on edge 1 (3) and on
    edge 2 (3); count (N, B): elements per bin.  live (N, B): the bins to fill (an
    element of another bin is skipped before its beta terms are evaluated; the bins
    filled are those of the whole integral).
    """
    step_o, ref_o = cfg[0], int(cfg[2])
    excess = cfg[4]
    for k in range(geo.shape[0]):
        g = geo[k]
        len1 = g[6]
        pair = (src, rcv, g[0:3], g[3:6], g[7:10], g[10:13], g[13])
        p_min, z_apex = g[22], g[23]
        limit = min(p_min + excess, g[24])
        last = -1  # the last live bin
        for b in range(live.shape[1]):
            if live[k, b]:
                last = b
        for side in range(2):
            z_end = 0.0 if side == 0 else len1
            real_end = _profile(z_end, pair)[0] - p_min
            e_end = min(real_end, limit - p_min)
            if not (abs(z_end - z_apex) > 0 and e_end > 0):
                continue
            n_in = _count_below(e_end, step_o, ref_o)
            za = z_apex
            for j in range(n_in):
                lev = e_end if j + 1 >= n_in else _level_value(j + 1, step_o, ref_o)
                zb = _level(p_min + lev, z_apex, z_end, pair)
                if _bin(_profile(0.5 * (za + zb), pair)[0] - p_min - PATH_SLACK, cfg) > last:
                    break  # every path of this element and the ones after: past the live bins
                dz = abs(zb - za)
                if dz > 0:
                    z1 = 0.5 * (za + zb)
                    out = (acc[k], count[k], live[k])
                    _edge2((z1, dz), (src, rcv), g, consts[k], limit, cfg, out)
                za = zb


@njit(cache=True, nogil=True)
def _edge2(element, ends, g, c, limit, cfg, out):  # pragma: no cover - compiled
    """The first-order elements of edge 2 with the source at z1 on edge 1 (element:
    (z1, its length)), times beta_1 and the outer weight, into the pair's bins out:
    (acc (B, 9), count (B,), live (B,): the bins to fill); ends: (source, receiver)."""
    z1, dz1 = element
    src, rcv = ends
    step, refine = cfg[1], int(cfg[3])
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
    outer = (-nu1 / (4 * math.pi)) * 0.5 * g[20] * dz1 / m
    xa = np.empty(3)
    xa[0], xa[1], xa[2] = x
    form = _spheroid_form(xa, rcv, s2, a2)
    for side in range(2):
        z_end = 0.0 if side == 0 else len2
        real_end = math.hypot(rs, z_end - zs) + math.hypot(rr, z_end - zr) - l_apex
        e_end = min(real_end, limit - m - l_apex)
        if not (abs(z_end - z_apex) > 0 and e_end > 0):
            continue
        n_in = _count_below(e_end, step, refine)
        lo, hi = min(z_apex, z_end), max(z_apex, z_end)
        e_a = 0.0
        za = z_apex
        ea = 0.0 if z_apex == z_mid else _eta(za, rs, zs, rr, zr, z_mid)
        pa = _prim(ea, nu2, c[3], c[4], c[5])
        stale = False
        for j in range(n_in):
            e_b = e_end if j + 1 >= n_in else _level_value(j + 1, step, refine)
            # the element's path is m + l_apex + its mid excess (its point lies on
            # that spheroid): skipped without solving for its points unless a bin
            # within PATH_SLACK of it is live
            ex = m + l_apex + 0.5 * (e_a + e_b) - g[22]
            if not (out[2][_bin(ex - PATH_SLACK, cfg)] or out[2][_bin(ex + PATH_SLACK, cfg)]):
                e_a, stale = e_b, True
                continue
            if stale:  # za, as the skipped element would have left it
                za = min(max(_on_spheroid(form, l_apex + e_a, side == 1), lo), hi)
            zb = min(max(_on_spheroid(form, l_apex + e_b, side == 1), lo), hi)
            zc = min(max(_on_spheroid(form, l_apex + 0.5 * (e_a + e_b), side == 1), lo), hi)
            n_c = math.sqrt(rs * rs + (zc - zs) ** 2)
            l_c = math.sqrt(rr * rr + (zc - zr) ** 2)
            if not out[2][_bin(m + n_c + l_c - g[22], cfg)]:
                e_a, za, stale = e_b, zb, True
                continue
            if stale:  # the prim at za, as the skipped element would have left it
                ea = _eta(za, rs, zs, rr, zr, z_mid)
                pa = _prim(ea, nu2, c[3], c[4], c[5])
                stale = False
            eb = _eta(zb, rs, zs, rr, zr, z_mid)
            pb = _prim(eb, nu2, c[3], c[4], c[5])
            deta = abs(eb - ea)
            if deta > 0:
                amp_in = -(nu2 / (4 * math.pi)) * (abs(zb - za) / deta / (n_c * l_c))
                amp_in *= (2 / nu2) * (pb - pa)
                if amp_in != 0:
                    _add(x, (m, z1, zc, n_c, l_c, amp_in * outer), g, c, cfg, out)
            e_a, za, ea, pa = e_b, zb, eb, pb


@njit(cache=True, nogil=True, inline="always")
def _add(x, el, g, c, cfg, out):  # pragma: no cover - compiled
    """beta_1 at the element (el: m, z1 on edge 1, zc on edge 2, n, l, amplitude;
    x: the point z1), the taper, into its bin of out (acc, count)."""
    m, z1, zc, n_c, l_c, amp = el
    acc, count, _ = out
    s1, a1, s2, a2 = g[0:3], g[3:6], g[7:10], g[10:13]
    nu1, rs1, zs1, p_min = g[14], g[16], g[17], g[22]
    excess = cfg[4]
    y = (s2[0] + zc * a2[0], s2[1] + zc * a2[1], s2[2] + zc * a2[2])
    e0, e1, e2 = y[0] - s1[0], y[1] - s1[1], y[2] - s1[2]
    z21 = e0 * a1[0] + e1 * a1[1] + e2 * a1[2]
    r21 = math.sqrt(max(e0 * e0 + e1 * e1 + e2 * e2 - z21 * z21, 0.0))
    cosh1 = ((z1 - zs1) * (z1 - z21) + m * n_c) / (rs1 * r21) if r21 > 0 else math.inf
    big = _cosh_nu(nu1, cosh1)
    beta = 0.0
    for i in range(4):
        if c[2, i] != 0:
            beta += c[2, i] * c[0, i] / (big - c[1, i])
    amp = amp * beta
    path = m + n_c + l_c
    ex = path - p_min
    if g[21] > 0:
        t = min(max((ex - excess / 2) / (excess / 2), 0.0), 1.0)
        amp *= 0.5 * (1 + math.cos(math.pi * t))
    if not (math.isfinite(amp) and amp != 0):
        return
    b = _bin(ex, cfg)
    w = abs(amp)
    acc[b, 0] += amp
    acc[b, 1] += w
    acc[b, 2] += w * path
    acc[b, 3] += w * x[0]
    acc[b, 4] += w * x[1]
    acc[b, 5] += w * x[2]
    acc[b, 6] += w * y[0]
    acc[b, 7] += w * y[1]
    acc[b, 8] += w * y[2]
    count[b] += 1


@njit(cache=True, nogil=True, inline="always")
def _cosh_nu(nu, x):  # pragma: no cover - compiled
    """cosh(nu acosh(x)) (x below 1 taken as 1): (y^nu + y^-nu) / 2 with
    y = x + sqrt(x^2 - 1)."""
    if not x < 1e300:
        return math.inf
    x = max(x, 1.0)
    yn = math.exp(nu * math.log(x + math.sqrt((x - 1.0) * (x + 1.0))))
    return 0.5 * (yn + 1.0 / yn)


@njit(cache=True, nogil=True, inline="always")
def _bin(ex, cfg):  # pragma: no cover - compiled
    """The bin of excess path ex (m): cfg[6] wide, cfg[7] of them, the last open."""
    return min(max(int(math.floor(ex / cfg[6])), 0), int(cfg[7]) - 1)
