"""Compiled geometry of :mod:`acousim.trace.rays.specular` (numba; optional: without
numba the same steps run in numpy there, with the same arithmetic to rounding).

Per plane sequence, with no ray: its image sources and whether the last is within
reach (:func:`images`), and one backward step of its reflection points
(:func:`step`); per point, whether it lies on a face of its plane (:func:`on_planes`,
:func:`holding`, the barycentric test of trimesh's ``points_to_barycentric``).
The rays themselves are cast by the caller (Embree).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def images(ids, emitter, normal, offset, reach, out):  # pragma: no cover - compiled
    """The image sources ``out`` (S, k + 1, 3) of the sequences `ids` (S, k) of
    planes n . x = offset (normal (P, 3), offset (P,)): the emitter (3,) mirrored
    across each plane in turn; returns (S,) bool: the last image within `reach` (m)
    of the emitter (all when `reach` is inf)."""
    S, k = ids.shape
    ok = np.ones(S, np.bool_)
    for s in range(S):
        x, y, z = emitter[0], emitter[1], emitter[2]
        out[s, 0, 0], out[s, 0, 1], out[s, 0, 2] = x, y, z
        for j in range(k):
            p = ids[s, j]
            nx, ny, nz = normal[p, 0], normal[p, 1], normal[p, 2]
            a = 2 * ((x * nx + y * ny + z * nz) - offset[p])
            x, y, z = x - a * nx, y - a * ny, z - a * nz
            out[s, j + 1, 0], out[s, j + 1, 1], out[s, j + 1, 2] = x, y, z
        dx, dy, dz = x - emitter[0], y - emitter[1], z - emitter[2]
        ok[s] = math.sqrt(dx * dx + dy * dy + dz * dz) <= reach
    return ok


@njit(cache=True, nogil=True)
def step(
    planes, image, cur, ok, normal, offset, boxes, tol, eps, inner, x, start, at_edge
):  # pragma: no cover - compiled
    """One backward step of the reflection points, S sequences at once: the point
    ``x`` (S, 3) where the line from `cur` (S, 3) to the `image` (S, 3) meets the
    plane ``planes`` (S,), ``start`` (S, 3) of the leg to check (`cur`, moved `eps`
    towards x when `inner`: cur is a reflection point) and ``at_edge`` (S,) (x on
    cur, within `tol`, and `inner`); `ok` (S,) cleared for the rows whose line
    misses the plane (parallel, behind cur, past the image) or whose point lies off
    the plane's box (P, 2, 3) grown by 2.01 `tol` (the rows refused already: x and
    start at cur, not at an edge)."""
    grow = 2.01 * tol
    lift = eps if inner else 0.0
    for s in range(planes.shape[0]):
        cx, cy, cz = cur[s, 0], cur[s, 1], cur[s, 2]
        if not ok[s]:  # refused already: nothing to find (x and start left at cur)
            x[s, 0], x[s, 1], x[s, 2] = cx, cy, cz
            start[s, 0], start[s, 1], start[s, 2] = cx, cy, cz
            at_edge[s] = False
            continue
        p = planes[s]
        nx, ny, nz = normal[p, 0], normal[p, 1], normal[p, 2]
        dx, dy, dz = image[s, 0] - cx, image[s, 1] - cy, image[s, 2] - cz
        denom = dx * nx + dy * ny + dz * nz
        safe = 1.0 if abs(denom) < 1e-12 else denom
        t = (offset[p] - (cx * nx + cy * ny + cz * nz)) / safe
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        good = abs(denom) >= 1e-12 and t * length > -tol and t < 1
        tp = max(t, 0.0)
        px, py, pz = cx + tp * dx, cy + tp * dy, cz + tp * dz
        x[s, 0], x[s, 1], x[s, 2] = px, py, pz
        good = (
            good
            and boxes[p, 0, 0] - grow <= px <= boxes[p, 1, 0] + grow
            and boxes[p, 0, 1] - grow <= py <= boxes[p, 1, 1] + grow
            and boxes[p, 0, 2] - grow <= pz <= boxes[p, 1, 2] + grow
        )
        ok[s] = good
        at_edge[s] = tp * length <= tol and inner
        m = max(length, 1e-300)
        start[s, 0] = cx + lift * (dx / m)
        start[s, 1] = cy + lift * (dy / m)
        start[s, 2] = cz + lift * (dz / m)


@njit(cache=True, nogil=True, inline="always")
def _in_box(boxes, p, x, grow):  # pragma: no cover - compiled
    """Whether x (3,) lies in the box of plane p, grown by `grow` (m)."""
    for c in range(3):
        if not (boxes[p, 0, c] - grow <= x[c] <= boxes[p, 1, c] + grow):
            return False
    return True


@njit(cache=True, nogil=True, inline="always")
def barycentric(tri, k, x, y, z):  # pragma: no cover - compiled
    """The barycentric coordinates (b0, b1, b2) of the point (x, y, z) on face k's
    plane (trimesh's Cramer solution, its operations in its order)."""
    ax, ay, az = tri[k, 0, 0], tri[k, 0, 1], tri[k, 0, 2]
    e0x, e0y, e0z = tri[k, 1, 0] - ax, tri[k, 1, 1] - ay, tri[k, 1, 2] - az
    e1x, e1y, e1z = tri[k, 2, 0] - ax, tri[k, 2, 1] - ay, tri[k, 2, 2] - az
    wx, wy, wz = x - ax, y - ay, z - az
    d00 = e0x * e0x + e0y * e0y + e0z * e0z
    d01 = e0x * e1x + e0y * e1y + e0z * e1z
    d02 = e0x * wx + e0y * wy + e0z * wz
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d12 = e1x * wx + e1y * wy + e1z * wz
    inv = 1.0 / (d00 * d11 - d01 * d01)
    b2 = (d00 * d12 - d01 * d02) * inv
    b1 = (d11 * d02 - d01 * d12) * inv
    return 1 - b1 - b2, b1, b2


@njit(cache=True, nogil=True, inline="always")
def _off_face(tri, face, x, y, z, longest):  # pragma: no cover - compiled
    """How far (m, about) the point lies outside face `face`: minus its least
    barycentric coordinate times the longest edge."""
    b0, b1, b2 = barycentric(tri, face, x, y, z)
    return -min(b0, min(b1, b2)) * longest[face]


@njit(cache=True, nogil=True)
def on_planes(pids, x, tol, boxes, order, starts, tri, longest):  # pragma: no cover
    """(K,) bool: whether each point x (K, 3) lies on (within `tol` of) a face of its
    plane ``pids`` (K,) (none if off the plane's box (P, 2, 3) grown by 2.01 `tol`;
    the faces of plane p: ``order[starts[p]:starts[p + 1]]``; tri: corners (F, 3, 3);
    longest: each face's longest edge (F,))."""
    K = pids.shape[0]
    out = np.zeros(K, np.bool_)
    for i in range(K):
        p = pids[i]
        if not _in_box(boxes, p, x[i], 2.01 * tol):
            continue
        for q in range(starts[p], starts[p + 1]):
            if _off_face(tri, order[q], x[i, 0], x[i, 1], x[i, 2], longest) <= tol:
                out[i] = True
                break
    return out


@njit(cache=True, nogil=True)
def holding(pids, x, tol, boxes, order, starts, tri, longest):  # pragma: no cover
    """The (row, face) pairs, rows ascending and each row's faces in `order`: point
    x[row] lies on (within `tol` of) face `face` of its plane pids[row]
    (arguments as :func:`on_planes`)."""
    K = pids.shape[0]
    total = 0
    for i in range(K):
        total += starts[pids[i] + 1] - starts[pids[i]]
    rows = np.empty(total, np.int64)
    faces = np.empty(total, np.int64)
    n = 0
    for i in range(K):
        p = pids[i]
        if not _in_box(boxes, p, x[i], 2.01 * tol):
            continue
        for q in range(starts[p], starts[p + 1]):
            face = order[q]
            if _off_face(tri, face, x[i, 0], x[i, 1], x[i, 2], longest) <= tol:
                rows[n], faces[n] = i, face
                n += 1
    return rows[:n], faces[:n]
