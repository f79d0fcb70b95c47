"""Compiled helper of :class:`processing.imaging.steering.CoarrayKernel` (numba; optional).

:func:`floor_invert` raises every element of a block to at least `floor` and, for
MUSIC and Capon, replaces it by its reciprocal, in one pass over the block while
it is in cache (numpy needs two ufunc passes, ``maximum`` and ``divide``).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, error_model="numpy")
def floor_invert(block, floor, invert):
    """In place on a C-contiguous 2D float64 block: ``max(x, floor)``, then ``1 / x``
    when `invert`."""
    flat = block.reshape(-1)
    if invert:
        for i in range(flat.size):
            v = flat[i]
            flat[i] = 1.0 / max(v, floor)
    else:
        for i in range(flat.size):
            v = flat[i]
            flat[i] = max(v, floor)
