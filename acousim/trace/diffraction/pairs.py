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
   :func:`acousim.trace.diffraction.btm.integrate_rows` with the source at z1 (on a face plane of
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

import numpy as np

from acousim.trace.diffraction.btm import (
    DEFAULT_LIMITS,
    DEFAULT_MAX_EXCESS_M,
    DEFAULT_STEP_M,
    EdgeRows,
    ElementLimits,
    Wedge,
    integrate_rows,
)
from acousim.trace.diffraction.pair_geometry import (
    EdgePairElements,
    PairGeometry,
    _farthest,
    _levels,
    _Profile,
    cylindrical,
    shortest_paths,
)
from acousim.trace.diffraction.pairs_compiled import compiled_elements, fine_live
from processing.base.kernels import optional_kernel

#: bins per element step (each bin is BIN * step_m of path length)
BIN = 0.25
#: the first step next to edge 1's apex is subdivided by halving this many times,
#: and edge 2's (for each element of edge 1) INNER_REFINE times, as first order
#: (each element of edge 1 is a whole integral over edge 2: 3 and 5 halvings take
#: a third fewer elements and keep the turned box's error against a 0.05 mm step,
#: 2.0 %, but its reciprocity error at 1 mm grows from 2.2 to 4.2 %)
OUTER_REFINE = 8
INNER_REFINE = 8
REFINE = (OUTER_REFINE, INNER_REFINE)

__all__ = [
    "EdgePairElements",
    "PairGeometry",
    "Wedge",
    "edge_pair_elements",
    "pair_elements",
    "pair_elements_in",
    "shortest_paths",
]


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
    limits = (step_m, max_path_m, max_excess_m, bin_m or step_m * BIN, REFINE)
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
    workers=None,
) -> EdgePairElements:
    """:func:`pair_elements` (excess kept :data:`DEFAULT_MAX_EXCESS_M`), only the
    bins of excess path within `live`: (mask (N, B), width w (m)), bin b of pair k
    the excess [b w, (b + 1) w) beyond the pair's shortest path.  The bins given are
    those of the whole integral (the compiled kernel skips an element of another
    bin before evaluating its beta terms).  workers: the threads to share the pairs
    among (:func:`acousim.trace.diffraction.pairs_compiled.compiled_elements`; None: this one)."""
    limits = (step_m, max_path_m, DEFAULT_MAX_EXCESS_M, bin_m or step_m * BIN, REFINE)
    return _elements(pairs, source, receiver, limits, True, live, workers)


def _elements(pairs: PairGeometry, source, receiver, limits, use_kernel, live=None, workers=None):
    """:func:`pair_elements` (:class:`EdgePairElements`); limits: (step, longest path,
    excess kept, bin width) in metres and the halvings of the first step next to
    each apex (in both edges); live: as :func:`pair_elements_in` (None: all);
    workers: the compiled kernel's (:func:`pair_elements_in`)."""
    source, receiver = np.asarray(source, float), np.asarray(receiver, float)
    step_m, max_path_m, max_excess_m, bin_m, refine = limits
    if len(pairs) == 0 or step_m <= 0:
        return EdgePairElements.empty()
    kernel = optional_kernel("acousim.trace.diffraction.pair_kernel") if use_kernel else None
    if kernel is not None and np.isfinite(max_excess_m):
        return compiled_elements(kernel, pairs, source, receiver, (limits, live), workers)
    z_apex, p_min = shortest_paths(pairs, source, receiver)
    limit = np.minimum(p_min + max_excess_m, max_path_m)
    outer = _outer(_Profile(pairs, source, receiver), z_apex, p_min, limit, (step_m, refine[0]))
    if outer is None:
        return EdgePairElements.empty()
    k, z1, dz1 = outer
    el, g = _inner(pairs, source, receiver, (k, z1, dz1), limit, (step_m, refine[1]))
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
