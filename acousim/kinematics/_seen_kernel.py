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
