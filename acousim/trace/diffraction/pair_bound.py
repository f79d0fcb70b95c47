"""Which edge pairs can matter: a closed-form upper bound, and an estimate, of the
largest path one pair of edges adds by edge-to-edge diffraction.

The edge-to-edge response of edges 1 and 2 (:mod:`acousim.trace.diffraction.pairs`) is::

    h_2(t) = f (nu1 nu2 / 16 pi^2) int int delta(t - P / c) beta_1 beta_2 / (m n l) dz1 dz2

with ``P = m + n + l`` (m = |S - z1|, n = |z1 - z2|, l = |z2 - R|), integrated over the
pairs whose path lies within ``max_excess_m`` of the shortest one, and summed into
bins of ``bin_m`` of path length: every bin is one path, which the tracer's energy
floor keeps or drops by its amplitude.  This module bounds the largest bin's
amplitude of a pair from its geometry alone (no integration), so that the stage
integrates a pair only if its bound reaches the floor; a pair whose bound is below
the floor loses nothing the floor would keep.

The bound, for every pair (all factors are upper bounds):

1. ``|beta_i| = |sin(nu phi_i)| / (cosh(nu eta) - cos(nu phi_i)) <= |cot(nu phi_i / 2)|``
   (eta >= 0): B1 = sum_i |w_i| |cot(nu1 phi_i / 2)| for S and the face of edge 1
   that holds edge 2 (angles th_S and theta_12), B2 likewise for edge 2 and R.
2. The domain: the shortest path is at most P at (z1 = first-order apex of S, R on
   edge 1, z2 = the apex of z1, R on edge 2); a z1 can be on a kept path only if
   ``m + |z1 - R| <= limit`` (the path through z1 is at least that), a z2 only if
   ``|S - z2| + l <= limit``: two sub-segments, of lengths L1, L2, found on the
   spheroids with foci S and R.  m_min, l_min (m_max, l_max): the least (largest)
   distances of S and R to them; n_min: the least distance between them.
3. Bounds of the largest bin, the least of which is taken:
   (a) the whole integral of |integrand| (every bin is at most the sum):
   ``B1 B2 / (m_min l_min) int int dz1 dz2 / n``, the last in closed form for two
   coplanar segments (parallel: exactly; on lines meeting at an angle alpha:
   ``n >= sqrt(1 - |cos alpha|) sqrt(a^2 + b^2)`` with a, b the distances from the
   meeting point);
   (b) for each z1 the z2 of one bin: P is convex in z2 with curvature at least
   ``kappa2 = r_R^2 / l_max^3`` (r_R: R's distance from edge 2), so they span at
   most ``2 sqrt(2 bin / kappa2)``: ``B1 B2 L1 2 sqrt(2 bin / kappa2) / (m_min
   n_min l_min)``;
   (c) the same with the roles of the edges swapped (``kappa1 = r_S^2 / m_max^3``);
   (d) one bin about the least path: along every ray from it the path grows with
   curvature at least that of H = diag(kappa1, kappa2) (the Hessian of n is positive
   semi-definite), so a bin covers at most ``2 pi bin / sqrt(kappa1 kappa2)`` of
   (z1, z2), over which ``1 / n <= 1 / n_min``;
   (e) for edges on lines that meet: the same area with ``1 / n`` integrated about
   the meeting point (:func:`_near_meeting_point`).

The bound is rigorous but loose (10 to 10^4 times the largest bin in the corridor);
:func:`pair_estimate` estimates the largest bin at the pair's shortest path, and
:func:`coarse_estimate` integrates the pair at a coarse step (:data:`COARSE_STEPS`
times the element step, a tenth of the cost); the stage integrates a pair at the
fine step if the bound, the estimate times :data:`ESTIMATE_MARGIN` and the coarse
estimate times :data:`COARSE_MARGIN` all reach the floor.  Tested in
``tests/acousim/trace/diffraction/test_pair_selection.py`` (every pair of a scene integrated in
full:
the bound above each pair's largest bin; the stage's paths above the floor those
of the full computation).

Both :func:`pair_bound` and :func:`pair_estimate` run compiled, one pass over the
pairs in scalar math (:mod:`._bound_kernel`, numba, the ``fast`` extra), else on
whole numpy arrays here; the two agree within rounding
(``tests/acousim/trace/diffraction/test_bound_kernel.py``).
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from acousim.trace.diffraction.btm import DEFAULT_MAX_EXCESS_M
from acousim.trace.diffraction.pair_geometry import (
    PairGeometry,
    _apex,
    _dot,
    cylindrical,
    shortest_paths,
)
from acousim.trace.diffraction.pairs import BIN, _elements
from processing.base.kernels import optional_kernel

__all__ = [
    "COARSE_MARGIN",
    "ESTIMATE_MARGIN",
    "beta_bound",
    "coarse_estimate",
    "pair_bound",
    "pair_estimate",
]


def _cylindrical(p, start, end, face_dir, normal):
    """(r, theta, z, axis, length) of point(s) p about N edges given by their ends
    (:func:`~acousim.trace.diffraction.pair_geometry.cylindrical`, theta in [0, 2 pi))."""
    length = np.linalg.norm(end - start, axis=1)
    axis = (end - start) / np.maximum(length, 1e-300)[:, None]
    return (*cylindrical(p, start, axis, face_dir, normal), axis, length)


def beta_bound(nu: np.ndarray, th_a: np.ndarray, th_b: np.ndarray, terms: np.ndarray):
    """Upper bound (N,) of |sum_i w_i beta_i| over every eta >= 0: ``sum_i |w_i|
    |cot(nu phi_i / 2)|`` (inf where a term is singular: an end in a boundary plane)."""
    phi = np.pi + np.stack([th_a + th_b, th_a - th_b, -th_a + th_b, -th_a - th_b], axis=1)
    half = np.mod(nu[:, None] * phi / 2, np.pi)
    s = np.sin(half)
    with np.errstate(divide="ignore", invalid="ignore"):
        cot = np.where(s > 1e-12, np.abs(np.cos(half)) / s, np.inf)
    w = np.abs(np.asarray(terms, float))
    return np.where(w > 0, w * cot, 0.0).sum(axis=1)


def _spheroid_interval(s, r, start, axis, length, limit):
    """The sub-segment [lo, hi] of each edge (z along its axis) where |s - x| + |x - r|
    <= limit (N,); lo > hi where there is none."""
    centre = 0.5 * (s + r)
    c = 0.5 * np.linalg.norm(r - s, axis=-1)
    focal = np.broadcast_to(r - s, start.shape)
    u = focal / np.where(c > 0, 2 * c, 1.0)[..., None]
    a2 = (0.5 * limit) ** 2
    b2 = np.maximum(a2 - c * c, 0.0)
    y0 = start - centre
    y0u, eu, y0e = _dot(y0, u), _dot(axis, u), _dot(y0, axis)
    q2 = b2 * eu**2 + a2 * (1 - eu**2)
    q1 = 2 * (b2 * y0u * eu + a2 * (y0e - y0u * eu))
    q0 = b2 * y0u**2 + a2 * (_dot(y0, y0) - y0u**2) - a2 * b2
    disc = q1**2 - 4 * q2 * q0
    root = np.sqrt(np.maximum(disc, 0.0))
    q2 = np.where(q2 > 0, q2, 1e-300)
    lo = np.maximum((-q1 - root) / (2 * q2), 0.0)
    hi = np.minimum((-q1 + root) / (2 * q2), length)
    return np.where(disc >= 0, lo, 1.0), np.where(disc >= 0, hi, 0.0)


def _point_segment(p, a, b):
    """Least and largest distance (N,) from points p to segments a-b."""
    ab = b - a
    t = np.clip(_dot(p - a, ab) / np.maximum(_dot(ab, ab), 1e-300), 0, 1)
    near = np.linalg.norm(a + t[:, None] * ab - p, axis=1)
    far = np.maximum(np.linalg.norm(a - p, axis=1), np.linalg.norm(b - p, axis=1))
    return near, far


def _segment_segment(a1, b1, a2, b2):
    """Least distance (N,) between segments a1-b1 and a2-b2 (sampled ends and the
    closest points of the lines, clipped: exact for coplanar segments)."""
    cands = [
        _point_segment(a1, a2, b2)[0],
        _point_segment(b1, a2, b2)[0],
        _point_segment(a2, a1, b1)[0],
        _point_segment(b2, a1, b1)[0],
    ]
    d1, d2, r = b1 - a1, b2 - a2, a1 - a2
    aa, ee, bb = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    cc, ff = _dot(d1, r), _dot(d2, r)
    den = aa * ee - bb * bb
    ok = den > 1e-12 * np.maximum(aa * ee, 1e-300)
    s = np.clip(np.where(ok, (bb * ff - cc * ee) / np.where(ok, den, 1.0), 0.0), 0, 1)
    t = np.clip(np.where(ok, (aa * ff - bb * cc) / np.where(ok, den, 1.0), 0.0), 0, 1)
    cands.append(
        np.where(ok, np.linalg.norm(a1 + s[:, None] * d1 - a2 - t[:, None] * d2, axis=1), np.inf)
    )
    return np.min(np.stack(cands), axis=0)


def _quadrant(a, b):
    """int_0^a int_0^b dx dy / sqrt(x^2 + y^2) for a, b >= 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(a > 0, a * np.arcsinh(b / np.where(a > 0, a, 1.0)), 0.0)
        t2 = np.where(b > 0, b * np.arcsinh(a / np.where(b > 0, b, 1.0)), 0.0)
    return t1 + t2


def _interval_abs(lo, hi):
    """[lo, hi] as pieces of |x|: ((0, p), (0, q), sign) so that int_lo^hi g(|x|) dx =
    G(p) + s G(q) for G(t) = int_0^t g (s = +1 across zero, -1 on one side)."""
    across = (lo < 0) & (hi > 0)
    neg = hi <= 0
    p = np.where(across, -lo, np.where(neg, -lo, hi))
    q = np.where(across, hi, np.where(neg, -hi, lo))
    sign = np.where(across, 1.0, -1.0)
    return p, q, sign


def _inverse_distance_integral(a1, b1, a2, b2):
    """Upper bound (N,) of int int dz1 dz2 / |z1 - z2| over two segments (exact when
    parallel, a bound on lines that meet; coplanar segments, else a bound still:
    the out-of-plane distance only adds)."""
    u1 = b1 - a1
    u2 = b2 - a2
    l1 = np.linalg.norm(u1, axis=1)
    l2 = np.linalg.norm(u2, axis=1)
    u1 = u1 / np.maximum(l1, 1e-300)[:, None]
    u2 = u2 / np.maximum(l2, 1e-300)[:, None]
    cos = np.clip(_dot(u1, u2), -1, 1)
    sin2 = 1 - cos * cos
    parallel = sin2 < 1e-10
    # parallel: n = sqrt(d^2 + (s1 - s2)^2), s along u1
    s1a, s1b = np.zeros_like(l1), l1
    s2a, s2b = _dot(a2 - a1, u1), _dot(b2 - a1, u1)
    s2a, s2b = np.minimum(s2a, s2b), np.maximum(s2a, s2b)
    perp = (a2 - a1) - _dot(a2 - a1, u1)[:, None] * u1
    d = np.maximum(np.linalg.norm(perp, axis=1), 1e-300)

    def h(x):
        return x * np.arcsinh(x / d) - np.sqrt(x * x + d * d)

    par = h(s1b - s2a) - h(s1b - s2b) - h(s1a - s2a) + h(s1a - s2b)
    par = np.where(np.linalg.norm(perp, axis=1) > 0, par, np.inf)
    # meeting lines: the meeting point O of the lines in their common plane
    w = a2 - a1
    den = np.where(parallel, 1.0, sin2)
    t1 = (_dot(w, u1) - cos * _dot(w, u2)) / den  # along u1 from a1
    t2 = (cos * _dot(w, u1) - _dot(w, u2)) / den  # along u2 from a2
    pa, qa, sa = _interval_abs(-t1, l1 - t1)
    pb, qb, sb = _interval_abs(-t2, l2 - t2)
    rect = (
        _quadrant(pa, pb)
        + sb * _quadrant(pa, qb)
        + sa * _quadrant(qa, pb)
        + sa * sb * _quadrant(qa, qb)
    )
    meet = rect / np.sqrt(np.maximum(1 - np.abs(cos), 1e-300))
    return np.where(parallel, par, meet)


def pair_bound(
    pairs: PairGeometry,
    source: np.ndarray,
    receiver: np.ndarray,
    *,
    max_excess_m: float,
    max_path_m: float,
    bin_m: float,
    use_kernel: bool = True,
) -> np.ndarray:
    """Upper bound (N,) of the largest bin amplitude (free-field 1/r units at R) of
    each pair's edge-to-edge response (see the module docstring); 0 where no path
    of the pair is within max_path_m.  source, receiver (3,); bin_m: the bins'
    width in path length (m); use_kernel: the compiled kernel
    (:mod:`._bound_kernel`) if numba is installed, else (or False) numpy (they
    agree within rounding)."""
    p = pairs
    n = len(p)
    if n == 0:
        return np.zeros(0)
    kernel = optional_kernel("acousim.trace.diffraction.bound_kernel") if use_kernel else None
    if kernel is not None:
        out = np.empty(n)
        limits = (float(max_excess_m), float(max_path_m), float(bin_m))
        kernel.bounds(_point(source), _point(receiver), _columns(p), limits, out)
        return out
    return _bound_numpy(p, source, receiver, (max_excess_m, max_path_m, bin_m))


def _bound_numpy(p: PairGeometry, source, receiver, limits) -> np.ndarray:
    """:func:`pair_bound` on whole arrays; limits: (max excess, max path, bin) (m)."""
    max_excess_m, max_path_m, bin_m = limits
    rs, ts, _, ax1, len1 = _cylindrical(source, p.start1, p.end1, p.face_dir1, p.normal1)
    rr, tr, _, ax2, len2 = _cylindrical(receiver, p.start2, p.end2, p.face_dir2, p.normal2)
    nu1, nu2 = np.pi / p.angle1, np.pi / p.angle2
    b1 = beta_bound(nu1, ts, p.theta12, p.terms1)
    b2 = beta_bound(nu2, p.theta21, tr, p.terms2)
    # 2. a path no shorter than the shortest: first-order apex on edge 1, then edge 2's
    z1 = _apex(source, receiver, p.start1, ax1, len1)
    x1 = p.start1 + z1[:, None] * ax1
    z2 = _apex(x1, receiver, p.start2, ax2, len2)
    x2 = p.start2 + z2[:, None] * ax2
    upper = (
        np.linalg.norm(x1 - source, axis=1)
        + np.linalg.norm(x2 - x1, axis=1)
        + np.linalg.norm(receiver - x2, axis=1)
    )
    limit = np.minimum(upper + max_excess_m, max_path_m)
    lo1, hi1 = _spheroid_interval(source, receiver, p.start1, ax1, len1, limit)
    lo2, hi2 = _spheroid_interval(source, receiver, p.start2, ax2, len2, limit)
    live = (hi1 >= lo1) & (hi2 >= lo2)
    a1, e1 = p.start1 + lo1[:, None] * ax1, p.start1 + hi1[:, None] * ax1
    a2, e2 = p.start2 + lo2[:, None] * ax2, p.start2 + hi2[:, None] * ax2
    m_min, m_max = _point_segment(source, a1, e1)
    l_min, l_max = _point_segment(receiver, a2, e2)
    n_min = _segment_segment(a1, e1, a2, e2)
    scale = 0.5 * p.sides * nu1 * nu2 / (16 * np.pi**2) * b1 * b2
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        whole = _inverse_distance_integral(a1, e1, a2, e2)
        k2 = rr**2 / l_max**3
        k1 = rs**2 / m_max**3
        band2 = np.maximum(hi1 - lo1, 0) * 2 * np.sqrt(2 * bin_m / k2) / n_min
        band1 = np.maximum(hi2 - lo2, 0) * 2 * np.sqrt(2 * bin_m / k1) / n_min
        ring = 2 * np.pi * bin_m / np.sqrt(k1 * k2)
        near = _near_meeting_point(ax1, ax2, bin_m, k1, k2)
        best = np.minimum(np.minimum(whole, band1), np.minimum(band2, ring / n_min))
        best = np.minimum(best, near)
        out = scale * best / (m_min * l_min)
    out = np.where(np.isnan(out), np.inf, out)
    return np.where(live, out, 0.0)


def _near_meeting_point(ax1, ax2, bin_m, k1, k2):
    """Bound (N,) of the integral of 1 / n over one bin for edges on lines that meet
    at an angle alpha (inf for parallel ones): n >= c |x - V| with V the meeting point
    in (z1, z2), c = sqrt(1 - |cos alpha|); inside a disc of radius d about V the
    integral is at most 2 pi d / c, outside it 1 / (c d) times the bin's area
    (at most ``2 pi bin / sqrt(k1 k2)``); the best d gives
    ``4 pi sqrt(bin) / (c (k1 k2)^(1/4))``."""
    cos = np.abs(np.clip(_dot(ax1, ax2), -1, 1))
    c = np.sqrt(np.maximum(1 - cos, 0.0))
    with np.errstate(divide="ignore"):
        return np.where(c > 1e-5, 4 * np.pi * np.sqrt(bin_m) / (c * (k1 * k2) ** 0.25), np.inf)


def pair_estimate(
    pairs: PairGeometry,
    source: np.ndarray,
    receiver: np.ndarray,
    *,
    bin_m: float,
    excess_m: float = DEFAULT_MAX_EXCESS_M,
    use_kernel: bool = True,
) -> np.ndarray:
    """Estimate (N,) of the largest bin amplitude of each pair (bins of bin_m of
    path length, as :func:`pair_bound`), at the pair's shortest path (z1*, z2*):

    * inside the edges: the integrand there times the area of one bin about a
      minimum, ``f nu1 nu2 / (16 pi^2) B1 B2 / (m n l) 2 pi bin / sqrt(det H)``
      (B1, B2: :func:`beta_bound`; H: the Hessian of the path in (z1, z2) there);
    * at the end of an edge, where the path grows with slope g: a bin is a strip
      ``bin / g`` wide and at most ``2 sqrt(2 excess_m / H22)`` long (the last bin
      kept, the largest), or at the ends of both ``bin excess_m / (g1 g2)``;
    * at a corner the two edges share (n = 0 there): the 1 / n singularity over the
      bin's triangle ``g1 a + g2 b <= bin``, ``(pi / 2) (bin / g) / (c m l)`` (c =
      sqrt(1 - |cos alpha|), g the lesser slope of the path away from the corner
      along either edge), times :data:`CORNER_MARGIN`.

    Not a bound (far bins of long edges can exceed the first one); what it misses
    is measured (BENCHMARKS.md, diffraction;
    ``tests/acousim/trace/diffraction/test_pair_selection.py``),
    and the stage keeps a margin of :data:`ESTIMATE_MARGIN` on it.  use_kernel: as
    :func:`pair_bound`.
    """
    p = pairs
    if len(p) == 0:
        return np.zeros(0)
    source, receiver = np.asarray(source, float), np.asarray(receiver, float)
    kernel = optional_kernel("acousim.trace.diffraction.bound_kernel") if use_kernel else None
    if kernel is not None:
        z1 = np.ascontiguousarray(shortest_paths(p, source, receiver)[0])  # one signature
        out = np.empty(len(p))
        widths = (float(bin_m), float(excess_m), CORNER_MARGIN)
        kernel.estimates(_point(source), _point(receiver), _columns(p), z1, widths, out)
        return out
    return _estimate_numpy(p, source, receiver, (bin_m, excess_m))


def _estimate_numpy(p: PairGeometry, source, receiver, widths) -> np.ndarray:
    """:func:`pair_estimate` on whole arrays; widths: (bin, excess) (m)."""
    bin_m, excess_m = widths
    ax1, len1 = p.edge1()
    ax2, len2 = p.edge2()
    rs, ts, _ = cylindrical(source, p.start1, ax1, p.face_dir1, p.normal1)
    rr, tr, _ = cylindrical(receiver, p.start2, ax2, p.face_dir2, p.normal2)
    nu1, nu2 = np.pi / p.angle1, np.pi / p.angle2
    b1 = beta_bound(nu1, ts, p.theta12, p.terms1)
    b2 = beta_bound(nu2, p.theta21, tr, p.terms2)
    z1, _ = shortest_paths(p, source, receiver)
    x1 = p.start1 + z1[:, None] * ax1
    z2 = _apex(x1, receiver, p.start2, ax2, len2)
    x2 = p.start2 + z2[:, None] * ax2
    d1, d, d2 = x1 - source, x1 - x2, receiver - x2
    m, n, l_ = (np.linalg.norm(v, axis=1) for v in (d1, d, d2))
    scale = 0.5 * p.sides * nu1 * nu2 / (16 * np.pi**2) * b1 * b2
    legs = (d1, d, d2, m, n, l_)
    with np.errstate(divide="ignore", invalid="ignore"):
        inside = scale / (m * n * l_) * _bin_area(p, legs, (z1, z2, rs, rr), (bin_m, excess_m))
        # a shared corner: the slopes of the path away from it along each edge
        s1 = 1 + _dot(d1, ax1) / m * np.where(z1 > 0.5 * len1, -1, 1)
        s2 = 1 + _dot(-d2, ax2) / l_ * np.where(z2 > 0.5 * len2, -1, 1)
        g = np.maximum(np.minimum(s1, s2), 1e-3)
        c = np.sqrt(np.maximum(1 - np.abs(_dot(ax1, ax2)), 1e-6))
        corner = scale * (np.pi / 2) * (bin_m / g) / (c * m * l_) * CORNER_MARGIN
    tiny = n <= 1e-9 * np.maximum(m, l_)
    out = np.where(tiny, corner, inside)
    return np.where(np.isfinite(out), out, np.inf)


def _point(x) -> np.ndarray:
    """A point (3,) as the kernel takes it (float, contiguous)."""
    return np.ascontiguousarray(x, float).reshape(3)


def _columns(p: PairGeometry) -> tuple:
    """The arrays of `p` in the order of its fields, as :mod:`._bound_kernel` takes
    them (float, but `sides`, and contiguous)."""
    return tuple(
        np.ascontiguousarray(getattr(p, f.name), int if f.name == "sides" else float)
        for f in fields(p)
    )


def _bin_area(p: PairGeometry, legs, at, widths) -> np.ndarray:
    """The area (N,) in (z1, z2) of one bin about the shortest path (see
    :func:`pair_estimate`); legs: (S -> z1, z1 - z2, R - z2 vectors and lengths),
    at: (z1, z2, r of S about edge 1, r of R about edge 2), widths: (bin, excess)."""
    d1, d, d2, m, n, l_ = legs
    z1, z2, rs, rr = at
    bin_m, excess_m = widths
    ax1, len1 = p.edge1()
    ax2, len2 = p.edge2()
    with np.errstate(divide="ignore", invalid="ignore"):
        dh = d / n[:, None]
        c1, c2, c12 = _dot(dh, ax1), _dot(dh, ax2), _dot(ax1, ax2)
        h11 = rs**2 / m**3 + (1 - c1**2) / n
        h22 = rr**2 / l_**3 + (1 - c2**2) / n
        h12 = (c1 * c2 - c12) / n
        det = np.maximum(h11 * h22 - h12**2, 1e-300)
        area = 2 * np.pi * bin_m / np.sqrt(det)
        # at an end of an edge the path grows there with slope g: a bin is a strip
        # bin / g wide along the other edge (up to the excess kept), or a band at
        # the ends of both
        end1 = (z1 <= 1e-9 * len1) | (z1 >= len1 * (1 - 1e-9))
        end2 = (z2 <= 1e-9 * len2) | (z2 >= len2 * (1 - 1e-9))
        g1 = np.abs(_dot(d1, ax1) / m + c1)
        g2 = np.abs(-_dot(d2, ax2) / l_ - c2)
        strip1 = bin_m / g1 * 2 * np.sqrt(2 * excess_m / h22)
        strip2 = bin_m / g2 * 2 * np.sqrt(2 * excess_m / h11)
        area = np.where(end1 & ~end2, np.minimum(area, strip1), area)
        area = np.where(end2 & ~end1, np.minimum(area, strip2), area)
        return np.where(end1 & end2, np.minimum(area, bin_m * excess_m / (g1 * g2)), area)


#: the corner estimate is scaled up by this (it is the least reliable: measured
#: between 0.1 and 10^4 times the largest bin; with ESTIMATE_MARGIN, at least 1.5
#: times it in every case measured)
CORNER_MARGIN = 3.0

#: the stage integrates a pair whose estimate times this reaches the floor
ESTIMATE_MARGIN = 5.0


#: the coarse pass's element step and bins, in element steps and bins of the fine one
COARSE_STEPS = 4
#: halvings of the coarse pass's first step next to edge 1's apex and edge 2's
#: (2 and 2: a tenth less time than 4 and 4, the same pairs and bins selected in
#: the 20 poses of the corridor benchmark, and closer to the fine bins: its largest
#: bin up to 2.0 times the coarse estimate there, against 2.6 with 4 and 4)
COARSE_REFINE = (2, 2)
#: the stage integrates a pair whose coarse estimate times this reaches the floor
#: (the largest fine bin measured at up to 2.0 times the coarse estimate in the
#: corridor, 20 poses: at 1/sqrt(excess) onsets, at an edge's end, the fine bins
#: resolve a peak the coarse ones average over, sqrt(COARSE_STEPS)), and in the
#: bins whose coarse level times this reaches it
COARSE_MARGIN = 4.0
#: the fine pass integrates the coarse bins that reach the floor and this many
#: either side of each (half of a coarse element's step); in the 30 poses 0, 2, ...,
#: 58 of the corridor drive 2 misses none of the 15,794 fine bins above the stage's
#: floor that 4 keep, in 88 % of the fine pass's time (1: none either, 80 %, but 3
#: of 525 in tests/acousim/trace/diffraction/test_pair_selection.py's room; 0: 192 missed, up to
# 3.3 dB
#: above the floor)
LIVE_SPREAD = 2


def coarse_estimate(
    pairs: PairGeometry,
    source: np.ndarray,
    receiver: np.ndarray,
    *,
    step_m: float,
    bin_m: float,
    floor: float,
    max_path_m: float = np.inf,
    workers=None,
) -> tuple[np.ndarray, tuple[np.ndarray, float]]:
    """Estimates from each pair's integral at :data:`COARSE_STEPS` times the element
    step step_m (m) with :data:`COARSE_REFINE` halvings next to the apexes, its bins
    (of width w) scaled to bin_m's width (m): (the largest bin (N,); (the coarse
    bins whose estimate times :data:`COARSE_MARGIN` reaches `floor` and
    :data:`LIVE_SPREAD` either side (N, B), w): the live bins of
    :func:`acousim.trace.diffraction.pairs.pair_elements_in`).  Not bounds: what they miss
    is measured, as for :func:`pair_estimate`.  workers: the threads to share the
    pairs among (:func:`acousim.trace.diffraction.pairs.pair_elements_in`)."""
    coarse = COARSE_STEPS * step_m
    width = coarse * BIN
    limits = (coarse, max_path_m, DEFAULT_MAX_EXCESS_M, width, COARSE_REFINE)
    el = _elements(pairs, source, receiver, limits, True, workers=workers)
    amp = np.abs(el.amplitude) * bin_m / width
    largest = np.zeros(len(pairs))
    np.maximum.at(largest, el.pair, amp)
    _, p_min = shortest_paths(pairs, source, receiver)
    excess = el.first_leg_m + el.second_leg_m - p_min[el.pair]
    b = np.maximum(np.floor(excess / width), 0).astype(np.int64)
    n_b = int(np.ceil(DEFAULT_MAX_EXCESS_M / width)) + 4
    dense = np.zeros((len(pairs), n_b))
    np.add.at(dense, (el.pair, np.minimum(b, n_b - 1)), amp)
    # a coarse element's bin holds what the fine bins of one coarse step share:
    # the level of a bin is its own or the mean over a step either side
    spread = 1 + 2 * COARSE_STEPS
    pad = np.pad(dense, ((0, 0), (COARSE_STEPS, COARSE_STEPS)))
    mean = sum(pad[:, i : i + n_b] for i in range(spread)) / spread
    reach = COARSE_MARGIN * np.maximum(dense, mean) >= floor
    live = reach.copy()
    for k in range(1, LIVE_SPREAD + 1):
        live[:, k:] |= reach[:, :-k]
        live[:, :-k] |= reach[:, k:]
    return largest, (live, width)
