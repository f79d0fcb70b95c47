"""Second-order (edge-to-edge) BTM diffraction: the double line integral over two
edges that share a plane, with equal-excess-path elements in both edges.

The edge-source form of Svensson and Calamia::

    h_2(t) = f (nu1 nu2 / 16 pi^2) int int delta(t - (m + n + l)/c)
             beta_1 beta_2 / (m n l) dz1 dz2

with m = |S - z1|, n = |z1 - z2|, l = |z2 - R|; beta_1 the first-order beta sum of
wedge 1 for the source S and the "receiver" z2 (at angle theta_12 about edge 1: 0
or the open angle, as edge 2 lies on a face plane of wedge 1), beta_2 that of wedge
2 for the "source" z1 (angle theta_21) and R.  The path from z1 to z2 runs along the
shared face, where the field of edge 1 already holds the face's doubling and an
edge source of edge 2 on its own face is doubled again: each side of the face along
which the path runs counts half, ``f = sides / 2`` (1 for a box face, air on one
side; 2 for the two rims of a thin plate, air on both sides, whose two products are
equal because beta changes sign from one side to the other).  The formula is
symmetric in S and R (reciprocal).

Discretisation (:func:`pair_elements`, every pair of a pose in one vectorised pass):

1. The profile ``P1(z1) = m + min_z2 (n + l)`` (the inner minimum in closed form:
   the first-order apex of z1 and R on edge 2, clipped to it) is convex in z1 (a
   partial minimum of the convex path); its least value is the pair's shortest path
   (found by bisection on the sign of its derivative, the envelope theorem's
   ``dm/dz1 + dn/dz1``).
2. Edge 1 is cut at equal steps ``step_m`` of excess profile ``P1 - P1_min`` (the
   first step subdivided 8 times, as first order), up to ``max_excess_m`` or its
   end; the cuts are found by Newton's method from the edge's ends (monotone on a
   convex function).  One point per element, at its mid excess, weight its length.
3. For each such point z1, edge 2 is the first-order integral of
   :func:`acousim.trace.btm.integrate_rows` with the source at z1 (on a face plane of
   wedge 2): equal steps of its own excess path, beta_2 integrated exactly in eta;
   its elements carry beta_1 (at their point) and ``f nu1 / (4 pi) dz1 / m``; each
   element keeps the paths within the pair's limit (shortest + max_excess_m).
4. The second half of the excess range is tapered (raised cosine) if the edges
   reach beyond it, and the elements are summed into bins of ``step_m / 4`` of
   path length per pair: one element per bin, at the bin's mean path length and
   mean points (weights |amplitude|).

Accuracy against the element step and the exact strip: BENCHMARKS.md (diffraction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.kernels import optional_kernel

from .btm import (
    DEFAULT_LIMITS,
    DEFAULT_MAX_EXCESS_M,
    DEFAULT_STEP_M,
    EdgeRows,
    ElementLimits,
    Wedge,
    integrate_rows,
)

#: bins per element step (each bin is BIN * step_m of path length)
BIN = 0.25
#: the first step next to each apex (edge 1's, and edge 2's for each element of
#: edge 1) is subdivided by halving this many times, as first order
OUTER_REFINE = 8
__all__ = [
    "EdgePairElements",
    "PairGeometry",
    "Wedge",
    "edge_pair_elements",
    "pair_elements",
    "pair_elements_in",
]


@dataclass(frozen=True, eq=False)
class EdgePairElements:
    """K elements of the edge-to-edge paths S -> edge 1 -> edge 2 -> R (world frame).

    pair (K,): the pair (of :class:`PairGeometry`) each element belongs to.

    first_point_m (K, 3): mean point on edge 1; point_m (K, 3): mean point on edge 2;
    first_leg_m (K,): path length from S over edge 1 to point_m; second_leg_m (K,):
    |point_m - R|; amplitude (K,): the element's impulse amplitude at R (free field
    ``1/r`` units), signed.  The path length of an element at R is exact
    (first_leg_m + second_leg_m); its points are means over the element.
    """

    first_point_m: np.ndarray
    point_m: np.ndarray
    first_leg_m: np.ndarray
    second_leg_m: np.ndarray
    amplitude: np.ndarray
    pair: np.ndarray | None = None

    def __post_init__(self):
        if self.pair is None:
            object.__setattr__(self, "pair", np.zeros(self.amplitude.size, int))

    def __len__(self) -> int:
        return self.amplitude.size

    @staticmethod
    def empty() -> EdgePairElements:
        z3, z = np.zeros((0, 3)), np.zeros(0)
        return EdgePairElements(z3, z3, z, z, z, np.zeros(0, int))


@dataclass(frozen=True, eq=False)
class PairGeometry:
    """N ordered edge pairs that share a plane (world frame, metres).

    start1, end1, start2, end2 (N, 3): the edges; face_dir1, normal1 (N, 3): edge
    1's wedge oriented for the source (air at angles 0 .. angle1; normal towards the
    air), face_dir2, normal2 edge 2's oriented for the receiver; angle1, angle2
    (N,): open angles (rad); theta12, theta21 (N,): the angle of edge 2 about edge 1
    and of edge 1 about edge 2 (rad: 0 or the open angle); terms1, terms2 (N, 4):
    the weights of the four beta terms of each wedge (``(R2, 1, 1, R1)``: the whole
    wedge, see :class:`Wedge`); sides (N,): 1 or 2 (see the module docstring).
    """

    start1: np.ndarray
    end1: np.ndarray
    start2: np.ndarray
    end2: np.ndarray
    face_dir1: np.ndarray
    normal1: np.ndarray
    face_dir2: np.ndarray
    normal2: np.ndarray
    angle1: np.ndarray
    angle2: np.ndarray
    theta12: np.ndarray
    theta21: np.ndarray
    terms1: np.ndarray
    terms2: np.ndarray
    sides: np.ndarray

    def __len__(self) -> int:
        return self.angle1.size

    @classmethod
    def of(cls, wedge1: Wedge, wedge2: Wedge, theta_12: float, theta_21: float, sides: int):
        """One pair from two :class:`Wedge`."""

        def terms(w):
            r1, r2 = w.reflection
            return np.array([w.terms if w.terms is not None else (r2, 1.0, 1.0, r1)], float)

        def row(x):
            return np.asarray(x, float)[None]

        return cls(
            row(wedge1.start_m), row(wedge1.end_m), row(wedge2.start_m), row(wedge2.end_m),
            row(wedge1.face_dir), row(wedge1.normal), row(wedge2.face_dir), row(wedge2.normal),
            row(wedge1.angle_rad), row(wedge2.angle_rad), row(theta_12), row(theta_21),
            terms(wedge1), terms(wedge2), np.array([sides], int),
        )  # fmt: skip

    def edge1(self):
        """(axis (N, 3), length (N,)) of edge 1."""
        return _axis(self.start1, self.end1)

    def edge2(self):
        """(axis (N, 3), length (N,)) of edge 2."""
        return _axis(self.start2, self.end2)


def _axis(start, end):
    length = np.linalg.norm(end - start, axis=1)
    return (end - start) / np.where(length > 0, length, 1.0)[:, None], length


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def cylindrical(p, start, axis, face_dir, normal):
    """(r, theta, z) (N,) of points p (3,) or (N, 3) about N edges; theta in [0, 2 pi)
    from face 1 towards its normal, z along the edge from its start."""
    d = p - start
    z = _dot(d, axis)
    v = d - z[:, None] * axis
    th = np.mod(np.arctan2(_dot(v, normal), _dot(v, face_dir)), 2 * np.pi)
    return np.linalg.norm(v, axis=1), th, z


def edge_pair_elements(
    wedge1: Wedge,
    wedge2: Wedge,
    theta_12: float,
    theta_21: float,
    sides: int,
    source: np.ndarray,
    receiver: np.ndarray,
    limits: ElementLimits = DEFAULT_LIMITS,
) -> EdgePairElements:
    """:func:`pair_elements` of one pair of wedges (see :class:`PairGeometry`)."""
    return pair_elements(
        PairGeometry.of(wedge1, wedge2, theta_12, theta_21, sides),
        source,
        receiver,
        step_m=limits.step_m,
        max_path_m=limits.max_path_m,
        max_excess_m=limits.max_excess_m,
    )


@dataclass(frozen=True)
class _Profile:
    """The profile P1(z1) = m + min_z2 (n + l) of N pairs (step 1)."""

    pairs: PairGeometry
    source: np.ndarray
    receiver: np.ndarray

    def __call__(self, z1: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """P1 and dP1/dz1 at z1 (K,) on the edges 1 of pairs k (K,)."""
        p = self.pairs
        ax1, _ = p.edge1()
        ax2, len2 = p.edge2()
        x1 = p.start1[k] + z1[:, None] * ax1[k]
        z2 = _apex(x1, self.receiver, p.start2[k], ax2[k], len2[k])
        x2 = p.start2[k] + z2[:, None] * ax2[k]
        d1, d2 = x1 - self.source, x1 - x2
        m = np.linalg.norm(d1, axis=1)
        n = np.linalg.norm(d2, axis=1)
        value = m + n + np.linalg.norm(self.receiver - x2, axis=1)
        slope = _dot(d1, ax1[k]) / np.maximum(m, 1e-300) + _dot(d2, ax1[k]) / np.maximum(n, 1e-300)
        return value, slope


def _edge_table(pairs: PairGeometry) -> np.ndarray:
    """(N, 14): start1, axis1, length1, start2, axis2, length2 of each pair."""
    ax1, len1 = pairs.edge1()
    ax2, len2 = pairs.edge2()
    return np.column_stack([pairs.start1, ax1, len1, pairs.start2, ax2, len2])


def _apex(s, r, start, axis, length):
    """First-order apex (K,) of s (K, 3) or (3,) and r (3,) on K edges (z along each
    edge from its start, clipped to it): the point of least |s - x| + |x - r|."""
    ds, dr = s - start, r - start
    zs, zr = _dot(ds, axis), _dot(dr, axis)
    rs = np.linalg.norm(ds - zs[:, None] * axis, axis=1)
    rr = np.linalg.norm(dr - zr[:, None] * axis, axis=1)
    tot = rs + rr
    z = np.where(tot > 0, (rr * zs + rs * zr) / np.where(tot > 0, tot, 1.0), zs)
    return np.clip(z, 0.0, length)


def shortest_paths(pairs: PairGeometry, source, receiver) -> tuple[np.ndarray, np.ndarray]:
    """(z1 at the pair's shortest path, that path's length) (N,) each: the least of
    the convex profile, by bisection on the sign of its slope (60 halvings; compiled
    if numba is installed)."""
    kernel = optional_kernel("acousim.trace._pair_kernel")
    if kernel is not None:
        out = np.empty((len(pairs), 2))
        kernel.shortest(
            np.asarray(source, float), np.asarray(receiver, float), _edge_table(pairs), out
        )
        return out[:, 0], out[:, 1]
    prof = _Profile(pairs, source, receiver)
    _, length = pairs.edge1()
    k = np.arange(len(pairs))
    lo, hi = np.zeros(len(pairs)), length.copy()
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        up = prof(mid, k)[1] > 0
        lo, hi = np.where(up, lo, mid), np.where(up, mid, hi)
    z = 0.5 * (lo + hi)
    return z, prof(z, k)[0]


def _levels(prof: _Profile, k, z_apex, z_end, p_min, level, newton=30):
    """z (K,) where the profile of pair k reaches p_min + level between its apex and
    z_end (Newton from z_end: monotone on a convex function; clipped)."""
    z = z_end.copy()
    target = p_min + level
    lo, hi = np.minimum(z_apex, z_end), np.maximum(z_apex, z_end)
    for _ in range(newton):
        value, slope = prof(z, k)
        gap = value - target
        safe = np.abs(slope) > 1e-12
        z = np.clip(np.where(safe, z - gap / np.where(safe, slope, 1.0), z), lo, hi)
        if np.all(np.abs(gap) < 1e-12 + 1e-9 * level):
            break
    return np.where(level <= 0, z_apex, z)


def pair_elements(
    pairs: PairGeometry,
    source: np.ndarray,
    receiver: np.ndarray,
    *,
    step_m: float = DEFAULT_STEP_M,
    max_path_m: float | np.ndarray = np.inf,
    max_excess_m: float = DEFAULT_MAX_EXCESS_M,
    bin_m: float | None = None,
    use_kernel: bool = True,
) -> EdgePairElements:
    """Edge-to-edge elements of every pair at once (steps 1-4 of the module
    docstring).  source, receiver (3,); step_m: excess path per element and four
    bins per step (m); paths longer than max_path_m (m; one, or (N,) one per pair)
    are left out (the bins of paths shorter by two steps are as without it); the
    response is kept to max_excess_m beyond each pair's shortest path (second half
    tapered);
    bin_m: the bins' width (m; None: step_m / 4);
    use_kernel: the compiled kernel (:mod:`._pair_kernel`) if numba is installed,
    else (or False) whole arrays in numpy (they agree within rounding)."""
    limits = (step_m, max_path_m, max_excess_m, bin_m or step_m * BIN, OUTER_REFINE)
    return _elements(pairs, source, receiver, limits, use_kernel)


def pair_elements_in(
    pairs: PairGeometry,
    source: np.ndarray,
    receiver: np.ndarray,
    live: tuple[np.ndarray, float],
    *,
    step_m: float = DEFAULT_STEP_M,
    bin_m: float | None = None,
    max_path_m: float = np.inf,
) -> EdgePairElements:
    """:func:`pair_elements` (excess kept :data:`DEFAULT_MAX_EXCESS_M`), only the
    bins of excess path within `live`: (mask (N, B), width w (m)), bin b of pair k
    the excess [b w, (b + 1) w) beyond the pair's shortest path.  The bins given are
    those of the whole integral (the compiled kernel skips an element of another
    bin before evaluating its beta terms)."""
    limits = (step_m, max_path_m, DEFAULT_MAX_EXCESS_M, bin_m or step_m * BIN, OUTER_REFINE)
    return _elements(pairs, source, receiver, limits, True, live)


def _elements(pairs: PairGeometry, source, receiver, limits, use_kernel, live=None):
    """:func:`pair_elements` (:class:`EdgePairElements`); limits: (step, longest path,
    excess kept, bin width) in metres and the halvings of the first step next to
    each apex (in both edges); live: as :func:`pair_elements_in` (None: all)."""
    source, receiver = np.asarray(source, float), np.asarray(receiver, float)
    step_m, max_path_m, max_excess_m, bin_m, refine = limits
    if len(pairs) == 0 or step_m <= 0:
        return EdgePairElements.empty()
    kernel = optional_kernel("acousim.trace._pair_kernel") if use_kernel else None
    if kernel is not None and np.isfinite(max_excess_m):
        from .btm_pairs_compiled import compiled_elements  # it imports this module

        return compiled_elements(kernel, pairs, source, receiver, (limits, live))
    z_apex, p_min = shortest_paths(pairs, source, receiver)
    limit = np.minimum(p_min + max_excess_m, max_path_m)
    outer = _outer(_Profile(pairs, source, receiver), z_apex, p_min, limit, (step_m, refine))
    if outer is None:
        return EdgePairElements.empty()
    k, z1, dz1 = outer
    el, g = _inner(pairs, source, receiver, (k, z1, dz1), limit, (step_m, refine))
    if g.size == 0:
        return EdgePairElements.empty()
    kg = k[g]
    path = el["m"] + el["n"] + el["l"]
    far = _farthest(pairs, source, receiver)
    x = np.clip((path - p_min[kg] - max_excess_m / 2) / (max_excess_m / 2), 0, 1)
    cut = (far - p_min > max_excess_m)[kg]
    amp = el["amp"] * np.where(cut, 0.5 * (1 + np.cos(np.pi * x)), 1.0)
    good = np.isfinite(amp) & (amp != 0)
    if live is not None:
        b = np.floor((path - p_min[kg]) / bin_m).astype(np.int64)
        from .btm_pairs_compiled import fine_live

        mask = fine_live(live, int(b.max(initial=0)) + 1, bin_m)
        good &= mask[kg, np.maximum(b, 0)] > 0
    return _bins(
        kg[good],
        path[good] - p_min[kg[good]],
        (amp[good], path[good], el["x1"][good], el["x2"][good]),
        receiver,
        bin_m,
    )


def _outer(prof: _Profile, z_apex, p_min, limit, steps):
    """Step 2: the elements of edge 1: (pair (K,), centre z1 (K,), length (K,));
    steps: (element step (m), halvings of the first one)."""
    step_m, refine = steps
    p = prof.pairs
    n = len(p)
    _, length = p.edge1()
    side_pair = np.repeat(np.arange(n), 2)
    z_end = np.column_stack([np.zeros(n), length]).ravel()
    real_end = prof(z_end, side_pair)[0] - p_min[side_pair]
    e_end = np.minimum(real_end, limit[side_pair] - p_min[side_pair])
    live = (np.abs(z_end - z_apex[side_pair]) > 0) & (e_end > 0)
    if not live.any():
        return None
    e_cap = float(e_end[live].max())
    template = np.concatenate(
        [
            [0.0],
            step_m * 0.5 ** np.arange(refine, 0, -1),
            step_m * np.arange(1, int(np.ceil(e_cap / step_m)) + 1),
        ]
    )
    n_in = np.where(live, np.searchsorted(template, e_end, side="left"), 0)
    sides = np.flatnonzero(live & (n_in > 0))
    counts = n_in[sides] + 1  # boundaries per side: the template's below the end, and the end
    side_of = np.repeat(sides, counts)
    j = np.arange(side_of.size) - np.repeat(np.cumsum(counts) - counts, counts)
    level = np.where(
        j < np.repeat(counts - 1, counts),
        template[np.minimum(j, template.size - 1)],
        e_end[side_of],
    )
    kk = side_pair[side_of]
    zb = _levels(prof, kk, z_apex[kk], z_end[side_of], p_min[kk], level)
    inner = np.flatnonzero(j < np.repeat(counts - 1, counts))  # each boundary but a side's last
    a, b = zb[inner], zb[inner + 1]
    kk = kk[inner]
    dz = np.abs(b - a)
    keep = dz > 0
    return kk[keep], (0.5 * (a + b))[keep], dz[keep]


def _inner(pairs: PairGeometry, source, receiver, outer, limit, steps):
    """Step 3: for each element of edge 1, the first-order elements of edge 2 with
    the source there, times beta_1 and the outer weight (steps: element step (m),
    halvings of the first one).  Returns (a dict of per element arrays: m, n, l,
    amp, x1, x2; the outer element of each)."""
    step_m, refine = steps
    p = pairs
    k, z1, dz1 = outer
    ax1, _ = p.edge1()
    ax2, len2 = p.edge2()
    x1 = p.start1[k] + z1[:, None] * ax1[k]
    m = np.linalg.norm(x1 - source, axis=1)
    r_s, _, z_s = cylindrical(x1, p.start2[k], ax2[k], p.face_dir2[k], p.normal2[k])
    r_r, th_r, z_r = cylindrical(receiver, p.start2[k], ax2[k], p.face_dir2[k], p.normal2[k])
    rows = EdgeRows(
        p.start2[k], ax2[k], len2[k], p.angle2[k], r_s, p.theta21[k], z_s, r_r, th_r, z_r,
        x1, receiver, p.terms2[k],
    )  # fmt: skip
    el, g = integrate_rows(
        rows, step_m=step_m, max_path_m=limit[k] - m, max_excess_m=np.inf, refine=refine
    )
    if g.size == 0:
        return {}, g
    kg = k[g]
    # beta_1: source S, "receiver" the element's point on edge 2 (angle theta_12)
    rS, tS, zS = cylindrical(source, p.start1[kg], ax1[kg], p.face_dir1[kg], p.normal1[kg])
    r21, _, z21 = cylindrical(el.point_m, p.start1[kg], ax1[kg], p.face_dir1[kg], p.normal1[kg])
    n_leg = el.first_leg_m
    with np.errstate(divide="ignore", invalid="ignore"):
        cosh1 = ((z1[g] - zS) * (z1[g] - z21) + m[g] * n_leg) / (rS * r21)
    nu1 = np.pi / p.angle1[kg]
    beta1 = _beta(nu1, tS, p.theta12[kg], cosh1, p.terms1[kg])
    amp = (-nu1 / (4 * np.pi)) * (0.5 * p.sides[kg]) * dz1[g] / m[g] * beta1 * el.amplitude
    arrays = {
        "m": m[g],
        "n": n_leg,
        "l": el.second_leg_m,
        "amp": amp,
        "x1": x1[g],
        "x2": el.point_m,
    }
    return arrays, g


def _beta(nu, th_a, th_b, cosh_eta, terms):
    """Sum (K,) of the four weighted beta terms (as :meth:`Wedge.beta`, per element)."""
    c = np.cosh(nu * np.arccosh(np.maximum(np.nan_to_num(cosh_eta, nan=1.0, posinf=1e300), 1.0)))
    phis = (np.pi + th_a + th_b, np.pi + th_a - th_b, np.pi - th_a + th_b, np.pi - th_a - th_b)
    out = np.zeros(np.shape(cosh_eta))
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, phi in enumerate(phis):
            w = terms[:, i]
            term = np.sin(nu * phi) / (c - np.cos(nu * phi))
            out = out + np.where(w != 0, w * term, 0.0)
    return out


def _farthest(pairs: PairGeometry, source, receiver) -> np.ndarray:
    """The longest path (N,) over the ends of both edges (the path is convex in
    (z1, z2): its largest value on the edges is at a pair of ends)."""
    p = pairs
    best = np.zeros(len(p))
    for a in (p.start1, p.end1):
        for b in (p.start2, p.end2):
            d = (
                np.linalg.norm(a - source, axis=1)
                + np.linalg.norm(a - b, axis=1)
                + np.linalg.norm(receiver - b, axis=1)
            )
            best = np.maximum(best, d)
    return best


def _bins(k, excess, values, receiver, width) -> EdgePairElements:
    """Step 4: elements summed into bins of `width` of excess path length (m), per
    pair k; values: (amplitude, path, point on edge 1, point on edge 2)."""
    if k.size == 0:
        return EdgePairElements.empty()
    amp, path, x1, x2 = values
    b = np.maximum(np.floor(excess / width), 0).astype(np.int64)
    key = k.astype(np.int64) * (int(b.max()) + 1) + b
    used, inv = np.unique(key, return_inverse=True)
    w = np.abs(amp)
    wsum = np.bincount(inv, w)
    wsum = np.where(wsum > 0, wsum, 1.0)

    def mean(x):
        return np.bincount(inv, w * x) / wsum

    total = np.bincount(inv, amp)
    length = mean(path)
    q1 = np.column_stack([mean(x1[:, i]) for i in range(3)])
    q2 = np.column_stack([mean(x2[:, i]) for i in range(3)])
    second = np.linalg.norm(q2 - receiver, axis=1)
    pair = used // (int(b.max()) + 1)
    return EdgePairElements(q1, q2, length - second, second, total, pair)
