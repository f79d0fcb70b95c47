"""Edge-to-edge diffraction in the stage: which pairs of edges, their order chosen
by what they can contribute, and their paths.

Paths emitter -> edge 1 -> edge 2 -> receiver over ordered pairs of edges that
share a plane (:mod:`acousim.trace.diffraction.pairs`).  A pair is a candidate if the
emitter is on a convex side of edge 1 and sees it, the receiver likewise for edge
2 (at one of five points along it), the two edges are not collinear, and the plane
holds a face half way between the edges' mid points (the path runs over the face:
a ray down onto the plane there).  Edge 2 lies on a face of wedge 1: at angle 0
about edge 1 if the shared plane is its face 1, else at its open angle (and likewise
edge 1 about edge 2).  Both rims of a thin plate: the path runs along both of its
sides (``sides = 2``).  Visibility is checked per edge, not per element.  The
pairs that share a plane and are not collinear, the least distance between their
edges, and whether each runs over a face, do not change from pose to pose: they
are found once per geometry (and caster).  A pair none of whose paths can be
within ``max_path_m`` (a lower bound of its length from the edges' distances to
the emitter, the receiver and each other, :func:`_reach`) is left out before its
edges' probe rays (it would have no element, and each pair's paths are its own);
the probe rays are cast last, for the edges of the pairs left.

Order per pair: each candidate's largest path (one bin) is bounded in closed form
(:func:`acousim.trace.diffraction.pair_bound.pair_bound`) and estimated at the pair's shortest
path (:func:`acousim.trace.diffraction.pair_bound.pair_estimate`, with a margin) and by the
pair's integral at a coarse step (:func:`acousim.trace.diffraction.pair_bound.coarse_estimate`,
with a margin); only the pairs whose bound and estimates reach the stage's floor
are integrated at the fine step, the others
keep first order alone (their paths would be dropped by the tracer's energy floor:
what is skipped is measured in BENCHMARKS.md and
``tests/acousim/trace/diffraction/test_pair_selection.py``).  A trace asked only for
the paths at least ``min_path_m`` long (a call heard late in another sonar's window)
also skips the pairs whose every path is shorter and the bins of paths shorter in
the others, where they cannot be the strongest echo (the same paths that long).

With frequency-dependent materials (``face_column``), each wedge's response is split
into the part without the image terms of its table faces and each of those terms
alone; every pair of parts is a set of paths of its own, which counts one
interaction with each table face whose image term it holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.trace.diffraction.btm import DEFAULT_MAX_EXCESS_M
from acousim.trace.diffraction.first_order import (
    edge_frame,
    pose_edges,
    probe_seen,
    segment_distance,
)
from acousim.trace.diffraction.pair_bound import (
    COARSE_MARGIN,
    ESTIMATE_MARGIN,
    coarse_estimate,
    pair_bound,
    pair_estimate,
)
from acousim.trace.diffraction.pair_geometry import _farthest, shortest_paths
from acousim.trace.diffraction.pairs import BIN, PairGeometry, pair_elements, pair_elements_in
from acousim.trace.diffraction.paths import DiffractedPaths, empty_paths
from acousim.trace.diffraction.setup import StageContext

__all__ = ["candidate_pairs", "edge_to_edge"]


def edge_to_edge(ctx: StageContext, floor: float) -> DiffractedPaths:
    """The edge-to-edge paths of the pose; pairs whose bound is below `floor` (a gain
    at the receiver) are skipped unless ``ctx.options.select_pairs`` is False."""
    rows, edge2, columns = candidate_pairs(ctx)
    if len(rows) == 0:
        return empty_paths()
    opt = ctx.options
    step = dict(step_m=_pair_step(opt), bin_m=opt.step_m * BIN, max_path_m=opt.max_path_m)
    if opt.select_pairs and floor > 0:
        keep, live, rows = _selected(ctx, rows, floor)
        edge2, columns = edge2[keep], columns[keep]
        if len(rows) == 0:
            return empty_paths()
        el = pair_elements_in(rows, ctx.emitter, ctx.receiver, live, workers=ctx.caster, **step)
    else:
        el = pair_elements(rows, ctx.emitter, ctx.receiver, **step)
    if len(el) == 0:
        return empty_paths()
    dep = el.first_point_m - ctx.emitter
    dep /= np.maximum(np.linalg.norm(dep, axis=1, keepdims=True), 1e-12)
    counts = None
    if ctx.geometry.face_column is not None:
        n_col = int(np.max(ctx.geometry.face_column, initial=-1)) + 2
        counts = np.zeros((len(el), n_col), int)
        for side in (0, 1):
            c = columns[el.pair, side]
            table = np.flatnonzero(c >= 0)
            counts[table, c[table]] += 1
    return DiffractedPaths(
        el.point_m,
        el.first_leg_m,
        el.amplitude * el.second_leg_m,
        el.point_m,
        dep,
        edge2[el.pair],
        np.full(len(el), 2),
        counts,
    )


def _selected(ctx: StageContext, rows: PairGeometry, floor: float):
    """(indices (K,) of the pairs whose contribution can reach `floor` (a gain at the
    receiver), the bins of path to integrate each in (:func:`pair_elements_in`),
    those rows):
    the closed-form bound
    of their largest path first (rigorous), then the estimate of it
    (:func:`pair_estimate`) times :data:`ESTIMATE_MARGIN`, then the coarse
    integral's estimates (:func:`coarse_estimate`) times :data:`COARSE_MARGIN`."""
    opt = ctx.options
    bound = pair_bound(
        rows,
        ctx.emitter,
        ctx.receiver,
        max_excess_m=DEFAULT_MAX_EXCESS_M,
        max_path_m=opt.max_path_m,
        bin_m=opt.step_m * BIN,
    )
    need = floor
    if opt.min_path_m > 0:  # pairs whose paths are all too short: only if one could lead
        need = opt.needed(floor, _farthest(rows, ctx.emitter, ctx.receiver))
    keep = np.flatnonzero(bound >= need)
    if keep.size:
        # one set of rows from here on: their shortest paths found once (the
        # estimate, the coarse and the fine pass ask for them)
        sub = rows.take(keep)
        est = pair_estimate(sub, ctx.emitter, ctx.receiver, bin_m=opt.step_m * BIN)
        ok = ESTIMATE_MARGIN * est >= floor
        keep, sub = keep[ok], sub.take(ok)
    if keep.size == 0:
        return keep, (np.zeros((0, 1), bool), 1.0), rows.take(keep)
    est, (live, width) = coarse_estimate(
        sub,
        ctx.emitter,
        ctx.receiver,
        step_m=_pair_step(opt),
        bin_m=opt.step_m * BIN,
        floor=floor,
        max_path_m=opt.max_path_m,
        workers=ctx.caster,
    )
    ok = COARSE_MARGIN * est >= floor
    keep, live, sub = keep[ok], live[ok], sub.take(ok)
    if opt.min_path_m > 0:
        keep, live, sub = _reaching_bins(ctx, floor, (keep, live, sub), bound[keep], width)
    return keep, (live, width), sub


def _reaching_bins(ctx: StageContext, floor: float, selected, bound: np.ndarray, width: float):
    """`selected` (the pairs kept, their live bins (K, B) of `width` (m), their rows)
    without the bins whose every path is shorter than ``min_path_m`` in the pairs
    whose `bound` (K,) is under the strongest echo found before the stage (their
    paths are dropped after the trace, and none of them can change the floors or
    the strongest echo: :meth:`DiffractionOptions.needed`), and without the pairs
    left with no live bin.  The other bins are integrated as they would be (each
    bin's elements are its own: :func:`pair_elements_in`)."""
    keep, live, sub = selected
    top = ctx.options.lead(floor)
    if top is None or keep.size == 0:
        return selected
    _, p_min = shortest_paths(sub, ctx.emitter, ctx.receiver)
    # bin b holds the excess [b w, (b + 1) w) beyond the shortest path (the fine
    # bins over it likewise: its elements' paths, and their mean, lie there)
    top_of_bin = p_min[:, None] + width * np.arange(1, live.shape[1] + 1)
    short = top_of_bin < ctx.options.min_path_m * (1 - 1e-12)
    short[:, -1] = False  # the last bin also stands for any excess beyond (fine_live)
    live = live & ~(short & (bound < top)[:, None])
    some = live.any(axis=1)
    return keep[some], live[some], sub.take(some)


def _pair_step(opt) -> float:
    return opt.step_m if opt.pair_step_m is None else opt.pair_step_m


def _pairs_in_view(ctx: StageContext) -> np.ndarray:
    """The pairs (indices into the table, ascending) whose edge 1 is convex on the
    emitter's side and edge 2 on the receiver's, both within reach and the pair too
    (:func:`_reach`), whose path runs over a face (:meth:`_PairTable.over_a_face`)
    and whose edge 1 the emitter sees and edge 2 the receiver (at one of the probe
    points: rays cast last, for the edges of the pairs left only)."""
    pose = pose_edges(ctx)
    near = _reach(ctx, pose.dist_e + pose.dist_r)
    keep1 = pose.convex_e & (pose.dist_e < ctx.options.max_path_m) & near
    keep2 = pose.convex_r & (pose.dist_r < ctx.options.max_path_m) & near
    table = _pair_table(ctx)
    at = table.of_edges(np.flatnonzero(keep1))  # the pairs of the edges 1 kept
    i, j = table.i[at], table.j[at]
    near = keep2[j] & _reach(ctx, pose.dist_e[i] + table.gap[at] + pose.dist_r[j])
    at = at[near]
    at = at[table.over_a_face(ctx, pose.wedge_e, at)]
    if ctx.caster is not None and at.size:  # seen at one of the probe points
        i, j = table.i[at], table.j[at]
        keep1[:], keep2[:] = False, False
        keep1[i], keep2[j] = True, True  # the edges of the pairs left
        idx1, idx2 = np.flatnonzero(keep1), np.flatnonzero(keep2)
        seen1, seen2 = probe_seen(ctx, (0, idx1), (1, idx2))
        keep1[idx1], keep2[idx2] = seen1.any(axis=1), seen2.any(axis=1)
        at = at[keep1[i] & keep2[j]]
    return at


#: a pair of edges is left out where every path over it is longer than
#: ``max_path_m`` by more than this (m): far more than the rounding of the lengths
#: compared, so that none of its paths is within ``max_path_m`` (it would have no
#: element, and it changes none of the others': each pair's integral is its own)
REACH_SLACK_M = 1e-6


def _reach(ctx: StageContext, shortest_m: np.ndarray) -> np.ndarray:
    """(N,) True where a lower bound `shortest_m` (N,) (m) of the paths over an edge
    or a pair of edges is within ``max_path_m`` (and :data:`REACH_SLACK_M`): a path
    from the emitter over a point x of an edge (and on to the receiver, via another
    edge or not) is at least |S - x| + |x - R| (the triangle inequality), at least
    the sum of the edge's distances from the emitter and from the receiver; over a
    pair, at least the distance of the emitter from edge 1, the edges' distance
    from each other and the receiver's distance from edge 2."""
    return shortest_m <= ctx.options.max_path_m + REACH_SLACK_M


def candidate_pairs(ctx: StageContext) -> tuple[PairGeometry, np.ndarray, np.ndarray]:
    """Every candidate pair (see the module docstring) within reach (a pair none of
    whose paths is within ``max_path_m`` has no element: :func:`_reach`), one row
    per pair of parts: (the rows, edge 2's index (N,), the table column of each
    part (N, 2), -1: none)."""
    at = _pairs_in_view(ctx)
    table, pose = _pair_table(ctx), pose_edges(ctx)
    w1, w2 = pose.wedge_e, pose.wedge_r
    i, j, shared = table.i[at], table.j[at], table.shared[at]
    plane = np.asarray(ctx.geometry.face_plane, int)
    edges = ctx.geometry.edges
    th12 = np.where(plane[w1.faces[i, 0]] == shared, 0.0, w1.angle_rad[i])
    th21 = np.where(plane[w2.faces[j, 0]] == shared, 0.0, w2.angle_rad[j])
    rim = edges.faces[:, 1] < 0
    sides = np.where(rim[i] & rim[j], 2, 1)
    # the parts of each wedge (its table of parts either way round, per geometry)
    terms, column, exists = _part_table(ctx)
    s1, s2 = pose.side_e[i].astype(np.intp), pose.side_r[j].astype(np.intp)
    if ctx.geometry.face_column is None:  # one part a wedge: a row a pair
        q, t1, t2 = np.arange(i.size), terms[s1, i, 0], terms[s2, j, 0]
        columns = np.full((i.size, 2), -1)
    else:  # every pair of parts: a row
        o1, o2 = exists[s1, i], exists[s2, j]
        q, u, v = np.nonzero(o1[:, :, None] & o2[:, None, :])
        t1, t2 = terms[s1[q], i[q], u], terms[s2[q], j[q], v]
        columns = np.column_stack([column[s1[q], i[q], u], column[s2[q], j[q], v]])
    iq, jq = i[q], j[q]
    frame = edge_frame(ctx.geometry)  # each edge's axis and length, found once
    axis, length = frame.axis, frame.length

    def at_(x, k):  # rows of x (np.take gathers them much faster than indexing does)
        return np.take(x, k, axis=0)

    rows = PairGeometry(
        at_(w1.start_m, iq), at_(w1.end_m, iq), at_(w2.start_m, jq), at_(w2.end_m, jq),
        at_(w1.face_dir, iq), at_(w1.normal, iq), at_(w2.face_dir, jq), at_(w2.normal, jq),
        w1.angle_rad[iq], w2.angle_rad[jq], th12[q], th21[q], t1, t2, sides[q],
    ).with_axes((at_(axis, iq), length[iq]), (at_(axis, jq), length[jq]))  # fmt: skip
    return rows, jq, columns


def _part_table(ctx: StageContext):
    """:func:`_parts` of every edge of the geometry as listed (index 0) and turned
    (1): terms (2, E, 3, 4), table column (2, E, 3), which parts exist (2, E, 3)
    (per geometry, kept in its memo)."""

    def build():
        edges, frame = ctx.geometry.edges, edge_frame(ctx.geometry)
        every = np.arange(len(edges))
        both = [
            _parts(ctx, frame.turned(edges, np.full(every.size, f, bool)), every) for f in (0, 1)
        ]
        return tuple(np.stack(x) for x in zip(*both))

    return ctx.geometry.kept("edge_parts", build)


@dataclass(frozen=True, eq=False)
class _PairTable:
    """What does not change from pose to pose: the ordered pairs of edges (i, j)
    that share a plane (`shared`, edge i's first plane where both of its planes
    are shared) and are not collinear, sorted by (i, j); the least distance
    between the two edges of each (`gap`); and whether the path of each runs over
    a face of that plane (:func:`_over_a_face`; found for a pair when a pose first
    needs it: a pair whose edge 1 is convex on the emitter's side and edge 2 on the
    receiver's has one orientation (a wedge is convex on one side only; a thin
    sheet's rim never turns), so the answer is the pose's own)."""

    i: np.ndarray
    j: np.ndarray
    shared: np.ndarray
    caster: object
    tol: float
    known: np.ndarray  # (K,) int8: -1 not yet asked, 0 no, 1 yes
    #: (K,) the least distance between the two edges of each pair (m; a lower
    #: bound of it, :func:`_segments_apart`)
    gap: np.ndarray
    #: (E + 1,) the pairs of edge e (as edge 1) are ``first[e]`` to ``first[e + 1]``
    first: np.ndarray

    def of_edges(self, edges: np.ndarray) -> np.ndarray:
        """The pairs (indices, ascending) whose edge 1 is one of `edges` (indices,
        ascending)."""
        lo, size = self.first[edges], np.diff(self.first)[edges]
        return np.repeat(lo, size) + _ranges(size)

    def over_a_face(self, ctx: StageContext, w1, at: np.ndarray) -> np.ndarray:
        """(len(at),) :func:`_over_a_face` of the pairs `at` (indices into the table)."""
        ask = at[self.known[at] < 0]
        if ask.size:
            over = _over_a_face(ctx, w1, self.i[ask], self.j[ask], self.shared[ask])
            self.known[ask] = over
        return self.known[at] > 0


def _pair_table(ctx: StageContext) -> _PairTable:
    """The geometry's :class:`_PairTable` for this caster and tolerance (built on
    first use, kept in the geometry's memo: it goes with the geometry)."""
    with ctx.geometry.memo_lock:
        table = ctx.geometry.memo.get("pair_table")
        if table is None or table.caster is not ctx.caster or table.tol != ctx.tol:
            table = _new_pair_table(ctx)
            ctx.geometry.memo["pair_table"] = table
    return table


def _new_pair_table(ctx: StageContext) -> _PairTable:
    """Build :class:`_PairTable` (see there)."""
    edges = ctx.geometry.edges
    plane = np.asarray(ctx.geometry.face_plane, int)
    p_a = plane[edges.faces[:, 0]]
    p_b = np.where(edges.faces[:, 1] >= 0, plane[np.maximum(edges.faces[:, 1], 0)], p_a)
    # every ordered pair of distinct edges with a plane in common
    owner = np.concatenate([np.arange(len(edges)), np.flatnonzero(p_b != p_a)])
    on = np.concatenate([p_a, p_b[p_b != p_a]])
    order = np.argsort(on, kind="stable")
    owner, on = owner[order], on[order]
    start = np.searchsorted(on, on, side="left")
    size = np.searchsorted(on, on, side="right") - start
    first = np.repeat(owner, size)
    second = owner[np.repeat(start, size) + _ranges(size)]
    key = np.unique(first * len(edges) + second)
    i, j = key // len(edges), key % len(edges)
    ok = i != j
    i, j = i[ok], j[ok]
    shared = np.where((p_a[i] == p_a[j]) | (p_a[i] == p_b[j]), p_a[i], p_b[i])
    good = _not_collinear(edges, i, j, ctx.tol)
    i, j, shared = i[good], j[good], shared[good]
    known = np.full(i.size, -1, np.int8)
    gap = _segments_apart(edges.start_m, edges.end_m, i, j)
    first = np.searchsorted(i, np.arange(len(edges) + 1))  # i is sorted
    return _PairTable(i, j, shared, ctx.caster, ctx.tol, known, gap, first)


def _segments_apart(start: np.ndarray, end: np.ndarray, i: np.ndarray, j: np.ndarray):
    """(K,) a lower bound of the least distance (m) between segments i and j (start,
    end (E, 3) each).  The least distance is that from an end of one to the other
    segment, or that between the lines' nearest points where both lie within the
    segments; the latter is found where the segments' angle has a sine above 1e-3
    (well conditioned).  Below, the ends' distance less the segments' length L times
    |u1 -+ u2| (unit axes): sliding both points of the nearest pair along their
    segments by as much (at most L) until one reaches an end moves them apart by at
    most that.  Less 1e-9 of the segments' size (rounding), at least 0."""
    a1, b1, a2, b2 = start[i], end[i], start[j], end[j]
    best = np.minimum(segment_distance(a1, a2, b2), segment_distance(b1, a2, b2))
    best = np.minimum(best, np.minimum(segment_distance(a2, a1, b1), segment_distance(b2, a1, b1)))
    d1, d2, r = b1 - a1, b2 - a2, a1 - a2
    aa, ee, bb = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    cc, ff = _dot(d1, r), _dot(d2, r)
    den = aa * ee - bb * bb
    skew = den > 1e-6 * aa * ee
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (bb * ff - cc * ee) / den
        t = (aa * ff - bb * cc) / den
        u1 = d1 / np.sqrt(np.maximum(aa, 1e-300))[:, None]
        u2 = d2 / np.sqrt(np.maximum(ee, 1e-300))[:, None]
    inside = skew & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    s, t = np.where(inside, s, 0.0), np.where(inside, t, 0.0)
    between = np.linalg.norm(r + s[:, None] * d1 - t[:, None] * d2, axis=1)
    best = np.where(inside, np.minimum(best, between), best)
    turn = np.minimum(np.linalg.norm(u1 - u2, axis=1), np.linalg.norm(u1 + u2, axis=1))
    slide = np.sqrt(np.maximum(aa, ee)) * turn
    best = np.where(skew, best, best - slide)
    size = np.sqrt(np.maximum(aa, ee)) + np.linalg.norm(r, axis=1)
    return np.maximum(best - 1e-9 * size, 0.0)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _not_collinear(w1, i, j, tol) -> np.ndarray:
    """(N,) True where an end of edge j lies off the line of edge i by more than tol."""
    axis = w1.end_m[i] - w1.start_m[i]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    off = 0.0
    for end in (w1.start_m[j], w1.end_m[j]):
        d = end - w1.start_m[i]
        r = np.linalg.norm(d - np.einsum("ij,ij->i", d, axis)[:, None] * axis, axis=1)
        off = np.maximum(off, r)
    return off > tol


def _ranges(size: np.ndarray) -> np.ndarray:
    """0 .. size[k] - 1 for each k, one after the other."""
    return np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)


def _over_a_face(ctx: StageContext, w1, i, j, shared) -> np.ndarray:
    """(N,) True where a ray down onto the shared plane, half way between the two
    edges' mid points, meets a face of that plane (the path runs over a face)."""
    if ctx.caster is None or i.size == 0:
        return np.ones(i.size, bool)
    plane = np.asarray(ctx.geometry.face_plane, int)
    mid = 0.25 * (w1.start_m[i] + w1.end_m[i] + w1.start_m[j] + w1.end_m[j])
    on_first = plane[w1.faces[i, 0]] == shared
    # face 1's normal points into the air; face 2's air side is the other way from
    # the direction of growing angle there
    turn = np.cross(w1.face_dir[i], w1.normal[i])
    up = np.where(on_first[:, None], w1.normal[i], -np.cross(turn, w1.other_dir[i]))
    lift = 10 * ctx.nudge + ctx.tol
    t, hit = ctx.caster.first_hit(mid + lift * up, -up, np.full(i.size, 2 * lift))
    return (
        (hit >= 0)
        & (plane[np.maximum(hit, 0)] == shared)
        & (np.abs(t - lift) <= ctx.tol + ctx.nudge)
    )


def _parts(ctx: StageContext, w, idx):
    """The parts of wedges idx of oriented edges w: (terms (N, 3, 4), table column
    (N, 3), which parts exist (N, 3)).  Part 0: the whole wedge, or without the image
    terms of its table faces; parts 1 and 2: the image term of face 2 and of face 1
    alone where that face has a table (see the module docstring); they sum to the
    whole wedge (beta is linear in its term weights)."""
    refl = np.asarray(ctx.geometry.face_reflection, float)
    f1 = w.faces[idx, 0]
    f2 = np.where(w.faces[idx, 1] >= 0, w.faces[idx, 1], f1)
    r1, r2 = refl[f1], refl[f2]
    one, zero = np.ones(idx.size), np.zeros(idx.size)
    column = ctx.geometry.face_column
    c1 = np.full(idx.size, -1) if column is None else np.asarray(column)[f1]
    c2 = np.full(idx.size, -1) if column is None else np.asarray(column)[f2]
    terms = np.stack(
        [
            np.column_stack([np.where(c2 < 0, r2, 0), one, one, np.where(c1 < 0, r1, 0)]),
            np.column_stack([r2, zero, zero, zero]),
            np.column_stack([zero, zero, zero, r1]),
        ],
        axis=1,
    )
    columns = np.column_stack([np.full(idx.size, -1), c2, c1])
    exists = np.column_stack([one > 0, c2 >= 0, c1 >= 0])
    return terms, columns, exists
