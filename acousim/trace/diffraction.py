"""The edge-diffraction stage: first-order BTM diffraction of every edge in view
(and, as an option, second order: edge to edge).

Input: the scene's diffracting edges (:mod:`acousim.trace.edges`), the ray caster,
the emitter and the receiver (the array centre).  Output: one point reflector per
edge element (:mod:`acousim.trace.btm`) in the tracer's path form, so synthesis,
air absorption, directivity and noise apply unchanged.

Steps of :func:`diffract`:

1. Cull edges that cannot contribute within ``max_path_m`` (shortest path from the
   emitter over the edge's segment to the receiver is longer).
2. Keep the edges whose side holding the emitter and the receiver is a convex wedge
   (:meth:`Edges.oriented`) and that both see at one of five points along the edge
   (rays); their BTM elements for the emitter and the receiver, all edges in one
   vectorised pass (edge-element step ``step_m``), with the faces' reflection
   factors applied to the terms of their images.
3. Optionally (``planes`` given) the same with the emitter replaced by its image
   in each planar face of the scene (a specular reflection before the edge) and the
   receiver by its image (a reflection after the edge), all (edge, plane) pairs in
   one pass; a pair is tried if, at one of five points along the edge, the other
   end sees it and the reflection lands on a face of the plane; an element is kept
   only if its own reflection point lies on a face of the plane (a ray).
4. Visibility: an element is kept only if nothing lies between it and the emitter
   (or the reflection point) and between it and the receiver: one ray each way
   through the Embree scene, blocked if it meets a face before the element (by more
   than the caster's ``tolerance_m``: the element lies on its own faces).

:func:`edge_diffraction` is the tracer's stage 3: :func:`diffract` on the
:class:`DiffractingGeometry` of a world (built once per world), its paths in the
tracer's form with kind ``"diffraction"``.

Valid where the edges are straight and their faces nearly rigid (BTM is exact for
an infinite rigid wedge; a finite edge is integrated over its length).  Not
modelled: edge to edge between edges that share no plane, third order, edge to edge
with reflections; diffraction of the diffuse and curved-surface parts.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from .btm import DEFAULT_STEP_M, EdgeElements, Wedge, edge_pair_elements, many_edge_elements
from .edges import Edges, find_edges, triangles_mesh
from .embree import DISTANCE_TOLERANCE, RAY_OFFSET
from .geometry import World
from .paths import KIND, TracedPaths

__all__ = [
    "DiffractedPaths",
    "DiffractingGeometry",
    "diffract",
    "edge_diffraction",
    "DEFAULT_STEP_M",
]


@dataclass(frozen=True, eq=False)
class DiffractedPaths:
    """N diffraction paths in the tracer's path form (world frame, metres).

    anchor_m (N, 3): the element's point on the edge (or, for a reflection after
    the edge, its image); first_leg_m (N,): emitter (or its image) to the element;
    strength (N,): signed, the gain at a microphone p is ``strength / |anchor - p|``;
    position_m (N, 3): the element's point on the edge; departure (N, 3): unit
    direction leaving the emitter; edge (N,): index into the Edges; order (N,):
    interactions (1: the edge alone, 2: a reflection and the edge); counts (N, K):
    the path's interactions with frequency-dependent materials (a face's image
    term, a reflection before or after the edge; K = 0 without tables).
    """

    anchor_m: np.ndarray
    first_leg_m: np.ndarray
    strength: np.ndarray
    position_m: np.ndarray
    departure: np.ndarray
    edge: np.ndarray
    order: np.ndarray
    counts: np.ndarray | None = None

    def __post_init__(self):
        if self.counts is None:
            object.__setattr__(self, "counts", np.zeros((self.strength.size, 0), int))

    def __len__(self) -> int:
        return self.strength.size


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (E,) from a point (3,) to segments a-b (E, 3)."""
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=1)


def _elements(
    edges: Edges,
    candidates: np.ndarray,
    source: np.ndarray,
    receiver: np.ndarray,
    face_reflection: np.ndarray,
    step_m: float,
    max_path_m: float,
    caster,
    tol: float,
    seen_from: tuple[np.ndarray, ...],
    face_column: np.ndarray | None = None,
) -> tuple[EdgeElements, np.ndarray, np.ndarray | None]:
    """BTM elements of the candidate edges (indices) that form a convex wedge on the
    side of source and receiver and that every point of `seen_from` sees (at one of
    five points along the edge, at least)."""
    keep, wedge = edges.oriented(source, receiver)
    idx = np.asarray(candidates, int)
    idx = idx[keep[idx]]
    if idx.size and caster is not None and seen_from:
        pts = _probe_points(edges.start_m[idx], edges.end_m[idx]).reshape(-1, 3)
        seen = np.ones(pts.shape[0], bool)
        for p in seen_from:
            seen &= _visible(caster, p, pts, tol)
        idx = idx[seen.reshape(-1, PROBE_FRACTIONS.size).any(axis=1)]
    el, local, counts = _wedge_elements(
        wedge, idx, source, receiver, face_reflection, step_m, max_path_m, face_column
    )
    return el, idx[local], counts


def _wedge_elements(
    wedge, rows, source, receiver, face_reflection, step_m, max_path_m, face_column=None
):
    """:func:`many_edge_elements` of the oriented edges `wedge` at `rows`, each with
    the reflection factors of its two faces (a thin plate's one face twice).

    With `face_column` (F,) (each face's specular interaction column of a
    frequency-dependent material, -1: a material of single numbers; None: no
    tables) the image term of each such face is an element of its own, which counts
    one interaction in that column (so the path response applies the table: see
    :mod:`acousim.core.materials`), and the rest of the element another.  Returns
    (elements, their rows' local indices (K,), counts (K, C) or None)."""
    refl = np.asarray(face_reflection, float)
    f1 = wedge.faces[rows, 0]
    f2 = np.where(wedge.faces[rows, 1] >= 0, wedge.faces[rows, 1], f1)
    R1, R2 = refl[f1], refl[f2]

    def part(sel, terms):
        return many_edge_elements(
            wedge.start_m[rows[sel]],
            wedge.end_m[rows[sel]],
            wedge.face_dir[rows[sel]],
            wedge.normal[rows[sel]],
            wedge.angle_rad[rows[sel]],
            source if np.ndim(source) == 1 else source[sel],
            receiver,
            step_m,
            max_path_m,
            terms=terms,
        )

    every = np.arange(rows.size)
    one = np.ones(rows.size)
    if face_column is None:
        el, local = part(every, np.column_stack([R2, one, one, R1]))
        return el, local, None
    c1, c2 = face_column[f1], face_column[f2]
    # the element without the image terms of table faces, then each of those alone
    parts = [
        (every, np.column_stack([np.where(c2 < 0, R2, 0), one, one, np.where(c1 < 0, R1, 0)]), None)
    ]
    zero = np.zeros(rows.size)
    parts.append((np.flatnonzero(c2 >= 0), np.column_stack([R2, zero, zero, zero]), c2))
    parts.append((np.flatnonzero(c1 >= 0), np.column_stack([zero, zero, zero, R1]), c1))
    els, locals_, counts = [], [], []
    n_col = int(np.max(face_column, initial=-1)) + 2  # columns come in pairs
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
    el = EdgeElements(*(np.concatenate([getattr(e, f) for e in els]) for f in _FIELDS))
    return el, np.concatenate(locals_), np.concatenate(counts)


#: where along an edge (fractions of its length) visibility is probed
PROBE_FRACTIONS = np.array([0.02, 0.25, 0.5, 0.75, 0.98])


def _probe_points(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Points (E, 5, 3) at PROBE_FRACTIONS along edges from start (E, 3) to end."""
    return start[:, None, :] + PROBE_FRACTIONS[None, :, None] * (end - start)[:, None, :]


def _visible(caster, origin: np.ndarray, points: np.ndarray, tol: float) -> np.ndarray:
    """(K,) True where the segment from origin (3,) or (K, 3) to points (K, 3) is free."""
    if caster is None or points.shape[0] == 0:
        return np.ones(points.shape[0], bool)
    o = np.broadcast_to(origin, points.shape)
    d = points - o
    dist = np.linalg.norm(d, axis=1)
    t, f = caster.first_hit(o, d, dist + tol)
    return ~((f >= 0) & (t < dist - tol))


def diffract(
    edges: Edges,
    caster,
    emitter: np.ndarray,
    receiver: np.ndarray,
    max_path_m: float,
    face_reflection: np.ndarray,
    step_m: float = DEFAULT_STEP_M,
    planes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    floor_db: float = -np.inf,
    order: int = 1,
    face_plane: np.ndarray | None = None,
    floor_level: float = 0.0,
    face_column: np.ndarray | None = None,
    plane_column: np.ndarray | None = None,
) -> DiffractedPaths:
    """First-order edge diffraction, and second order if asked (see the module
    docstring).

    edges: the scene's diffracting edges; caster: the RayCaster (None: no occlusion);
    emitter, receiver (3,); max_path_m: longest path kept; face_reflection (F,):
    pressure reflection factor per face; step_m: edge-element step (excess path
    length, m); planes: (normal (P, 3), offset (P,), reflection (P,)) of the planes
    to combine with one specular reflection before or after the edge (None: none);
    floor_db: elements weaker than this relative to the strongest first-order one
    are dropped before their visibility is checked (pass the tracer's energy floor:
    its strongest echo is at least as strong, so nothing it would keep is lost);
    order: 1, or 2 to add edge-to-edge diffraction over pairs of edges that share a
    plane (``face_plane`` (F,): the plane id of each face, needed then).
    floor_level: elements weaker than this gain at the receiver are dropped too,
    before their visibility is checked (the tracer passes its energy floor under the
    strongest echo it has found before this stage: elements below it would be
    dropped by the floor at the end anyway).  face_column (F,) and plane_column
    (P,): the specular interaction column of each face's and each plane's material
    if it is a table over frequency (-1: single numbers; None: no tables): such a
    face's image term, and such a plane's reflection before or after the edge,
    count in the paths' interactions (edge to edge too: :func:`_edge_to_edge`).
    """
    emitter, receiver = np.asarray(emitter, float), np.asarray(receiver, float)
    if len(edges) == 0:
        return _empty()
    r_edge = np.asarray(face_reflection, float)
    # distances along a ray agree within tol; a ray leaves a surface this far off it
    tol = caster.tolerance_m if caster is not None else sum(DISTANCE_TOLERANCE)
    nudge = caster.offset_m if caster is not None else sum(RAY_OFFSET)
    out = []
    # 1-2. direct legs
    near = _segment_distance(emitter, edges.start_m, edges.end_m) + _segment_distance(
        receiver, edges.start_m, edges.end_m
    )
    idx = np.flatnonzero(near <= max_path_m)
    el, owner, counts = _elements(
        edges,
        idx,
        emitter,
        receiver,
        r_edge,
        step_m,
        max_path_m,
        caster,
        tol,
        (emitter, receiver),
        face_column,
    )
    # 4. visibility both ways (of the elements above the floor)
    floor = max(np.abs(el.amplitude).max(initial=0.0) * 10 ** (floor_db / 20), floor_level)
    strong = np.abs(el.amplitude) >= floor
    ok = strong.copy()
    ok[strong] = _visible(caster, emitter, el.point_m[strong], tol) & _visible(
        caster, receiver, el.point_m[strong], tol
    )
    out.append(_paths(el, owner, ok, emitter, el.point_m, np.ones(len(el)), 1, counts))
    # 5. edge to edge
    if order >= 2 and face_plane is not None:
        out.append(
            _edge_to_edge(
                edges,
                caster,
                emitter,
                receiver,
                face_plane,
                r_edge,
                step_m,
                max_path_m,
                tol,
                nudge,
                face_column,
            )
        )
    # 3. one reflection before or after the edge
    if planes is not None:
        for before in (True, False):
            out.append(
                _reflected(
                    edges,
                    caster,
                    emitter,
                    receiver,
                    planes,
                    before,
                    r_edge,
                    step_m,
                    max_path_m,
                    tol,
                    nudge,
                    floor,
                    face_column,
                    plane_column,
                )
            )
    out = [p for p in out if len(p)]
    if not out:
        return _empty()
    return _concatenate(out)


def _concatenate(parts: list[DiffractedPaths]) -> DiffractedPaths:
    """The paths of `parts` one after the other (their counts padded to the widest)."""
    k = max(p.counts.shape[1] for p in parts)
    counts = np.concatenate([np.pad(p.counts, ((0, 0), (0, k - p.counts.shape[1]))) for p in parts])
    fields = (np.concatenate([getattr(p, f) for p in parts]) for f in _PATH_FIELDS)
    return DiffractedPaths(*fields, counts)


def _reflected(
    edges,
    caster,
    emitter,
    receiver,
    planes,
    before,
    face_reflection,
    step_m,
    max_path_m,
    tol,
    nudge,
    floor,
    face_column=None,
    plane_column=None,
) -> DiffractedPaths:
    """All paths emitter -> plane -> edge -> receiver (before) or emitter -> edge ->
    plane -> receiver (after) at once, for every plane and edge: the reflecting leg's
    real end (emitter before, receiver after) is replaced by its image in the plane.
    After the edge the elements are computed from the receiver's image towards the
    emitter (the BTM response is reciprocal) and turned round."""
    normal, offset, p_refl = planes
    ref = emitter if before else receiver  # the end whose leg reflects
    oth = receiver if before else emitter
    side_ref, side_oth = normal @ ref - offset, normal @ oth - offset
    usable = (np.abs(side_ref) >= tol) & (np.abs(side_oth) >= tol)
    images = ref - 2 * side_ref[:, None] * normal  # (P, 3)
    mids = 0.5 * (edges.start_m + edges.end_m)
    side_mid = mids @ normal.T - offset  # (E, P)
    near = _segment_distance(oth, edges.start_m, edges.end_m)[:, None] + np.stack(
        [_segment_distance(i, edges.start_m, edges.end_m) for i in images], axis=1
    )
    e_idx, p_idx = np.nonzero(
        usable[None, :] & (side_mid * side_ref[None, :] > tol) & (near <= max_path_m)
    )
    if e_idx.size == 0:
        return _empty()
    # orientation, visibility from the other end, elements: one row per (edge, plane)
    keep, wedge = edges.select(e_idx).oriented(images[p_idx], oth)
    rows = np.flatnonzero(keep)
    if rows.size and caster is not None:
        frac = PROBE_FRACTIONS
        pts = _probe_points(wedge.start_m[rows], wedge.end_m[rows])
        seen = _visible(caster, oth, pts.reshape(-1, 3), tol).reshape(-1, frac.size)
        # and the reflection towards those points must land on a face of the plane
        img = np.repeat(images[p_idx[rows]], frac.size, axis=0)
        nn = np.repeat(normal[p_idx[rows]], frac.size, axis=0)
        oo = np.repeat(offset[p_idx[rows]], frac.size)
        d = pts.reshape(-1, 3) - img
        dn = np.einsum("ij,ij->i", d, nn)
        t_ = (oo - np.einsum("ij,ij->i", img, nn)) / np.where(np.abs(dn) < 1e-12, 1e-12, dn)
        x = img + t_[:, None] * d
        v = x - ref
        dist = np.linalg.norm(v, axis=1)
        t, f = caster.first_hit(np.broadcast_to(ref, v.shape), v, dist + tol)
        lands = ((t_ > 0) & (t_ < 1) & (f >= 0) & (np.abs(t - dist) <= tol)).reshape(-1, frac.size)
        rows = rows[(seen & lands).any(axis=1)]
    if rows.size == 0:
        return _empty()
    el, local, counts = _wedge_elements(
        wedge, rows, images[p_idx[rows]], oth, face_reflection, step_m, max_path_m, face_column
    )
    if len(el) == 0:
        return _empty()
    strong = np.abs(el.amplitude * p_refl[p_idx[rows[local]]]) >= floor
    el = EdgeElements(*(getattr(el, f)[strong] for f in _FIELDS))
    row = rows[local[strong]]
    if counts is not None:  # and the plane's own reflection
        counts = counts[strong]
        column = plane_column[p_idx[row]]
        table = column >= 0
        counts[np.flatnonzero(table), column[table]] += 1
    n, off, image = normal[p_idx[row]], offset[p_idx[row]], images[p_idx[row]]
    z = el.point_m
    # reflection point: where the line image -> element crosses the plane
    d = z - image
    dn = np.einsum("ij,ij->i", d, n)
    s_ = (off - np.einsum("ij,ij->i", image, n)) / np.where(np.abs(dn) < 1e-12, 1e-12, dn)
    x = image + s_[:, None] * d
    ok = (s_ > 0) & (s_ < 1)
    if caster is not None and ok.any():
        # the real end must meet a face exactly at x; x (nudged off the plane) and
        # the other end must see the element
        v = x - ref
        dist = np.linalg.norm(v, axis=1)
        t, f = caster.first_hit(np.broadcast_to(ref, v.shape), v, dist + tol)
        ok &= (f >= 0) & (np.abs(t - dist) <= tol)
        x_off = x + (np.sign(side_ref[p_idx[row]]) * nudge)[:, None] * n
        ok &= _visible(caster, x_off, z, tol) & _visible(caster, oth, z, tol)
    k = np.flatnonzero(ok)
    amp = el.amplitude[k] * p_refl[p_idx[row[k]]]
    edge = e_idx[row[k]]
    order = np.full(k.size, 2)
    counts = None if counts is None else counts[k]
    if before:  # image source: first leg from the image, anchor on the edge
        dep = x[k] - emitter
        dep /= np.linalg.norm(dep, axis=1, keepdims=True)
        return DiffractedPaths(
            z[k], el.first_leg_m[k], amp * el.second_leg_m[k], z[k], dep, edge, order, counts
        )
    # after: computed receiver-image -> edge -> emitter; the path is emitter -> z ->
    # plane -> microphone, so the first leg is |emitter - z| and the anchor is z's
    # image (its distance to the receiver is the reflected leg)
    zk, nk = z[k], n[k]
    anchor = zk - 2 * (np.einsum("ij,ij->i", zk, nk) - off[k])[:, None] * nk
    dep = (zk - emitter) / el.second_leg_m[k][:, None]
    return DiffractedPaths(
        anchor, el.second_leg_m[k], amp * el.first_leg_m[k], zk, dep, edge, order, counts
    )


def _edge_to_edge(
    edges: Edges,
    caster,
    emitter: np.ndarray,
    receiver: np.ndarray,
    face_plane: np.ndarray,
    face_reflection: np.ndarray,
    step_m: float,
    max_path_m: float,
    tol: float,
    nudge: float,
    face_column: np.ndarray | None = None,
) -> DiffractedPaths:
    """Step 5: second-order paths emitter -> edge 1 -> edge 2 -> receiver over every
    ordered pair of edges that share a plane (:func:`edge_pair_elements`).

    A pair is tried if the emitter is on a convex side of edge 1 and sees it, the
    receiver likewise for edge 2 (at one of five points along it), the two edges
    are not collinear, and the plane holds a face half way between the edges' mid
    points (the path runs over the face: a ray down onto the plane there).  Edge 2
    lies on a face of wedge 1: at angle 0 about edge 1 if the shared plane is its
    face 1, else at its open angle (and likewise edge 1 about edge 2).  Both rims of
    a thin plate: the path runs along both of its sides (``sides = 2``).
    Visibility is checked per edge, not per element.  With `face_column` (as
    :func:`_wedge_elements`), each wedge's response is split into the part without
    the image terms of its table faces and each of those terms alone
    (:func:`_wedge_parts`); every pair of parts is a set of paths of its own, which
    counts one interaction with each table face whose image term it holds.
    """
    keep1, w1 = edges.oriented(emitter, emitter)
    keep2, w2 = edges.oriented(receiver, receiver)
    n_e = len(edges)
    pts = _probe_points(edges.start_m, edges.end_m).reshape(-1, 3)
    near_s = _segment_distance(emitter, edges.start_m, edges.end_m)
    near_r = _segment_distance(receiver, edges.start_m, edges.end_m)
    keep1 &= near_s < max_path_m
    keep2 &= near_r < max_path_m
    if caster is not None:
        seen_s = _visible(caster, emitter, pts, tol).reshape(n_e, -1).any(axis=1)
        seen_r = _visible(caster, receiver, pts, tol).reshape(n_e, -1).any(axis=1)
        keep1 &= seen_s
        keep2 &= seen_r
    plane = np.asarray(face_plane, int)
    p_a = plane[edges.faces[:, 0]]
    p_b = np.where(edges.faces[:, 1] >= 0, plane[np.maximum(edges.faces[:, 1], 0)], p_a)
    i, j = np.nonzero(keep1[:, None] & keep2[None, :])
    common = (p_a[i] == p_a[j]) | (p_a[i] == p_b[j])
    common |= (p_b[i] == p_a[j]) | (p_b[i] == p_b[j])
    ok = (i != j) & common
    i, j = i[ok], j[ok]
    if i.size == 0:
        return _empty()
    shared = np.where((p_a[i] == p_a[j]) | (p_a[i] == p_b[j]), p_a[i], p_b[i])
    rim = edges.faces[:, 1] < 0
    refl = np.asarray(face_reflection, float)
    # interaction columns come in pairs (specular, diffuse), as _wedge_elements's
    n_col = 0 if face_column is None else int(np.max(face_column, initial=-1)) + 2
    out = []
    for a, b, p in zip(i, j, shared):
        wa, wb = _wedge(w1, a, refl), _wedge(w2, b, refl)
        ra, _, _ = wa.cylindrical(np.stack([wb.start_m, wb.end_m]))
        if ra.max() <= tol:  # collinear: no path over the face
            continue
        # the path runs over a face of the shared plane (a ray down onto it)
        mid = 0.25 * (wa.start_m + wa.end_m + wb.start_m + wb.end_m)
        f = w1.faces[a, 0] if plane[w1.faces[a, 0]] == p else w1.faces[a, 1]
        # face 1's normal points into the air; face 2's air side is the other way
        # from the direction of growing angle there
        turn = np.cross(w1.face_dir[a], w1.normal[a])
        up = w1.normal[a] if f == w1.faces[a, 0] else -np.cross(turn, w1.other_dir[a])
        if caster is not None:
            lift = 10 * nudge + tol
            t, hit = caster.first_hit((mid + lift * up)[None], -up[None], 2 * lift)
            if hit[0] < 0 or plane[hit[0]] != p or abs(t[0] - lift) > tol + nudge:
                continue
        th_ab = 0.0 if plane[w1.faces[a, 0]] == p else w1.angle_rad[a]
        th_ba = 0.0 if plane[w2.faces[b, 0]] == p else w2.angle_rad[b]
        sides = 2 if (rim[a] and rim[b]) else 1
        for (pa, ca), (pb, cb) in itertools.product(
            _wedge_parts(wa, w1, a, face_column), _wedge_parts(wb, w2, b, face_column)
        ):
            el = edge_pair_elements(
                pa, pb, th_ab, th_ba, sides, emitter, receiver, step_m, max_path_m
            )
            if len(el) == 0:
                continue
            dep = el.first_point_m - emitter
            dep /= np.maximum(np.linalg.norm(dep, axis=1, keepdims=True), 1e-12)
            counts = None
            if face_column is not None:
                counts = np.zeros((len(el), n_col), int)
                for column in (ca, cb):
                    if column >= 0:
                        counts[:, column] += 1
            out.append(
                DiffractedPaths(
                    el.point_m,
                    el.first_leg_m,
                    el.amplitude * el.second_leg_m,
                    el.point_m,
                    dep,
                    np.full(len(el), b),
                    np.full(len(el), 2),
                    counts,
                )
            )
    if not out:
        return _empty()
    return _concatenate(out)


def _wedge_parts(wedge: Wedge, w: Edges, e: int, face_column) -> list[tuple[Wedge, int]]:
    """Wedge e of oriented edges `w` (as `wedge`) whole, or, if a face has a table
    material (`face_column`, as :func:`_wedge_elements`), split into the part without
    those faces' image terms and each such term alone: (part, its table column or
    -1).  The parts sum to the whole wedge (beta is linear in its term weights)."""
    if face_column is None:
        return [(wedge, -1)]
    f1 = w.faces[e, 0]
    f2 = w.faces[e, 1] if w.faces[e, 1] >= 0 else f1
    c1, c2 = int(face_column[f1]), int(face_column[f2])
    if c1 < 0 and c2 < 0:
        return [(wedge, -1)]
    r1, r2 = wedge.reflection
    parts = [(replace(wedge, terms=(r2 if c2 < 0 else 0.0, 1.0, 1.0, r1 if c1 < 0 else 0.0)), -1)]
    if c2 >= 0:
        parts.append((replace(wedge, terms=(r2, 0.0, 0.0, 0.0)), c2))
    if c1 >= 0:
        parts.append((replace(wedge, terms=(0.0, 0.0, 0.0, r1)), c1))
    return parts


def _wedge(w: Edges, e: int, refl: np.ndarray) -> Wedge:
    """Edge e of oriented edges as a :class:`Wedge` (its faces' reflection factors)."""
    f1 = w.faces[e, 0]
    f2 = w.faces[e, 1] if w.faces[e, 1] >= 0 else f1
    return Wedge(
        w.start_m[e],
        w.end_m[e],
        w.face_dir[e],
        w.normal[e],
        float(w.angle_rad[e]),
        (float(refl[f1]), float(refl[f2])),
    )


_PATH_FIELDS = ("anchor_m", "first_leg_m", "strength", "position_m", "departure", "edge", "order")


def _paths(el: EdgeElements, owner, ok, source, points, scale, order, counts=None):
    k = np.flatnonzero(ok)
    dep = points[k] - source
    dep /= np.maximum(np.linalg.norm(dep, axis=1, keepdims=True), 1e-12)
    return DiffractedPaths(
        points[k],
        el.first_leg_m[k],
        el.amplitude[k] * scale[k] * el.second_leg_m[k],
        points[k],
        dep,
        owner[k],
        np.full(k.size, order),
        None if counts is None else counts[k],
    )


def _empty() -> DiffractedPaths:
    z3, z = np.zeros((0, 3)), np.zeros(0)
    return DiffractedPaths(z3, z, z, z3, z3, np.zeros(0, int), np.zeros(0, int))


_FIELDS = ("point_m", "first_leg_m", "second_leg_m", "amplitude")


@dataclass(frozen=True, eq=False)
class DiffractingGeometry:
    """What the stage needs of a world, built once per world (not per pose).

    edges: its diffracting edges (:func:`find_edges`); face_reflection (F,): pressure
    reflection factor per face; planes: (normal (P, 3), offset (P,), reflection (P,))
    of every plane, for the reflections before or after an edge; face_plane (F,):
    the plane id of each face (which edges share a plane, for edge to edge);
    face_column (F,), plane_column (P,): the specular interaction column of each
    face's and plane's frequency-dependent material (-1: single numbers; None: a
    world without tables).
    """

    edges: Edges
    face_reflection: np.ndarray
    planes: tuple[np.ndarray, np.ndarray, np.ndarray]
    face_plane: np.ndarray | None = None
    face_column: np.ndarray | None = None
    plane_column: np.ndarray | None = None

    @classmethod
    def of(cls, world: World) -> DiffractingGeometry:
        refl = world.face_values("reflection")
        first = np.unique(world.plane, return_index=True)[1]
        planes = (world.normals[first], world.offsets[first], refl[first])
        column = world.face_interactions(0)
        return cls(
            find_edges(triangles_mesh(world.triangles)),
            refl,
            planes,
            world.plane,
            column,
            None if column is None else column[first],
        )


def edge_diffraction(
    geometry: DiffractingGeometry,
    caster,
    emitter: np.ndarray,
    receiver: np.ndarray,
    max_path_m: float,
    step_m: float,
    reflections: bool,
    floor_db: float,
    order: int = 1,
    floor_level: float = 0.0,
) -> TracedPaths:
    """Stage 3 of the tracer: :func:`diffract` as :class:`TracedPaths` of kind
    ``"diffraction"`` (order 1, or 2 with a reflection before or after the edge or
    with a second edge).

    reflections: also the paths with one specular reflection (``planes``);
    floor_db: the tracer's energy floor (dB, negative); floor_level: see
    :func:`diffract`; order: 2 adds edge-to-edge diffraction.
    """
    d = diffract(
        geometry.edges,
        caster,
        emitter,
        receiver,
        max_path_m,
        geometry.face_reflection,
        step_m,
        geometry.planes if reflections else None,
        floor_db,
        order,
        geometry.face_plane,
        floor_level,
        geometry.face_column,
        geometry.plane_column,
    )
    kind = np.full(len(d), KIND["diffraction"])
    return TracedPaths(
        d.anchor_m,
        d.first_leg_m,
        d.strength,
        d.position_m,
        d.order,
        kind,
        d.departure,
        interactions=d.counts,
    )
