"""Compiled :func:`acousim.trace.rays.shoot.aimed` (numba; optional: without numba
the same tests run in numpy, :func:`acousim.trace.rays.shoot._aimed_numpy`, with the
same arithmetic, so the same rays).

Per ray and wanted plane sequence: the ray passes through the first plane's box
(a slab test), its mirror image in that plane through the next one's, and so on.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def aimed(emitter, dirs, seqs, lens, normal, offset, lo, hi, slack, out):  # pragma: no cover
    """Set ``out[r]`` (R,) bool for the rays r from `emitter` (3,) along `dirs`
    (R, 3) that pass through the boxes [lo, hi] (P, 3) of the planes of some
    sequence ``seqs[w, :lens[w]]`` (W, K) in turn, each from its mirror image in the
    plane before (planes n . x = offset: normal (P, 3), offset (P,)), or that run
    along a plane (|n . d| < 1e-9) after which the sequence goes on."""
    R, W = dirs.shape[0], seqs.shape[0]
    for r in range(R):
        for w in range(W):
            ox, oy, oz = emitter[0], emitter[1], emitter[2]
            dx, dy, dz = dirs[r, 0], dirs[r, 1], dirs[r, 2]
            hit = True
            for k in range(lens[w]):
                p = seqs[w, k]
                if not _through(ox, oy, oz, dx, dy, dz, lo[p], hi[p], slack):
                    hit = False
                    break
                if k + 1 == lens[w]:
                    break
                nx, ny, nz = normal[p, 0], normal[p, 1], normal[p, 2]
                dn = dx * nx + dy * ny + dz * nz
                if abs(dn) < 1e-9:  # along the plane: no mirror image to follow, kept
                    break
                t = (offset[p] - (ox * nx + oy * ny + oz * nz)) / dn
                ox, oy, oz = ox + t * dx, oy + t * dy, oz + t * dz
                dx, dy, dz = dx - 2 * dn * nx, dy - 2 * dn * ny, dz - 2 * dn * nz
            if hit:
                out[r] = True
                break


@njit(cache=True, nogil=True, inline="always")
def _through(ox, oy, oz, dx, dy, dz, lo, hi, slack):  # pragma: no cover - compiled
    """Whether the ray o + t d, t >= -slack, passes through the box [lo, hi] (3,)."""
    enter, leave = _slab(ox, dx, lo[0], hi[0], -np.inf, np.inf)
    enter, leave = _slab(oy, dy, lo[1], hi[1], enter, leave)
    enter, leave = _slab(oz, dz, lo[2], hi[2], enter, leave)
    return leave >= enter and leave >= -slack


@njit(cache=True, nogil=True, inline="always")
def _slab(o, d, lo, hi, enter, leave):  # pragma: no cover - compiled
    """(enter, leave) narrowed to where o + t d lies in [lo, hi] along one axis."""
    inv = 1.0 / (d if d != 0.0 else 1e-300)
    t1, t2 = (lo - o) * inv, (hi - o) * inv
    return max(enter, min(t1, t2)), min(leave, max(t1, t2))
