"""Stage 6 of the tracer: the energy floor.

1. The level of every path at the receiver (array centre).
2. Echoes (every path but the direct one) weaker than ``energy_floor_db`` below the
   strongest echo are dropped; the direct path is always kept.
"""

from __future__ import annotations

import logging

import numpy as np

from acousim.trace.paths import KIND, TracedPaths

__all__ = ["energy_floor"]

log = logging.getLogger(__name__)


def energy_floor(paths: TracedPaths, receiver: np.ndarray, floor_db: float) -> TracedPaths:
    """The paths within `floor_db` (negative, dB) of the strongest echo at `receiver`."""
    if len(paths) == 0:
        return paths
    level = paths.level_at(receiver)
    echo = paths.kind != KIND["direct"]
    top = level[echo].max() if echo.any() else level.max()
    keep = ~echo | (level >= top * 10 ** (floor_db / 20))
    if (~keep).any():
        log.debug("dropped %d paths below the %.0f dB energy floor", int((~keep).sum()), floor_db)
    return paths.select(keep)
