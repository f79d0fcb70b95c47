"""Edge diffraction with one specular reflection before or after the edge: the
emitter (before) or the receiver (after) replaced by its image in a plane of the
scene, every (edge, plane) pair in one pass."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.trace.diffraction.first_order import (
    PROBE_FRACTIONS,
    probe_points,
    segment_distance,
    visible,
    wedge_elements,
)
from acousim.trace.diffraction.paths import DiffractedPaths, empty_paths, select_elements
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.world.edges import Edges

__all__ = ["reflected_paths"]


@dataclass(frozen=True, eq=False)
class _Pairs:
    """The (edge, plane) pairs tried: edge (Q,), plane (Q,), the edges oriented for
    the image and the other end (Q rows), the images (P, 3), which end reflects."""

    edge: np.ndarray
    plane: np.ndarray
    wedge: Edges
    images: np.ndarray
    ref: np.ndarray  # the end whose leg reflects (emitter before, receiver after)
    oth: np.ndarray
    side_ref: np.ndarray  # (P,) its signed distance from each plane
    keep: np.ndarray  # (Q,) the wedge is convex towards both ends


def reflected_paths(ctx: StageContext, before: bool, floor: float) -> DiffractedPaths:
    """All paths emitter -> plane -> edge -> receiver (before) or emitter -> edge ->
    plane -> receiver (after) at once, for every plane and edge: the reflecting
    leg's real end is replaced by its image in the plane.  After the edge the
    elements are computed from the receiver's image towards the emitter (the BTM
    response is reciprocal) and turned round.  Elements whose gain (with the
    plane's reflection) is below `floor` are dropped before their rays.

    A pair is tried if, at one of five points along the edge, the other end sees it
    and the reflection lands on a face of the plane; an element is kept only if its
    own reflection point lies on a face of the plane (a ray) and it sees both ends.
    """
    pairs = _pairs(ctx, before)
    if pairs is None:
        return empty_paths()
    rows = _tried(ctx, pairs)
    if rows.size == 0:
        return empty_paths()
    el, local, counts = wedge_elements(ctx, pairs.wedge, rows, pairs.images[pairs.plane[rows]])
    if len(el) == 0:
        return empty_paths()
    normal, offset, p_refl = ctx.geometry.planes
    strong = np.abs(el.amplitude * p_refl[pairs.plane[rows[local]]]) >= floor
    el = select_elements(el, strong)
    row = rows[local[strong]]
    if counts is not None:  # and the plane's own reflection
        counts = counts[strong]
        column = ctx.geometry.plane_column[pairs.plane[row]]
        table = column >= 0
        counts[np.flatnonzero(table), column[table]] += 1
    p = pairs.plane[row]
    x, ok = _reflection_points(ctx, pairs, p, el.point_m)
    k = np.flatnonzero(ok)
    amp = el.amplitude[k] * p_refl[p[k]]
    edge = pairs.edge[row[k]]
    counts = None if counts is None else counts[k]
    z, legs = el.point_m[k], (el.first_leg_m[k], el.second_leg_m[k])
    order = np.full(k.size, 2)
    if before:  # image source: first leg from the image, anchor on the edge
        dep = x[k] - ctx.emitter
        dep /= np.linalg.norm(dep, axis=1, keepdims=True)
        return DiffractedPaths(z, legs[0], amp * legs[1], z, dep, edge, order, counts)
    # after: computed receiver-image -> edge -> emitter; the path is emitter -> z ->
    # plane -> microphone, so the first leg is |emitter - z| and the anchor is z's
    # image (its distance to the receiver is the reflected leg)
    n = normal[p[k]]
    anchor = z - 2 * (np.einsum("ij,ij->i", z, n) - offset[p[k]])[:, None] * n
    dep = (z - ctx.emitter) / legs[1][:, None]
    return DiffractedPaths(anchor, legs[1], amp * legs[0], z, dep, edge, order, counts)


def _pairs(ctx: StageContext, before: bool) -> _Pairs | None:
    """The (edge, plane) pairs on the side of the reflecting end within reach."""
    normal, offset, _ = ctx.geometry.planes
    edges, tol = ctx.geometry.edges, ctx.tol
    ref = ctx.emitter if before else ctx.receiver
    oth = ctx.receiver if before else ctx.emitter
    side_ref, side_oth = normal @ ref - offset, normal @ oth - offset
    usable = (np.abs(side_ref) >= tol) & (np.abs(side_oth) >= tol)
    images = ref - 2 * side_ref[:, None] * normal  # (P, 3)
    mids = 0.5 * (edges.start_m + edges.end_m)
    side_mid = mids @ normal.T - offset  # (E, P)
    near = segment_distance(oth, edges.start_m, edges.end_m)[:, None] + np.stack(
        [segment_distance(i, edges.start_m, edges.end_m) for i in images], axis=1
    )
    e_idx, p_idx = np.nonzero(
        usable[None, :] & (side_mid * side_ref[None, :] > tol) & (near <= ctx.options.max_path_m)
    )
    if e_idx.size == 0:
        return None
    keep, wedge = edges.select(e_idx).oriented(images[p_idx], oth)
    return _Pairs(e_idx, p_idx, wedge, images, ref, oth, side_ref, keep)


def _tried(ctx: StageContext, pairs: _Pairs) -> np.ndarray:
    """Rows of the pairs whose wedge is convex towards both ends and that pass the
    five-point test (the other end sees the point, the reflection lands on a face
    of the plane)."""
    rows = np.flatnonzero(pairs.keep)
    if rows.size == 0 or ctx.caster is None:
        return rows
    normal, offset, _ = ctx.geometry.planes
    tol, frac = ctx.tol, PROBE_FRACTIONS
    pts = probe_points(pairs.wedge.start_m[rows], pairs.wedge.end_m[rows])
    seen = visible(ctx.caster, pairs.oth, pts.reshape(-1, 3), tol).reshape(-1, frac.size)
    p = np.repeat(pairs.plane[rows], frac.size)
    lands = _lands_on_plane(ctx, pairs, p, pts.reshape(-1, 3)).reshape(-1, frac.size)
    return rows[(seen & lands).any(axis=1)]


def _crossing(image, n, off, z):
    """Where the lines image -> z (K, 3) cross the planes (n (K, 3), off (K,)):
    (the points (K, 3), their fraction along the line (K,))."""
    d = z - image
    dn = np.einsum("ij,ij->i", d, n)
    s = (off - np.einsum("ij,ij->i", image, n)) / np.where(np.abs(dn) < 1e-12, 1e-12, dn)
    return image + s[:, None] * d, s


def _lands_on_plane(ctx: StageContext, pairs: _Pairs, p: np.ndarray, z: np.ndarray):
    """(K,) True where the reflection towards z (K, 3) in plane p (K,) lies between
    the image and z and the real end's ray meets a face exactly there."""
    normal, offset, _ = ctx.geometry.planes
    x, s = _crossing(pairs.images[p], normal[p], offset[p], z)
    v = x - pairs.ref
    dist = np.linalg.norm(v, axis=1)
    t, f = ctx.caster.first_hit(np.broadcast_to(pairs.ref, v.shape), v, dist + ctx.tol)
    return (s > 0) & (s < 1) & (f >= 0) & (np.abs(t - dist) <= ctx.tol)


def _reflection_points(ctx: StageContext, pairs: _Pairs, p: np.ndarray, z: np.ndarray):
    """The reflection point (K, 3) of each element z (K, 3) in plane p (K,), and (K,)
    True where it is real: on a face of the plane, and x (nudged off the plane) and
    the other end both see the element."""
    normal, offset, _ = ctx.geometry.planes
    x, s = _crossing(pairs.images[p], normal[p], offset[p], z)
    ok = (s > 0) & (s < 1)
    if ctx.caster is not None and ok.any():
        ok &= _lands_on_plane(ctx, pairs, p, z)
        x_off = x + (np.sign(pairs.side_ref[p]) * ctx.nudge)[:, None] * normal[p]
        ok &= visible(ctx.caster, x_off, z, ctx.tol) & visible(ctx.caster, pairs.oth, z, ctx.tol)
    return x, ok
