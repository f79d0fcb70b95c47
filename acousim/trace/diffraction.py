"""The edge-diffraction stage: first-order BTM diffraction of every edge in view.

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
   receiver by its image (a reflection after the edge); an element is kept only if
   the reflection point lies on a face of that plane (checked by casting the leg).
4. Visibility: an element is kept only if nothing lies between it and the emitter
   (or the reflection point) and between it and the receiver: one ray each way
   through the Embree scene, blocked if it meets a face before the element
   (tolerance ``1e-5`` of the scene size: the element lies on its own faces).

Valid where the edges are straight and their faces nearly rigid (BTM is exact for
an infinite rigid wedge; a finite edge is integrated over its length).  Not
modelled: edge-to-edge (second-order) diffraction; diffraction of the diffuse and
curved-surface parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .btm import DEFAULT_STEP_M, EdgeElements, many_edge_elements
from .edges import Edges

__all__ = ["DiffractedPaths", "diffract", "DEFAULT_STEP_M"]


@dataclass(frozen=True, eq=False)
class DiffractedPaths:
    """N diffraction paths in the tracer's path form (world frame, metres).

    anchor_m (N, 3): the element's point on the edge (or, for a reflection after
    the edge, its image); first_leg_m (N,): emitter (or its image) to the element;
    strength (N,): signed, the gain at a microphone p is ``strength / |anchor - p|``;
    position_m (N, 3): the element's point on the edge; departure (N, 3): unit
    direction leaving the emitter; edge (N,): index into the Edges; order (N,):
    interactions (1: the edge alone, 2: a reflection and the edge).
    """

    anchor_m: np.ndarray
    first_leg_m: np.ndarray
    strength: np.ndarray
    position_m: np.ndarray
    departure: np.ndarray
    edge: np.ndarray
    order: np.ndarray

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
) -> tuple[EdgeElements, np.ndarray]:
    """BTM elements of the candidate edges (indices) that form a convex wedge on the
    side of source and receiver and that every point of `seen_from` sees (at one of
    five points along the edge, at least)."""
    keep, wedge = edges.oriented(source, receiver)
    idx = np.asarray(candidates, int)
    idx = idx[keep[idx]]
    if idx.size and caster is not None and seen_from:
        frac = np.array([0.02, 0.25, 0.5, 0.75, 0.98])
        pts = (
            edges.start_m[idx, None, :]
            + frac[None, :, None] * (edges.end_m[idx] - edges.start_m[idx])[:, None, :]
        )
        pts = pts.reshape(-1, 3)
        seen = np.ones(pts.shape[0], bool)
        for p in seen_from:
            seen &= _visible(caster, p, pts, tol)
        idx = idx[seen.reshape(-1, frac.size).any(axis=1)]
    refl = np.asarray(face_reflection, float)
    f1 = wedge.faces[idx, 0]
    f2 = np.where(wedge.faces[idx, 1] >= 0, wedge.faces[idx, 1], f1)
    el, local = many_edge_elements(
        wedge.start_m[idx],
        wedge.end_m[idx],
        wedge.face_dir[idx],
        wedge.normal[idx],
        wedge.angle_rad[idx],
        source,
        receiver,
        step_m,
        max_path_m,
        np.column_stack([refl[f1], refl[f2]]),
    )
    return el, idx[local]


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
) -> DiffractedPaths:
    """First-order edge diffraction (see the module docstring).

    edges: the scene's diffracting edges; caster: the RayCaster (None: no occlusion);
    emitter, receiver (3,); max_path_m: longest path kept; face_reflection (F,):
    pressure reflection factor per face; step_m: edge-element step (excess path
    length, m); planes: (normal (P, 3), offset (P,), reflection (P,)) of the planes
    to combine with one specular reflection before or after the edge (None: none).
    """
    emitter, receiver = np.asarray(emitter, float), np.asarray(receiver, float)
    if len(edges) == 0:
        return _empty()
    r_edge = np.asarray(face_reflection, float)
    scale = caster.scale if caster is not None else 1.0
    tol = 1e-5 * scale + 1e-7
    out = []
    # 1-2. direct legs
    near = _segment_distance(emitter, edges.start_m, edges.end_m) + _segment_distance(
        receiver, edges.start_m, edges.end_m
    )
    idx = np.flatnonzero(near <= max_path_m)
    el, owner = _elements(
        edges, idx, emitter, receiver, r_edge, step_m, max_path_m, caster, tol, (emitter, receiver)
    )
    # 4. visibility both ways
    ok = _visible(caster, emitter, el.point_m, tol) & _visible(caster, receiver, el.point_m, tol)
    out.append(_paths(el, owner, ok, emitter, el.point_m, np.ones(len(el)), 1))
    # 3. one reflection before or after the edge
    if planes is not None:
        normal, offset, p_refl = planes
        for n, off, rp in zip(normal, offset, p_refl):
            for before in (True, False):
                out.append(
                    _with_reflection(
                        edges,
                        caster,
                        emitter,
                        receiver,
                        n,
                        off,
                        rp,
                        before,
                        r_edge,
                        step_m,
                        max_path_m,
                        tol,
                    )
                )
    out = [p for p in out if len(p)]
    if not out:
        return _empty()
    return DiffractedPaths(
        *(
            np.concatenate([getattr(p, f) for p in out])
            for f in (
                "anchor_m",
                "first_leg_m",
                "strength",
                "position_m",
                "departure",
                "edge",
                "order",
            )
        )
    )


def _mirror(p: np.ndarray, n: np.ndarray, off: float) -> np.ndarray:
    return p - 2 * (p @ n - off)[..., None] * n if p.ndim > 1 else p - 2 * (p @ n - off) * n


def _with_reflection(
    edges, caster, emitter, receiver, n, off, rp, before, r_edge, step_m, max_path_m, tol
) -> DiffractedPaths:
    """Paths emitter -> plane -> edge -> receiver (before) or emitter -> edge -> plane
    -> receiver (after), through the image of the emitter or of the receiver."""
    src = _mirror(emitter, n, off) if before else emitter
    rcv = receiver if before else _mirror(receiver, n, off)
    # the two points must be on the same side of the plane as the real ones
    side_e, side_r = emitter @ n - off, receiver @ n - off
    if abs(side_e) < tol or abs(side_r) < tol:
        return _empty()
    near = _segment_distance(src, edges.start_m, edges.end_m) + _segment_distance(
        rcv, edges.start_m, edges.end_m
    )
    # the edge must be on the real side of the plane (not in the plane itself)
    mid = 0.5 * (edges.start_m + edges.end_m)
    side_m = mid @ n - off
    real_side = side_e if before else side_r
    idx = np.flatnonzero((near <= max_path_m) & (side_m * real_side > tol))
    if idx.size == 0:
        return _empty()
    other = receiver if before else emitter
    el, owner = _elements(edges, idx, src, rcv, r_edge, step_m, max_path_m, caster, tol, (other,))
    if len(el) == 0:
        return _empty()
    outer = emitter if before else receiver  # the leg that reflects
    image = src if before else rcv
    # reflection point: where the line image -> element crosses the plane
    d = el.point_m - image
    s_ = (off - image @ n) / np.where(np.abs(d @ n) < 1e-12, 1e-12, d @ n)
    x = image + s_[:, None] * d
    ok = (s_ > 0) & (s_ < 1)
    # the reflecting leg: from the reflection point (nudged off the plane) to the
    # element and to the real emitter/receiver; it must meet this plane's face: a ray
    # from the real point towards x must hit a face exactly at x
    if caster is not None and ok.any():
        v = x - outer
        dist = np.linalg.norm(v, axis=1)
        t, f = caster.first_hit(np.broadcast_to(outer, v.shape), v, dist + 10 * tol)
        ok &= (f >= 0) & (np.abs(t - dist) <= 10 * tol)
        x_off = x + np.sign(real_side) * tol * n
        ok &= _visible(caster, x_off, el.point_m, tol)
        other = receiver if before else emitter
        ok &= _visible(caster, other, el.point_m, tol)
    amp_scale = np.full(len(el), rp)
    p = _paths(el, owner, ok, src, el.point_m, amp_scale, 2)
    if before:
        # departure: from the emitter towards the reflection point
        dep = x[ok] - emitter
        dep /= np.linalg.norm(dep, axis=1, keepdims=True)
        return DiffractedPaths(
            p.anchor_m, p.first_leg_m, p.strength, p.position_m, dep, p.edge, p.order
        )
    # after the edge: the path to microphone q is |emitter - z| + |z - image(q)|;
    # anchor the path at the element's image so that |anchor - q| is that last leg
    anchor = _mirror(p.position_m, n, off)
    return DiffractedPaths(
        anchor, p.first_leg_m, p.strength, p.position_m, p.departure, p.edge, p.order
    )


def _paths(el: EdgeElements, owner, ok, source, points, scale, order) -> DiffractedPaths:
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
    )


def _empty() -> DiffractedPaths:
    z3, z = np.zeros((0, 3)), np.zeros(0)
    return DiffractedPaths(z3, z, z, z3, z3, np.zeros(0, int), np.zeros(0, int))
