"""Compiled bound and estimate of the largest path of edge pairs
(:func:`acousim.trace.diffraction.pair_bound.pair_bound` and
:func:`acousim.trace.diffraction.pair_bound.pair_estimate`; numba, optional: without numba the
numpy versions there run).

One pass over the pairs in scalar math: the same formulas as the numpy versions,
in the same order of operations, so the two agree within rounding
(``tests/acousim/trace/diffraction/test_bound_kernel.py``).  ``error_model="numpy"``: a division
by zero
gives inf or nan as in numpy (whose warnings the numpy versions silence), not an
exception; the mins and maxes propagate nan as numpy's do.

Each pair is a row of `cols`, the arrays of :class:`acousim.trace.diffraction.pairs.PairGeometry`
in the order of its fields (start1, end1, start2, end2, face_dir1, normal1,
face_dir2, normal2, angle1, angle2, theta12, theta21, terms1, terms2, sides).
"""

from __future__ import annotations

import math

from numba import njit

_jit = njit(cache=True, nogil=True, error_model="numpy")

SIXTEEN_PI2 = 16 * math.pi**2
TWO_PI = 2 * math.pi


@_jit
def _row(a, k):  # pragma: no cover - compiled
    return (a[k, 0], a[k, 1], a[k, 2])


@_jit
def _sub(a, b):  # pragma: no cover - compiled
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_jit
def _along(a, t, u):  # pragma: no cover - compiled
    """a + t u."""
    return (a[0] + t * u[0], a[1] + t * u[1], a[2] + t * u[2])


@_jit
def _times(t, u):  # pragma: no cover - compiled
    return (t * u[0], t * u[1], t * u[2])


@_jit
def _dot(a, b):  # pragma: no cover - compiled
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def _norm(a):  # pragma: no cover - compiled
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@_jit
def _min(a, b):  # pragma: no cover - compiled
    """np.minimum of two scalars (nan if either is)."""
    if a != a or b != b:
        return math.nan
    return a if a <= b else b


@_jit
def _max(a, b):  # pragma: no cover - compiled
    """np.maximum of two scalars (nan if either is)."""
    if a != a or b != b:
        return math.nan
    return a if a >= b else b


@_jit
def _axis(start, end, guard):  # pragma: no cover - compiled
    """(unit axis, length) of an edge; a zero length divides by 1e-300 (guard) or 1."""
    e = _sub(end, start)
    length = _norm(e)
    d = _max(length, 1e-300) if guard else (length if length > 0 else 1.0)
    return (e[0] / d, e[1] / d, e[2] / d), length


@_jit
def _cylindrical(p, start, axis, face_dir, normal):  # pragma: no cover - compiled
    """(r, theta in [0, 2 pi)) of p about an edge."""
    d = _sub(p, start)
    v = _sub(d, _times(_dot(d, axis), axis))
    th = math.atan2(_dot(v, normal), _dot(v, face_dir)) % TWO_PI
    return _norm(v), th


@_jit
def _beta_bound(nu, th_a, th_b, terms, k):  # pragma: no cover - compiled
    """sum_i |w_i| |cot(nu phi_i / 2)| (inf where a term is singular)."""
    a, b = th_a, th_b
    phis = (math.pi + (a + b), math.pi + (a - b), math.pi + (-a + b), math.pi + (-a - b))
    total = 0.0
    for i in range(4):
        w = abs(terms[k, i])
        if w > 0:  # (a term of weight 0 adds nothing: not evaluated)
            half = (nu * phis[i] / 2) % math.pi
            s = math.sin(half)
            total += w * (abs(math.cos(half)) / s if s > 1e-12 else math.inf)
    return total


@_jit
def _apex(s, r, start, axis, length):  # pragma: no cover - compiled
    """First-order apex of s and r on an edge (z from its start, clipped).

    Not :func:`.pair_kernel._apex`: that one takes the distance to the edge's line
    as sqrt(|d|^2 - z^2), fast but short of digits for a point almost on the line;
    here it is the norm of the perpendicular part, which the estimate needs at a
    corner two edges share (its test ``n <= 1e-9 max(m, l)``): with the other form
    5 of 76 estimates of a room's pairs change (tried, and kept apart).
    """
    ds, dr = _sub(s, start), _sub(r, start)
    zs, zr = _dot(ds, axis), _dot(dr, axis)
    rs = _norm(_sub(ds, _times(zs, axis)))
    rr = _norm(_sub(dr, _times(zr, axis)))
    tot = rs + rr
    z = (rr * zs + rs * zr) / tot if tot > 0 else zs
    return _min(_max(z, 0.0), length)


@_jit
def _spheroid_interval(s, r, edge, limit):  # pragma: no cover - compiled
    """[lo, hi] of an edge (start, axis, length) where |s - x| + |x - r| <= limit
    ((1, 0) where there is none)."""
    start, axis, length = edge
    centre = (0.5 * (s[0] + r[0]), 0.5 * (s[1] + r[1]), 0.5 * (s[2] + r[2]))
    focal = _sub(r, s)
    c = 0.5 * _norm(focal)
    two_c = 2 * c if c > 0 else 1.0
    u = (focal[0] / two_c, focal[1] / two_c, focal[2] / two_c)
    a2 = (0.5 * limit) * (0.5 * limit)
    b2 = _max(a2 - c * c, 0.0)
    y0 = _sub(start, centre)
    y0u, eu, y0e = _dot(y0, u), _dot(axis, u), _dot(y0, axis)
    q2 = b2 * (eu * eu) + a2 * (1 - eu * eu)
    q1 = 2 * (b2 * y0u * eu + a2 * (y0e - y0u * eu))
    q0 = b2 * (y0u * y0u) + a2 * (_dot(y0, y0) - y0u * y0u) - a2 * b2
    disc = q1 * q1 - 4 * q2 * q0
    if not disc >= 0:
        return 1.0, 0.0
    root = math.sqrt(_max(disc, 0.0))
    q2 = q2 if q2 > 0 else 1e-300
    return _max((-q1 - root) / (2 * q2), 0.0), _min((-q1 + root) / (2 * q2), length)


@_jit
def _point_segment(p, a, b):  # pragma: no cover - compiled
    """Least and largest distance from p to the segment a-b."""
    ab = _sub(b, a)
    t = _dot(_sub(p, a), ab) / _max(_dot(ab, ab), 1e-300)
    t = _min(_max(t, 0.0), 1.0)
    near = _norm(_sub(_along(a, t, ab), p))
    return near, _max(_norm(_sub(a, p)), _norm(_sub(b, p)))


@_jit
def _segment_segment(a1, b1, a2, b2):  # pragma: no cover - compiled
    """Least distance between two segments (ends and the lines' closest points)."""
    best = _min(_point_segment(a1, a2, b2)[0], _point_segment(b1, a2, b2)[0])
    best = _min(best, _point_segment(a2, a1, b1)[0])
    best = _min(best, _point_segment(b2, a1, b1)[0])
    d1, d2, r = _sub(b1, a1), _sub(b2, a2), _sub(a1, a2)
    aa, ee, bb = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    cc, ff = _dot(d1, r), _dot(d2, r)
    den = aa * ee - bb * bb
    if not den > 1e-12 * _max(aa * ee, 1e-300):
        return _min(best, math.inf)
    s = _min(_max((bb * ff - cc * ee) / den, 0.0), 1.0)
    t = _min(_max((aa * ff - bb * cc) / den, 0.0), 1.0)
    return _min(best, _norm(_sub(_sub(_along(a1, s, d1), a2), _times(t, d2))))


@_jit
def _quadrant(a, b):  # pragma: no cover - compiled
    """int_0^a int_0^b dx dy / sqrt(x^2 + y^2)."""
    t1 = a * math.asinh(b / a) if a > 0 else 0.0
    t2 = b * math.asinh(a / b) if b > 0 else 0.0
    return t1 + t2


@_jit
def _interval_abs(lo, hi):  # pragma: no cover - compiled
    """[lo, hi] as pieces (p, q, sign) of |x| (see pair_bound._interval_abs)."""
    if lo < 0 and hi > 0:
        return -lo, hi, 1.0
    if hi <= 0:
        return -lo, -hi, -1.0
    return hi, lo, -1.0


@_jit
def _h(x, d):  # pragma: no cover - compiled
    return x * math.asinh(x / d) - math.sqrt(x * x + d * d)


@_jit
def _inverse_distance_integral(a1, b1, a2, b2):  # pragma: no cover - compiled
    """Upper bound of int int dz1 dz2 / |z1 - z2| over two segments (parallel:
    exact; lines that meet: from their meeting point)."""
    u1, l1 = _axis(a1, b1, True)
    u2, l2 = _axis(a2, b2, True)
    cos = _min(_max(_dot(u1, u2), -1.0), 1.0)
    sin2 = 1 - cos * cos
    w = _sub(a2, a1)
    if sin2 < 1e-10:  # parallel: n = sqrt(d^2 + (s1 - s2)^2), s along u1
        s2a, s2b = _dot(w, u1), _dot(_sub(b2, a1), u1)
        s2a, s2b = _min(s2a, s2b), _max(s2a, s2b)
        perp = _norm(_sub(w, _times(_dot(w, u1), u1)))
        if not perp > 0:
            return math.inf
        d = _max(perp, 1e-300)
        return _h(l1 - s2a, d) - _h(l1 - s2b, d) - _h(0.0 - s2a, d) + _h(0.0 - s2b, d)
    t1 = (_dot(w, u1) - cos * _dot(w, u2)) / sin2
    t2 = (cos * _dot(w, u1) - _dot(w, u2)) / sin2
    pa, qa, sa = _interval_abs(-t1, l1 - t1)
    pb, qb, sb = _interval_abs(-t2, l2 - t2)
    rect = _quadrant(pa, pb) + sb * _quadrant(pa, qb) + sa * _quadrant(qa, pb)
    rect = rect + sa * sb * _quadrant(qa, qb)
    return rect / math.sqrt(_max(1 - abs(cos), 1e-300))


@_jit
def _edges(cols, k, guard):  # pragma: no cover - compiled
    """((start, axis, length) of edge 1, the same of edge 2) of pair k."""
    s1, s2 = _row(cols[0], k), _row(cols[2], k)
    ax1, len1 = _axis(s1, _row(cols[1], k), guard)
    ax2, len2 = _axis(s2, _row(cols[3], k), guard)
    return (s1, ax1, len1), (s2, ax2, len2)


@_jit
def _betas(src, rcv, cols, k, edges):  # pragma: no cover - compiled
    """(r of S about edge 1, r of R about edge 2, nu1, nu2, the amplitude scale
    f nu1 nu2 / (16 pi^2) B1 B2 / 2) of pair k."""
    (s1, ax1, _), (s2, ax2, _) = edges
    rs, ts = _cylindrical(src, s1, ax1, _row(cols[4], k), _row(cols[5], k))
    rr, tr = _cylindrical(rcv, s2, ax2, _row(cols[6], k), _row(cols[7], k))
    nu1, nu2 = math.pi / cols[8][k], math.pi / cols[9][k]
    b1 = _beta_bound(nu1, ts, cols[10][k], cols[12], k)
    b2 = _beta_bound(nu2, cols[11][k], tr, cols[13], k)
    return rs, rr, 0.5 * cols[14][k] * nu1 * nu2 / SIXTEEN_PI2 * b1 * b2


@_jit
def _near_meeting_point(ax1, ax2, bin_m, k1, k2):  # pragma: no cover - compiled
    c = math.sqrt(_max(1 - abs(_min(_max(_dot(ax1, ax2), -1.0), 1.0)), 0.0))
    if not c > 1e-5:
        return math.inf
    return 4 * math.pi * math.sqrt(bin_m) / (c * math.sqrt(math.sqrt(k1 * k2)))


@_jit
def _bound(src, rcv, cols, k, limits):  # pragma: no cover - compiled
    """pair_bound of pair k; limits: (max excess, max path, bin width) (m)."""
    max_excess_m, max_path_m, bin_m = limits
    e1, e2 = _edges(cols, k, True)
    (s1, ax1, len1), (s2, ax2, len2) = e1, e2
    x1 = _along(s1, _apex(src, rcv, s1, ax1, len1), ax1)
    x2 = _along(s2, _apex(x1, rcv, s2, ax2, len2), ax2)
    upper = _norm(_sub(x1, src)) + _norm(_sub(x2, x1)) + _norm(_sub(rcv, x2))
    limit = _min(upper + max_excess_m, max_path_m)
    lo1, hi1 = _spheroid_interval(src, rcv, e1, limit)
    lo2, hi2 = _spheroid_interval(src, rcv, e2, limit)
    if not (hi1 >= lo1 and hi2 >= lo2):
        return 0.0
    rs, rr, scale = _betas(src, rcv, cols, k, (e1, e2))
    a1, b1 = _along(s1, lo1, ax1), _along(s1, hi1, ax1)
    a2, b2 = _along(s2, lo2, ax2), _along(s2, hi2, ax2)
    m_min, m_max = _point_segment(src, a1, b1)
    l_min, l_max = _point_segment(rcv, a2, b2)
    n_min = _segment_segment(a1, b1, a2, b2)
    whole = _inverse_distance_integral(a1, b1, a2, b2)
    k2 = rr * rr / (l_max * l_max * l_max)  # (products: not the library's pow)
    k1 = rs * rs / (m_max * m_max * m_max)
    band2 = _max(hi1 - lo1, 0.0) * 2 * math.sqrt(2 * bin_m / k2) / n_min
    band1 = _max(hi2 - lo2, 0.0) * 2 * math.sqrt(2 * bin_m / k1) / n_min
    ring = 2 * math.pi * bin_m / math.sqrt(k1 * k2)
    best = _min(_min(whole, band1), _min(band2, ring / n_min))
    best = _min(best, _near_meeting_point(ax1, ax2, bin_m, k1, k2))
    out = scale * best / (m_min * l_min)
    return math.inf if math.isnan(out) else out


@_jit
def bounds(src, rcv, cols, limits, out):  # pragma: no cover - compiled
    """:func:`acousim.trace.diffraction.pair_bound.pair_bound` of every pair into out (N,);
    src, rcv (3,) arrays; limits: (max excess, max path, bin width) (m)."""
    s = (src[0], src[1], src[2])
    r = (rcv[0], rcv[1], rcv[2])
    for k in range(out.size):
        out[k] = _bound(s, r, cols, k, limits)


@_jit
def _bin_area(legs, edges, at, widths):  # pragma: no cover - compiled
    """pair_bound._bin_area of one pair: legs (d1, d, d2, m, n, l), edges (as
    _edges), at (z1, z2, rs, rr), widths (bin, excess)."""
    d1, d, d2, m, n, l_ = legs
    (_, ax1, len1), (_, ax2, len2) = edges
    z1, z2, rs, rr = at
    bin_m, excess_m = widths[0], widths[1]
    dh = (d[0] / n, d[1] / n, d[2] / n)
    c1, c2, c12 = _dot(dh, ax1), _dot(dh, ax2), _dot(ax1, ax2)
    h11 = rs * rs / (m * m * m) + (1 - c1 * c1) / n
    h22 = rr * rr / (l_ * l_ * l_) + (1 - c2 * c2) / n
    h12 = (c1 * c2 - c12) / n
    area = 2 * math.pi * bin_m / math.sqrt(_max(h11 * h22 - h12 * h12, 1e-300))
    end1 = z1 <= 1e-9 * len1 or z1 >= len1 * (1 - 1e-9)
    end2 = z2 <= 1e-9 * len2 or z2 >= len2 * (1 - 1e-9)
    g1 = abs(_dot(d1, ax1) / m + c1)
    g2 = abs(-_dot(d2, ax2) / l_ - c2)
    if end1 and not end2:
        return _min(area, bin_m / g1 * 2 * math.sqrt(2 * excess_m / h22))
    if end2 and not end1:
        return _min(area, bin_m / g2 * 2 * math.sqrt(2 * excess_m / h11))
    if end1 and end2:
        return _min(area, bin_m * excess_m / (g1 * g2))
    return area


@_jit
def _estimate(src, rcv, cols, k, z1, widths):  # pragma: no cover - compiled
    """pair_estimate of pair k with z1 its shortest path's point on edge 1; widths:
    (bin, excess, corner margin)."""
    bin_m, corner_margin = widths[0], widths[2]
    e1, e2 = _edges(cols, k, False)
    (s1, ax1, len1), (s2, ax2, len2) = e1, e2
    rs, rr, scale = _betas(src, rcv, cols, k, (e1, e2))
    x1 = _along(s1, z1, ax1)
    z2 = _apex(x1, rcv, s2, ax2, len2)
    x2 = _along(s2, z2, ax2)
    d1, d, d2 = _sub(x1, src), _sub(x1, x2), _sub(rcv, x2)
    m, n, l_ = _norm(d1), _norm(d), _norm(d2)
    if n <= 1e-9 * _max(m, l_):  # a shared corner: the path's slopes away from it
        s_1 = 1 + _dot(d1, ax1) / m * (-1.0 if z1 > 0.5 * len1 else 1.0)
        s_2 = 1 + -_dot(d2, ax2) / l_ * (-1.0 if z2 > 0.5 * len2 else 1.0)
        g = _max(_min(s_1, s_2), 1e-3)
        c = math.sqrt(_max(1 - abs(_dot(ax1, ax2)), 1e-6))
        out = scale * (math.pi / 2) * (bin_m / g) / (c * m * l_) * corner_margin
    else:
        legs = (d1, d, d2, m, n, l_)
        out = scale / (m * n * l_) * _bin_area(legs, (e1, e2), (z1, z2, rs, rr), widths)
    return out if math.isfinite(out) else math.inf


@_jit
def estimates(src, rcv, cols, z1, widths, out):  # pragma: no cover - compiled
    """:func:`acousim.trace.diffraction.pair_bound.pair_estimate` of every pair into out (N,);
    src, rcv (3,) arrays; z1 (N,): the shortest paths' points on edge 1; widths:
    (bin, excess, corner margin)."""
    s = (src[0], src[1], src[2])
    r = (rcv[0], rcv[1], rcv[2])
    for k in range(out.size):
        out[k] = _estimate(s, r, cols, k, z1[k], widths)
