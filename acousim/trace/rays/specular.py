"""Exact specular paths: image sources over a sequence of planes, checked both ways.

Stage 2 of the tracer. Rays find which sequences of planes can form a specular path;
for each sequence the emitter is mirrored plane by plane into its image, and the
reflection points are found backwards from the receiver (the array centre) by
intersecting the line to each image with its plane. A path is kept only if a ray
cast from each point towards the next meets exactly that plane first at exactly that
distance (visibility, and the point lies on a face of the plane), and the last leg
reaches the emitter unobstructed. The delay at each microphone is then the exact
distance from the image source, independent of the ray budget.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.trace.paths import KIND, TracedPaths
from acousim.trace.world.build import World
from acousim.trace.world.embree import RayCaster
from processing.base.kernels import optional_kernel

#: an image source within this times the longest path is within reach
REACH = 1.01

__all__ = ["SpecularPath", "refine_sequences", "by_length", "mirror", "as_paths"]


@dataclass(frozen=True)
class SpecularPath:
    planes: tuple[int, ...]  # plane ids, emitter side first
    image_m: np.ndarray  # (3,) image of the emitter
    points_m: np.ndarray  # (k, 3) reflection points, emitter side first
    amplitude: float  # product of the pressure reflection factors
    departure: np.ndarray  # (3,) unit direction leaving the emitter
    interactions: np.ndarray | None = None  # (K,) material interaction counts


def mirror(point: np.ndarray, normal: np.ndarray, offset: float) -> np.ndarray:
    """Mirror image of a point across the plane n . x = offset."""
    return point - 2 * (point @ normal - offset) * normal


def refine_sequences(
    world: World,
    caster: RayCaster,
    sequences: list[tuple[int, ...]] | dict[int, np.ndarray],
    emitter: np.ndarray,
    receiver: np.ndarray,
    max_path_m: float | None = None,
) -> list[SpecularPath]:
    """Valid specular paths among candidate plane sequences (batched by length), given
    as tuples of plane ids in order, or as arrays (S, k) of them by length k; with
    `max_path_m`, only those :func:`as_paths` keeps (image within reach), the others
    refused before any ray."""
    normal, offset, refl, column = _plane_table(world)
    K = world.n_interactions
    eps, tol = caster.offset_m, caster.tolerance_m
    paths: list[SpecularPath] = []
    found: set[tuple] = set()  # the image sources kept, in units of tol
    by_len = sequences if isinstance(sequences, dict) else by_length(sequences)
    for _k, ids in sorted(by_len.items()):
        images, ok = _images_within(ids, emitter, normal, offset, max_path_m)
        if not ok.all():  # those out of reach take no further work (order kept)
            within = np.flatnonzero(ok)
            ids, images = np.take(ids, within, axis=0), np.take(images, within, axis=0)
            ok = ok[within]
        points, edges, cur = _reflection_points(world, caster, ids, images, receiver, ok)
        # two reflections at one point of an edge: only inside a concave corner
        i, j = edges.T
        i, j = i[ok[i]], j[ok[i]]
        if i.size:
            before = _before(points[i], j, emitter, tol)
            pairs = np.column_stack([ids[i, j], ids[i, j + 1]])
            ok[i[~_concave(world, pairs, points[i, j], before, tol)]] = False
        # last leg: from the first reflection point to the emitter, unobstructed
        live = np.flatnonzero(ok)
        d = emitter - cur[live]
        L = np.linalg.norm(d, axis=1)
        t, f = caster.first_hit(cur[live] + eps * d / L[:, None], d)
        ok[live[(f >= 0) & (t < L - tol)]] = False
        rows = np.flatnonzero(ok)
        # two orders of the same reflections that meet at an edge are one path (the
        # same image): the first kept
        keys = np.round(images[rows, -1] / tol).astype(np.int64).tolist()
        first = []
        for i, key in zip(rows.tolist(), map(tuple, keys)):
            if key not in found:
                found.add(key)
                first.append(i)
        rows = np.array(first, np.intp)
        counts = _counts(ids[rows], column, K) if K else None
        paths += _as_specular(ids[rows], images[rows, -1], points[rows], refl, emitter, counts)
    return paths


def _as_specular(ids, images, points, refl, emitter, counts) -> list[SpecularPath]:
    """The paths of the sequences `ids` (S, k) kept, their last images (S, 3) and
    reflection points (S, k, 3), each its own :class:`SpecularPath` (the arrays made
    for all at once: the departures ``(x_1 - e) / |x_1 - e|``, the amplitudes the
    products of the planes' factors `refl`); `counts` (S, K) or None."""
    dep = points[:, 0] - emitter
    dep = dep / np.sqrt(np.sum(dep * dep, axis=1))[:, None]
    amp = np.prod(refl[ids], axis=1).tolist()
    return [
        SpecularPath(
            tuple(planes),
            images[i],
            points[i],
            amp[i],
            dep[i],
            None if counts is None else counts[i],
        )
        for i, planes in enumerate(ids.tolist())
    ]


def _kernels():
    """The compiled steps (:mod:`.specular_kernel`), or None without numba."""
    return optional_kernel("acousim.trace.rays.specular_kernel")


def _images_within(ids: np.ndarray, emitter: np.ndarray, normal, offset, max_path_m):
    """Image sources (S, k + 1, 3) of sequences `ids` (S, k) and (S,) whether the last
    lies within reach of the emitter (``max_path_m`` times :data:`REACH`; None: all)."""
    kernel = _kernels()
    if kernel is None:
        images = _images(ids, emitter, normal, offset)
        ok = np.ones(ids.shape[0], bool)
        if max_path_m is not None:
            ok &= np.linalg.norm(images[:, -1] - emitter, axis=1) <= max_path_m * REACH
        return images, ok
    images = np.empty((ids.shape[0], ids.shape[1] + 1, 3))
    reach = np.inf if max_path_m is None else max_path_m * REACH
    ids = np.ascontiguousarray(ids, np.int64)
    ok = kernel.images(ids, np.asarray(emitter, float), normal, offset, reach, images)
    return images, ok


def _images(ids: np.ndarray, emitter: np.ndarray, normal, offset) -> np.ndarray:
    """Image sources (S, k + 1, 3) of sequences `ids` (S, k): the emitter mirrored
    across each plane in turn."""
    S, k = ids.shape
    images = np.empty((S, k + 1, 3))
    images[:, 0] = emitter
    for j in range(k):
        n, off = normal[ids[:, j]], offset[ids[:, j]]
        prev = images[:, j]
        images[:, j + 1] = prev - 2 * (np.einsum("si,si->s", prev, n) - off)[:, None] * n
    return images


def _counts(ids: np.ndarray, column, K: int) -> np.ndarray:
    """(S, K) specular interactions of each sequence per interaction column (zeros
    without frequency-dependent materials, K = 0)."""
    S, k = ids.shape
    counts = np.zeros((S, K), int)
    if K:  # frequency-dependent materials: count each plane's specular interaction
        for j in range(k):
            c = column[ids[:, j]]
            np.add.at(counts, (np.flatnonzero(c >= 0), c[c >= 0]), 1)
    return counts


def _reflection_points(world, caster, ids, images, receiver, ok):
    """Backwards from the receiver, the reflection points (S, k, 3) of sequences `ids`
    (S, k) with image sources `images` (S, k + 1, 3), the (sequence, j) (E, 2) where
    reflections j and j + 1 meet at an edge, and the first reflection points (S, 3)
    (the receiver for k = 0); `ok` (S,) is cleared in place for
    sequences whose points miss their plane or whose legs are blocked."""
    normal, offset = _plane_table(world)[:2]
    eps, tol = caster.offset_m, caster.tolerance_m
    S, k = ids.shape
    edges: list[np.ndarray] = []
    cur = np.empty((S, 3))
    cur[:] = receiver
    points = np.empty((S, k, 3))
    kernel = _kernels()
    for j in range(k - 1, -1, -1):
        if kernel is None:
            x, start, at_edge = _step(
                world, ids[:, j], images[:, j + 1], cur, ok, eps, tol, j < k - 1
            )
        else:  # x written into points (a view), as the numpy form copies it there
            x, start, at_edge = points[:, j], np.empty((S, 3)), np.empty(S, bool)
            planes, image, box = ids[:, j], images[:, j + 1], world.plane_boxes
            kernel.step(
                planes, image, cur, ok, normal, offset, box, tol, eps, j < k - 1, x, start, at_edge
            )
        sel = np.flatnonzero(ok & at_edge)
        ok[sel] = _on_planes(world, ids[sel, j], x[sel], tol)
        met = np.flatnonzero(ok & at_edge)
        edges.append(np.column_stack([met, np.full(met.size, j)]))
        live = np.flatnonzero(ok & ~at_edge)
        begin = np.take(start, live, axis=0)
        leg = np.take(x, live, axis=0) - begin
        t, f = caster.first_hit(begin, leg)
        dist = np.linalg.norm(leg, axis=1)
        good = (f >= 0) & (np.abs(t - dist) <= tol)
        other = good.copy()
        other[good] = world.plane[f[good]] != ids[live[good], j]
        # a hit at the right distance on another plane: the point is on an edge
        # (e.g. a corner seen by a co-located emitter and receiver); keep it if it
        # lies on a face of the expected plane, within the tolerance
        sel = np.flatnonzero(other)
        good[sel] = _on_planes(world, ids[live[sel], j], x[live[sel]], tol)
        ok[live[~good]] = False
        if kernel is None:
            points[:, j] = x
        cur = x
    return points, np.concatenate([np.zeros((0, 2), int), *edges]).astype(int), cur


def _step(world, planes, image, cur, ok, eps, tol, inner):
    """One backward step of :func:`_reflection_points` in numpy (the compiled
    :func:`.specular_kernel.step`'s twin): the points x (S, 3) where the lines from
    `cur` to `image` (S, 3) meet the `planes` (S,), the starts (S, 3) of the legs to
    check, and (S,) whether x is at an edge (on cur, `inner`: cur a reflection
    point); `ok` cleared in place."""
    normal, offset = _plane_table(world)[:2]
    n, off = normal[planes], offset[planes]
    direction = image - cur
    denom = np.einsum("si,si->s", direction, n)
    safe = np.where(np.abs(denom) < 1e-12, 1.0, denom)
    s_ = (off - np.einsum("si,si->s", cur, n)) / safe
    length = np.linalg.norm(direction, axis=1)
    ok &= (np.abs(denom) >= 1e-12) & (s_ * length > -tol) & (s_ < 1)
    x = cur + np.maximum(s_, 0)[:, None] * direction
    # a reflection point off its plane's box is on none of its faces (every check
    # after would refuse it): no ray for it
    box = world.plane_boxes[planes]
    ok &= np.all((box[:, 0] - 2.01 * tol <= x) & (x <= box[:, 1] + 2.01 * tol), axis=1)
    # a reflection point on the previous one: the path meets an edge between two
    # planes (both reflections happen there); no leg to check for it
    at_edge = (np.maximum(s_, 0) * length <= tol) & inner
    unit = direction / np.maximum(length, 1e-300)[:, None]
    start = cur + (eps if inner else 0.0) * unit
    return x, start, at_edge


def by_length(sequences: list[tuple[int, ...]]) -> dict[int, np.ndarray]:
    """Plane sequences as arrays (S, k) of plane ids by length k (their order kept)."""
    by_len: dict[int, list[tuple[int, ...]]] = {}
    for seq in sequences:
        by_len.setdefault(len(seq), []).append(seq)
    return {k: np.array(seqs, int).reshape(len(seqs), k) for k, seqs in by_len.items()}


def as_paths(specular: list[SpecularPath], emitter: np.ndarray, max_path_m: float) -> TracedPaths:
    """Specular paths as image sources (first leg 0), those within reach."""
    if not specular:
        return TracedPaths.empty()
    image = np.array([p.image_m for p in specular])
    amp = np.array([p.amplitude for p in specular])
    pos = np.array([p.points_m[-1] for p in specular])
    dep = np.array([p.departure for p in specular])
    order = np.array([len(p.planes) for p in specular])
    kind = np.full(len(amp), KIND["specular"])
    counts = None
    if specular[0].interactions is not None:
        counts = np.array([p.interactions for p in specular])
    paths = TracedPaths(image, np.zeros(len(amp)), amp, pos, order, kind, dep, counts)
    return paths.select(np.linalg.norm(image - emitter, axis=1) <= max_path_m * REACH)


def _on_planes(world: World, pids: np.ndarray, x: np.ndarray, tol: float) -> np.ndarray:
    """(K,) whether each point x (K, 3) lies on (or within `tol` of) one of the faces
    of its plane `pids` (K,)."""
    out = np.zeros(len(pids), bool)
    if len(pids) == 0:
        return out
    kernel = _kernels()
    if kernel is not None and _few_faces(world, pids):
        return kernel.on_planes(*_holding_args(world, pids, x, tol))
    out[_holding(world, pids, x, tol)[0]] = True
    return out


def _few_faces(world: World, pids: np.ndarray) -> bool:
    """Whether the planes `pids` have at most 20000 faces in all (every face of each
    tested: the compiled test, as :func:`_holding`'s one pass)."""
    order, starts, _ = world._plane_index()
    return int(world._cached("plane_faces", lambda: np.diff(starts))[pids].sum()) <= 20000


def _holding_args(world: World, pids: np.ndarray, x: np.ndarray, tol: float) -> tuple:
    """The arguments of :func:`.specular_kernel.on_planes` and ``holding``."""
    order, starts, _ = world._plane_index()
    return (
        np.ascontiguousarray(pids, np.int64),
        np.ascontiguousarray(x, float),
        float(tol),
        world.plane_boxes,
        order,
        starts,
        world.triangles,
        _longest_edges(world),
    )


def _holding(world: World, pids: np.ndarray, x: np.ndarray, tol: float):
    """(row, face) pairs: point x[row] lies on face `face` of its plane pids[row]
    (within `tol`).  A point whose least barycentric coordinate on a face is -m lies
    within 2 m times the face's longest edge of the face's bounding box, so only the
    faces whose box, grown by 2 tol, holds the point are tested (and none of a plane
    whose whole box does not hold it)."""
    from trimesh.triangles import points_to_barycentric

    kernel = _kernels()
    if kernel is not None and len(pids) and _few_faces(world, pids):
        return kernel.holding(*_holding_args(world, pids, x, tol))
    none = np.zeros(0, int), np.zeros(0, int)
    grow = 2.01 * tol
    box = world.plane_boxes[pids]
    inside = np.flatnonzero(np.all((box[:, 0] - grow <= x) & (x <= box[:, 1] + grow), axis=1))
    if inside.size == 0:
        return none
    order, starts, _ = world._plane_index()
    count = world._cached("plane_faces", lambda: np.diff(starts))[pids[inside]]
    if count.sum() <= 20000:  # every face of each point's plane, in one pass
        row = np.repeat(np.arange(inside.size), count)
        first = np.repeat(starts[pids[inside]] - np.cumsum(count) + count, count)
        face = order[first + np.arange(count.sum())]
    else:  # large planes: a strip of faces around each point (World.faces_near)
        rows, faces = [], []
        for pid in np.unique(pids[inside]):
            idx = np.flatnonzero(pids[inside] == pid)
            r, f = world.faces_near(int(pid), x[inside[idx]], grow)
            rows.append(idx[r])
            faces.append(f)
        row, face = np.concatenate(rows), np.concatenate(faces)
    if row.size == 0:
        return none
    tri = world.triangles[face]
    bary = points_to_barycentric(tri, x[inside[row]])
    edge = _longest_edges(world)[face]
    on = -np.min(bary, axis=1) * edge <= tol
    return inside[row[on]], face[on]


def _longest_edges(world: World) -> np.ndarray:
    """(F,) the longest edge of every face (m), found once per world."""

    def make():
        tri = world.triangles
        return np.linalg.norm(tri[:, 1:] - tri[:, :1], axis=2).max(axis=1)

    return world._cached("longest_edges", make)


def _before(points: np.ndarray, j: np.ndarray, emitter: np.ndarray, tol: float) -> np.ndarray:
    """The last point (E, 3) of each path (its reflection points (E, k, 3), emitter
    side first) before its reflection j (E,) that is not where reflection j is (the
    emitter if none): in a corner, three reflections can share one point."""
    E, k = points.shape[:2]
    rows = np.arange(E)
    gap = np.linalg.norm(points - points[rows, j][:, None], axis=2)  # (E, k)
    apart = (gap > tol) & (np.arange(k)[None, :] < j[:, None])
    last = k - 1 - np.argmax(apart[:, ::-1], axis=1)  # the last point apart, if any
    return np.where(apart.any(axis=1)[:, None], points[rows, last], emitter)


def _concave(world: World, planes: np.ndarray, x: np.ndarray, before: np.ndarray, tol):
    """(E,) whether planes a and b (planes: (E, 2)), meeting at the edge point x
    (E, 3), form a corner concave towards the side the path comes from (`before`
    (E, 3): the point before its reflection on a): a face of each that holds x
    reaches into the front of the other.  At a convex edge (a door frame's outer
    corner) the two reflections at one point are no specular path (that echo is the
    edge's diffraction)."""
    normal = _plane_table(world)[0]
    n = len(planes)
    p, q = (
        np.concatenate([planes[:, 0], planes[:, 1]]),
        np.concatenate([planes[:, 1], planes[:, 0]]),
    )
    at, come = np.concatenate([x, x]), np.concatenate([before, before])
    side = np.sign(np.einsum("ij,ij->i", normal[p], come - at))
    row, face = _holding(world, q, at, tol)
    centroid = world.triangles[face].mean(axis=1)
    reach = side[row] * np.einsum("ij,ij->i", centroid - at[row], normal[p[row]]) > tol
    good = np.zeros(2 * n, bool)
    good[row[reach]] = True
    return good[:n] & good[n:] & (side[:n] != 0) & (side[n:] != 0)


def _plane_table(world: World):
    """Per plane: normal, offset, specular pressure factor and interaction column
    (computed once per world)."""

    def make():
        first = world.plane_first
        refl = world.face_values("reflection") * np.sqrt(1 - world.face_values("diffuse"))
        column = world.face_interactions(0)
        column = None if column is None else column[first]
        return world.normals[first], world.offsets[first], refl[first], column

    return world._cached("plane_table", make)
