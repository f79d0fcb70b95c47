"""Compiled reception times at the moving array centre (numba; optional: without
numba :func:`acousim.kinematics.seen.seen_moving` iterates on whole arrays in numpy,
the same operations in the same order)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def centre_times(
    t, t_r, anchor, local, times, rows, c, stop, iterations, rot, where
):  # pragma: no cover - compiled
    """The fixed point ``t = t_r + |R(t) local + p(t) - A| / c`` of every path, in
    place on `t` (N,) (s), iterated until no time changes by `stop` (s) or more (at
    most `iterations` times); into `rot` (N, 3, 3) and `where` (N, 3) the rotation
    and the centre's position (world, ``R local + p``) at the times before the last
    iteration.

    t_r (N,): when the sound leaves the anchors `anchor` (N, 3) (s, m); local (3,):
    the centre, sensor frame (m); times (K,) (s, evenly spaced) and rows (K, 12):
    the rotations (9, row-major) and positions (3) tabulated there, interpolated
    linearly.
    """
    N = t.size
    K = times.size
    h = times[1] - times[0]
    new = np.empty(N)
    for _ in range(iterations):
        done = True
        for n in range(N):
            x = (t[n] - times[0]) / h
            i = min(max(int(np.floor(x)), 0), K - 2)
            w = x - i
            for j in range(3):
                for k in range(3):
                    rot[n, j, k] = rows[i, 3 * j + k] * (1 - w) + rows[i + 1, 3 * j + k] * w
            d2 = 0.0
            for j in range(3):
                p = rows[i, 9 + j] * (1 - w) + rows[i + 1, 9 + j] * w
                pos = rot[n, j, 0] * local[0] + rot[n, j, 1] * local[1] + rot[n, j, 2] * local[2]
                where[n, j] = pos + p  # the centre, world
                d = where[n, j] - anchor[n, j]
                d2 += d * d
            new[n] = t_r[n] + np.sqrt(d2) / c
            if not abs(new[n] - t[n]) < stop:
                done = False
        t[:] = new
        if done:
            break


@njit(cache=True, nogil=True, error_model="numpy")
def centre_seen(t, t_r, anchor, local, table, c, pose, out):  # pragma: no cover - compiled
    """:func:`centre_times` (`table`: its times and rows; `c`: the speed of sound
    (m/s); the stop and iterations as :data:`acousim.kinematics.seen._CONVERGED`),
    then what the sensor sees of each path (:func:`acousim.kinematics.seen._seen`,
    the same operations): into `out` the arrival directions (N, 3) (unit, the
    sensor's frame at the reception), the apparent positions in that frame (N, 3)
    (``local + u c t / 2``, m) and in the world through `pose` (its rotation (3, 3)
    and position (3,): ``R x + p``, m)."""
    times, rows, stop, iterations = table
    R, p = pose
    u, app, world = out
    N = t.size
    rot, where = np.empty((N, 3, 3)), np.empty((N, 3))
    centre_times(t, t_r, anchor, local, times, rows, c, stop, iterations, rot, where)
    for n in range(N):
        d0 = anchor[n, 0] - where[n, 0]
        d1 = anchor[n, 1] - where[n, 1]
        d2 = anchor[n, 2] - where[n, 2]
        norm = max(np.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-300)
        d0, d1, d2 = d0 / norm, d1 / norm, d2 / norm
        half = 0.5 * c * t[n]
        for i in range(3):  # R(t)^T: the world's direction in the sensor's frame then
            u[n, i] = rot[n, 0, i] * d0 + rot[n, 1, i] * d1 + rot[n, 2, i] * d2
            app[n, i] = local[i] + u[n, i] * half
        for i in range(3):
            world[n, i] = R[i, 0] * app[n, 0] + R[i, 1] * app[n, 1] + R[i, 2] * app[n, 2] + p[i]
