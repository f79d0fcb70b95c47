"""Compiled preparation of the rays :class:`acousim.trace.world.embree.RayCaster`
casts (``first_hit``, ``occluded``; numba; optional: without numba the same
arithmetic runs in numpy there).

Each ray in one pass: its origin relative to the caster's centre and its direction
made unit, both in float64 and then rounded to Embree's float32 (the sum of squares
in the order x, y, z, as numpy's reduction of three numbers sums them).
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def prepare(origins, directions, centre, o32, d32):  # pragma: no cover - compiled
    """``o32`` (N, 3) float32: `origins` (N, 3) less `centre` (3,); ``d32`` (N, 3)
    float32: `directions` (N, 3) over their length (a zero direction left zero)."""
    for i in range(origins.shape[0]):
        for c in range(3):
            o32[i, c] = origins[i, c] - centre[c]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        norm = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not norm > 0:
            norm = 1.0
        d32[i, 0], d32[i, 1], d32[i, 2] = dx / norm, dy / norm, dz / norm
