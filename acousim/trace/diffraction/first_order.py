"""First-order edge diffraction of the edges in view: which edges a point sees
(rays to five points along each), and their BTM elements with the faces'
reflection factors (and frequency-dependent materials) applied."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.trace.diffraction.btm import (
    EdgeCoordinates,
    EdgeElements,
    ElementLimits,
    Wedge,
    many_edge_elements,
)
from acousim.trace.diffraction.paths import ELEMENT_FIELDS
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.world.edges import EdgeFrame, Edges, convex
from processing.base.kernels import optional_kernel

__all__ = [
    "PROBE_FRACTIONS",
    "edge_bound",
    "edge_frame",
    "edges_in_view",
    "PoseEdges",
    "pose_edges",
    "probe_points",
    "probe_seen",
    "segment_distance",
    "visible",
]

#: where along an edge (fractions of its length) visibility is probed
PROBE_FRACTIONS = np.array([0.02, 0.25, 0.5, 0.75, 0.98])


def segment_distance(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, span: tuple | None = None
) -> np.ndarray:
    """Distance (E,) from a point (3,), or from each of points (E, 3), to segments
    a-b (E, 3); span: (b - a, |b - a|^2) if known (None: found here)."""
    ab, ab2 = (b - a, None) if span is None else span
    ab2 = np.einsum("ij,ij->i", ab, ab) if ab2 is None else ab2
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / ab2, 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=1)


def probe_points(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Points (E, 5, 3) at PROBE_FRACTIONS along edges from start (E, 3) to end."""
    return start[:, None, :] + PROBE_FRACTIONS[None, :, None] * (end - start)[:, None, :]


def visible(caster, origin: np.ndarray, points: np.ndarray, tol: float) -> np.ndarray:
    """(K,) True where the segment from origin (3,) or (K, 3) to points (K, 3) is free:
    no face nearer to the origin than the point by more than `tol` (m; a point on
    a face does not block itself).  Embree's occlusion query (any hit, not the
    first: :meth:`~acousim.trace.world.embree.RayCaster.occluded`)."""
    if caster is None or points.shape[0] == 0:
        return np.ones(points.shape[0], bool)
    o = np.broadcast_to(origin, points.shape)
    d = points - o
    dist = np.linalg.norm(d, axis=1)
    return ~caster.occluded(o, d, dist - tol)


@dataclass(frozen=True, eq=False)
class PoseEdges:
    """What the stage's steps ask of every edge of the geometry for one pose, found
    once (:func:`pose_edges`): the side of the emitter and of the receiver (E,)
    (True: the side of face 2, :meth:`Edges.oriented`), the edges oriented for
    each side and whether that side is a convex wedge, the distances (E,) from
    the emitter and the receiver to each edge (m), and which probe points of each
    edge each sees (:func:`probe_seen`).  Shared by the steps: not to be changed
    (``convex_r`` and ``wedge_r`` may be ``convex_e`` and ``wedge_e``)."""

    side_e: np.ndarray
    side_r: np.ndarray
    wedge_e: Edges
    wedge_r: Edges
    convex_e: np.ndarray
    convex_r: np.ndarray
    dist_e: np.ndarray
    dist_r: np.ndarray
    seen: np.ndarray  # (2, E, 5) int8: -1 not yet cast, 0 blocked, 1 seen


def edge_frame(geometry) -> EdgeFrame:
    """The :class:`EdgeFrame` of the geometry's edges (kept in its memo)."""
    return geometry.kept("edge_frame", lambda: EdgeFrame.of(geometry.edges))


def pose_edges(ctx: StageContext) -> PoseEdges:
    """The pose's :class:`PoseEdges` (found on first use, kept in ``ctx.cache``)."""
    got = ctx.cache.get("edges")
    if got is not None:
        return got
    edges = ctx.geometry.edges
    frame = edge_frame(ctx.geometry)
    side_e = frame.theta(edges, ctx.emitter) > edges.angle_rad
    side_r = frame.theta(edges, ctx.receiver) > edges.angle_rad
    wedge_e = frame.turned(edges, side_e)
    # the emitter and the receiver are mostly on the same side of every edge
    same = np.array_equal(side_e, side_r)
    wedge_r = wedge_e if same else frame.turned(edges, side_r)
    convex_e = convex(wedge_e)
    got = ctx.cache["edges"] = PoseEdges(
        side_e,
        side_r,
        wedge_e,
        wedge_r,
        convex_e,
        convex_e if same else convex(wedge_r),
        segment_distance(ctx.emitter, edges.start_m, edges.end_m, (frame.span, frame.span2)),
        segment_distance(ctx.receiver, edges.start_m, edges.end_m, (frame.span, frame.span2)),
        np.full((2, len(edges), PROBE_FRACTIONS.size), -1, np.int8),
    )
    return got


def probe_seen(ctx: StageContext, *asks: tuple[int, np.ndarray]) -> list[np.ndarray]:
    """For each (which, idx) of `asks`: (len(idx), 5) True where probe point k of
    edge idx[i] (:data:`PROBE_FRACTIONS`) is seen from the emitter (`which` 0) or
    the receiver (1).  One ray each, cast once a pose (kept in :func:`pose_edges`),
    the rays not cast before for all `asks` in one batch."""
    seen = pose_edges(ctx).seen
    casts = [(which, idx[seen[which][idx, 0] < 0]) for which, idx in asks]
    casts = [(which, ask) for which, ask in casts if ask.size]
    if casts:
        edges = ctx.geometry.edges
        probes = ctx.geometry.kept("probes", lambda: probe_points(edges.start_m, edges.end_m))
        points = [np.take(probes, ask, axis=0).reshape(-1, 3) for _, ask in casts]
        origins = [
            np.broadcast_to(ctx.emitter if which == 0 else ctx.receiver, pts.shape)
            for (which, _), pts in zip(casts, points)
        ]
        free = visible(ctx.caster, np.concatenate(origins), np.concatenate(points), ctx.tol)
        for (which, ask), part in zip(
            casts, np.split(free, np.cumsum([p.shape[0] for p in points])[:-1])
        ):
            seen[which][ask] = part.reshape(ask.size, -1)
    return [seen[which][idx] > 0 for which, idx in asks]


def edges_in_view(
    ctx: StageContext, candidates: np.ndarray
) -> tuple[EdgeElements, np.ndarray, np.ndarray | None]:
    """BTM elements of the candidate edges (indices) that form a convex wedge on the
    side of the emitter and the receiver and that both see (at one of five points
    along the edge, at least): (elements, the edge of each, counts or None)."""
    pose = pose_edges(ctx)
    keep, wedge = (pose.side_e == pose.side_r) & pose.convex_e, pose.wedge_e
    idx = np.asarray(candidates, int)
    idx = idx[keep[idx]]
    # the edges' axes and the emitter's and receiver's coordinates about them, found
    # once for the bound and the elements
    known = _coordinates(ctx, wedge, idx, ctx.emitter)
    if idx.size and ctx.options.floor_level > 0:
        # no element of these edges can reach the floor (which lies at or above
        # floor_level): they are left out before their rays and their elements
        need = ctx.options.floor_level
        if ctx.options.min_path_m > 0:
            need = ctx.options.needed(need, _longest(wedge, idx, ctx.emitter, ctx.receiver))
        reach = edge_bound(ctx, wedge, idx, ctx.emitter, known) >= need
        idx, known = idx[reach], known.take(reach)
    if idx.size and ctx.caster is not None:
        from_e, from_r = probe_seen(ctx, (0, idx), (1, idx))
        seen = (from_e & from_r).any(axis=1)
        idx, known = idx[seen], known.take(seen)
    el, local, counts = wedge_elements(ctx, wedge, idx, ctx.emitter, known)
    return el, idx[local], counts


def _longest(wedge: Edges, rows: np.ndarray, emitter: np.ndarray, receiver: np.ndarray):
    """The longest path (R,) from `emitter` over a point of each edge `rows` of
    `wedge` to `receiver` (m): at one of its ends (the length is convex along it)."""
    out = np.zeros(rows.size)
    for end in (wedge.start_m[rows], wedge.end_m[rows]):
        way = np.linalg.norm(end - emitter, axis=1) + np.linalg.norm(end - receiver, axis=1)
        out = np.maximum(out, way)
    return out


def edge_bound(
    ctx: StageContext,
    wedge: Edges,
    rows: np.ndarray,
    source: np.ndarray,
    known: EdgeCoordinates | None = None,
):
    """An upper bound (R,) of |amplitude| of every BTM element of the oriented edges
    `wedge` at `rows` for `source` (3,) and the receiver (those of
    :func:`wedge_elements`, whichever of their terms it computes).

    An element from z_a to z_b has ``|a| = nu/(4 pi) |z_b - z_a| / (m l) |I| /
    |eta_b - eta_a|`` (:mod:`acousim.trace.diffraction.btm`, step 3; taper <= 1), where I
    integrates in eta the terms ``w_i sin(nu phi_i) / (cosh(nu eta) - cos(nu
    phi_i))``; eta is smallest at the apex (clipped to the edge), so ``|I| <=
    |eta_b - eta_a| C`` with the terms at that eta; m, l are at least the distances
    from the source and the receiver to the segment; and the excess path e(z) from
    the apex is convex with ``e'' = r_s^2/m^3 + r_r^2/l^3 >= kappa`` (m, l at most
    the farther end's) and e' at least its value at the apex (0 at an inner apex),
    so an element of excess step at most ``step_m`` spans at most ``sqrt(2 step_m /
    kappa)``, ``step_m / e'(apex)`` and the edge's length.  A term on its boundary
    (the denominator 0) gives an infinite bound.  A 1 % margin covers the rounding
    of the elements computed (the bound reaches 0.9997 of the largest element at
    most, where the element at a clipped apex is short).
    ``tests/acousim/trace/diffraction/test_first_order_bound.py`` checks it against every edge's
    largest
    element (random boxes and plates, corridor poses).  known: the rows'
    :class:`EdgeCoordinates` for `source` and the receiver (None: found here)."""
    if known is None:
        known = _coordinates(ctx, wedge, rows, source)
    length = known.length
    nu = np.pi / wedge.angle_rad[rows]
    (rs, ts, zs), (rr, tr, zr) = known.source, known.receiver
    half = nu[:, None] * (np.pi + np.stack([ts + tr, ts - tr, -ts + tr, -ts - tr], axis=1)) / 2
    R1, R2 = _face_reflections(ctx, wedge, rows)
    w = np.abs(np.column_stack([R2, np.ones(rows.size), np.ones(rows.size), R1]))
    step = ctx.options.step_m
    kernel = optional_kernel("acousim.trace.diffraction.element_kernel")
    if kernel is not None:  # the same numbers compiled
        return _edge_bound_compiled(kernel, known, (length, nu, w), step)
    with np.errstate(divide="ignore", invalid="ignore"):
        z_mid = (rr * zs + rs * zr) / (rs + rr)
        z_apex = np.clip(z_mid, 0.0, length)
        # cosh(eta) at the apex (eta grows away from it): cosh(nu eta) at least that
        a, b = z_apex - zs, z_apex - zr
        m, l_ = np.hypot(rs, a), np.hypot(rr, b)
        arg = ((rs + rr) * (z_apex - z_mid)) ** 2 / ((m * l_ - a * b + rs * rr) * rs * rr)
        cosh_nu = np.cosh(nu * np.arccosh(1 + np.maximum(arg, 0.0)))[:, None]
        # |sin(nu phi)| / (cosh(nu eta) - cos(nu phi)), |cot(nu phi / 2)| at eta = 0
        nu_phi = 2 * half
        gap = cosh_nu - np.cos(nu_phi)
        term = np.where(gap > 1e-12 * cosh_nu, np.abs(np.sin(nu_phi)) / gap, np.inf)
        c = nu / (4 * np.pi) * np.where(w > 0, w * term, 0.0).sum(axis=1)
        # the element's span: the excess path e(z) from the apex is convex with
        # e'' >= kappa and e' >= its slope at the apex (0 at an inner apex)
        slope = np.abs(a / m + b / l_) * (z_apex != z_mid)
        far_s = np.maximum(np.hypot(rs, zs), np.hypot(rs, length - zs))
        far_r = np.maximum(np.hypot(rr, zr), np.hypot(rr, length - zr))
        kappa = (rs / far_s) ** 2 / far_s + (rr / far_r) ** 2 / far_r
        span = np.minimum(np.minimum(length, np.sqrt(2 * step / kappa)), step / slope)
        d = np.hypot(rs, zs - np.clip(zs, 0, length)) * np.hypot(rr, zr - np.clip(zr, 0, length))
        bound = c * span / d
        bound *= 1.01  # a margin for the rounding of the elements computed
    return np.where(np.isnan(bound), np.inf, bound)


def _edge_bound_compiled(kernel, known: EdgeCoordinates, edge, step: float) -> np.ndarray:
    """:func:`edge_bound` by :mod:`.element_kernel` about numpy's arccosh and cosh
    (the same bound bit for bit); edge: (length, nu, |term weights|) of the rows."""
    length, nu, _ = edge
    arg, out = np.empty(length.size), np.empty(length.size)
    kernel.bound_argument(known.source, known.receiver, length, arg)
    cosh_nu = np.cosh(nu * np.arccosh(1 + np.maximum(arg, 0.0)))
    kernel.bound_rest(known.source, known.receiver, edge, cosh_nu, step, out)
    return out


def _coordinates(ctx: StageContext, wedge: Edges, rows: np.ndarray, source) -> EdgeCoordinates:
    """:class:`EdgeCoordinates` of the edges `wedge` at `rows` for `source` (3,) or
    (R, 3) and the receiver."""
    return EdgeCoordinates.of(
        wedge.start_m[rows],
        wedge.end_m[rows],
        wedge.face_dir[rows],
        wedge.normal[rows],
        source,
        ctx.receiver,
    )


def _face_reflections(ctx: StageContext, wedge: Edges, rows: np.ndarray):
    """(R1, R2) (R,): the reflection factors of faces 1 and 2 of the edges at rows
    (a thin plate's one face twice)."""
    refl = np.asarray(ctx.geometry.face_reflection, float)
    f1 = wedge.faces[rows, 0]
    f2 = np.where(wedge.faces[rows, 1] >= 0, wedge.faces[rows, 1], f1)
    return refl[f1], refl[f2]


def wedge_elements(
    ctx: StageContext,
    wedge: Edges,
    rows: np.ndarray,
    source: np.ndarray,
    known: EdgeCoordinates | None = None,
) -> tuple[EdgeElements, np.ndarray, np.ndarray | None]:
    """:func:`many_edge_elements` of the oriented edges `wedge` at `rows` for
    `source` (3,) or one per row (R, 3) and the receiver, each with the reflection
    factors of its two faces (a thin plate's one face twice).

    With the geometry's `face_column` (each face's specular interaction column of a
    frequency-dependent material, -1: a material of single numbers; None: no
    tables) the image term of each such face is an element of its own, which counts
    one interaction in that column (so the path response applies the table: see
    :mod:`acousim.core.materials`), and the rest of the element another.  Returns
    (elements, their rows' local indices (K,), counts (K, C) or None).  known: the
    rows' :class:`EdgeCoordinates` for `source` and the receiver (None: found in
    :func:`many_edge_elements`)."""
    face_column = ctx.geometry.face_column
    R1, R2 = _face_reflections(ctx, wedge, rows)
    every, one = np.arange(rows.size), np.ones(rows.size)

    def part(sel, terms):
        at = rows if sel is every else rows[sel]
        return many_edge_elements(
            Wedge(
                wedge.start_m[at],
                wedge.end_m[at],
                wedge.face_dir[at],
                wedge.normal[at],
                wedge.angle_rad[at],
                terms=terms,
            ),
            source if np.ndim(source) == 1 else source[sel],
            ctx.receiver,
            ElementLimits(step_m=ctx.options.step_m, max_path_m=ctx.options.max_path_m),
            None if known is None else known if sel is every else known.take(sel),
        )

    if face_column is None:
        el, local = part(every, np.column_stack([R2, one, one, R1]))
        return el, local, None
    f1 = wedge.faces[rows, 0]
    c1, c2 = (
        face_column[f1],
        face_column[np.where(wedge.faces[rows, 1] >= 0, wedge.faces[rows, 1], f1)],
    )
    # the element without the image terms of table faces, then each of those alone
    zero = np.zeros(rows.size)
    parts = [
        (
            every,
            np.column_stack([np.where(c2 < 0, R2, 0), one, one, np.where(c1 < 0, R1, 0)]),
            None,
        ),
        (np.flatnonzero(c2 >= 0), np.column_stack([R2, zero, zero, zero]), c2),
        (np.flatnonzero(c1 >= 0), np.column_stack([zero, zero, zero, R1]), c1),
    ]
    return _joined(parts, part, int(np.max(face_column, initial=-1)) + 2)


def _joined(parts, part, n_col: int):
    """The elements of every (rows, terms, table column) part of
    :func:`wedge_elements` (`part` computes one), joined: (elements, rows' local
    indices, counts (K, n_col))."""
    els, locals_, counts = [], [], []
    for sel, terms, column in parts:
        if sel.size == 0:
            continue
        el, local = part(sel, terms[sel])
        c = np.zeros((len(el), n_col), int)
        if column is not None:
            c[np.arange(len(el)), column[sel][local]] = 1
        els.append(el)
        locals_.append(sel[local])
        counts.append(c)
    if not els:  # no edge in view
        return EdgeElements.empty(), np.zeros(0, int), np.zeros((0, n_col), int)
    el = EdgeElements(*(np.concatenate([getattr(e, f) for e in els]) for f in ELEMENT_FIELDS))
    return el, np.concatenate(locals_), np.concatenate(counts)
