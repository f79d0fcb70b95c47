"""Compiled steps of :func:`acousim.trace.seen.chain_points` between its rays (numba;
optional: without numba the same arithmetic runs on whole arrays in numpy there):
aiming the rays at the paths' last points (straight, or a little beside) and
keeping the object of each ray that met its point's face.  One pass over the paths
still to find, where numpy takes a dozen small array operations per aim."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def aim(last, todo, receiver, shift, out, dist):  # pragma: no cover - compiled
    """Into `out` (K, 3) the rays from `receiver` (3,) to the points ``last[todo]``
    (last (N, 3), todo (K,) int; m) moved by `shift` (3,) times one plus their
    distance, and into `dist` (K,) the rays' lengths (m): ``to + shift (1 + |to|)``,
    ``to = last - receiver`` (the operations of the array version)."""
    for k in range(todo.size):
        n = todo[k]
        tx = last[n, 0] - receiver[0]
        ty = last[n, 1] - receiver[1]
        tz = last[n, 2] - receiver[2]
        grow = 1 + math.sqrt(tx * tx + ty * ty + tz * tz)
        ax = tx + shift[0] * grow
        ay = ty + shift[1] * grow
        az = tz + shift[2] * grow
        out[k, 0], out[k, 1], out[k, 2] = ax, ay, az
        dist[k] = math.sqrt(ax * ax + ay * ay + az * az)


@njit(cache=True, nogil=True)
def accept(todo, hit, dist, tolerance, face_object, obj) -> int:  # pragma: no cover
    """The rays of the paths `todo` (K,) that met a face (`hit`: the distances (K,),
    m, inf for none, and the faces (K,), -1 for none) within `tolerance` times one
    plus their length `dist` (K,) of it: their object (``face_object`` of the face)
    into `obj` (N,); the others' paths moved to the front of `todo`, in order, and
    their count returned."""
    t, face = hit
    keep = 0
    for k in range(todo.size):
        f = face[k]
        if f >= 0 and np.abs(t[k] - dist[k]) <= tolerance * (1 + dist[k]):
            obj[todo[k]] = face_object[f]
        else:
            todo[keep] = todo[k]
            keep += 1
    return keep
