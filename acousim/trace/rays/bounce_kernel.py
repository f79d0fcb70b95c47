"""Compiled steps of :mod:`acousim.trace.rays.shoot` and :mod:`.scatter` (numba;
optional: without numba the same arithmetic runs in numpy there, the same numbers).

:func:`bounce`: the rays that met a face, one bounce each: where they hit, the
normal there (the face's; on a curved face the corner normals interpolated at the
hit's barycentric coordinates, as ``World.normals_at``), turned to the side the ray
came from, the mirrored direction, the power and the start of the next leg.
:func:`towards`: the scattering hits' view of the receiver (distance, direction,
cosine to the normal, whether within the path budget) and their shadow rays' starts.
"""

from __future__ import annotations

import math

from numba import njit

from acousim.trace.rays.specular_kernel import barycentric


@njit(cache=True, nogil=True, inline="always")
def _smooth_normal(tri, vn, k, x, y, z, out, i):  # pragma: no cover - compiled
    """``out[i]``: the corner normals of face k interpolated at the point (x, y, z)
    (:func:`.specular_kernel.barycentric`), made unit."""
    b0, b1, b2 = barycentric(tri, k, x, y, z)
    for c in range(3):
        out[i, c] = b0 * vn[k, 0, c] + b1 * vn[k, 1, c] + b2 * vn[k, 2, c]
    n = math.sqrt(out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1] + out[i, 2] * out[i, 2])
    for c in range(3):
        out[i, c] = out[i, c] / n


@njit(cache=True, nogil=True)
def bounce(
    alive, t, f, origin, dirs, length, power, world, lift, x, normal, mirror, power_in
):  # pragma: no cover - compiled
    """The live rays `alive` (N,) that met faces `f` (N,) at distances `t` (N,) (m):
    ``x`` (N, 3) the hits, ``normal`` (N, 3) the normals there towards the ray's
    side, ``mirror`` (N, 3) the mirrored directions, ``power_in`` (N,) the rays'
    power before the hit; then, per ray (origin, dirs (R, 3), length, power (R,)):
    length += t, power times ``reflection^2 (1 - diffuse)`` of the face, the next
    leg from x moved `lift` (m) along the normal, along the mirrored direction.
    `world`: (face normals (F, 3), curved (F,), corners (F, 3, 3), corner normals
    (F, 3, 3), reflection (F,), diffuse (F,))."""
    normals, curved, tri, vn, refl, diffuse = world
    for i in range(alive.shape[0]):
        r, k = alive[i], f[i]
        for c in range(3):
            x[i, c] = origin[r, c] + t[i] * dirs[r, c]
        length[r] += t[i]
        if curved[k]:
            _smooth_normal(tri, vn, k, x[i, 0], x[i, 1], x[i, 2], normal, i)
        else:
            for c in range(3):
                normal[i, c] = normals[k, c]
        dx, dy, dz = dirs[r, 0], dirs[r, 1], dirs[r, 2]
        if normal[i, 0] * dx + normal[i, 1] * dy + normal[i, 2] * dz > 0:
            for c in range(3):
                normal[i, c] *= -1
        s = 2 * (dx * normal[i, 0] + dy * normal[i, 1] + dz * normal[i, 2])
        mirror[i, 0], mirror[i, 1], mirror[i, 2] = (
            dx - s * normal[i, 0],
            dy - s * normal[i, 1],
            dz - s * normal[i, 2],
        )
        power_in[i] = power[r]
        power[r] = power[r] * (refl[k] ** 2 * (1 - diffuse[k]))
        for c in range(3):
            origin[r, c] = x[i, c] + lift * normal[i, c]
            dirs[r, c] = mirror[i, c]


@njit(cache=True, nogil=True)
def towards(x, normal, length, receiver, max_path_m, lift, v, r2, u, cos_s, ok, start):
    """Per scattering hit x (K, 3) with `normal` (K, 3) at path `length` (K,) (m):
    ``v`` (K, 3) the vector to the `receiver` (3,), ``r2`` (K,) its length, ``u``
    (K, 3) its direction, ``cos_s`` (K,) the cosine to the normal, ``ok`` (K,)
    facing the receiver within `max_path_m`, ``start`` (K, 3) the shadow ray's
    start, x moved `lift` (m) along the normal."""  # pragma: no cover - compiled
    for i in range(x.shape[0]):
        for c in range(3):
            v[i, c] = receiver[c] - x[i, c]
        d = math.sqrt(v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2])
        r2[i] = d
        m = max(d, 1e-12)
        for c in range(3):
            u[i, c] = v[i, c] / m
        cos_s[i] = u[i, 0] * normal[i, 0] + u[i, 1] * normal[i, 1] + u[i, 2] * normal[i, 2]
        ok[i] = cos_s[i] > 0 and length[i] + d <= max_path_m
        for c in range(3):
            start[i, c] = x[i, c] + lift * normal[i, c]
