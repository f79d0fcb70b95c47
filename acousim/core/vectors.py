"""Row lengths of (..., 3) vectors, the same bits as ``np.linalg.norm(v, axis=-1)``
about three times faster: numpy's reduction over a short last axis costs more
than the three column sums it adds up (left to right, as numpy does for fewer than
eight terms)."""

from __future__ import annotations

import numpy as np

__all__ = ["row_norms"]


def row_norms(v: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """The Euclidean length of each row of `v` (..., 3) (its units): (...), or
    (..., 1) with `keepdims`; ``np.linalg.norm(v, axis=-1, keepdims=keepdims)``
    to the bit."""
    sq = np.square(np.asarray(v, float))
    out = sq[..., 0] + sq[..., 1]
    out += sq[..., 2]
    np.sqrt(out, out=out)
    return out[..., None] if keepdims else out
