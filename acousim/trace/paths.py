"""Traced paths: the one form every stage of the tracer hands to the renderer.

A path's length to microphone p is ``first_leg + |anchor - p|`` and its pressure gain
``strength / |anchor - p|``: an image source has first_leg 0, a scatterer or an explicit
point sits at its position with first_leg the way there from the emitter, an edge
element (diffraction) on its edge.  Strengths are signed (edge elements may be
negative); levels compare magnitudes.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from enum import IntEnum

import numpy as np

from acousim.core.echoes import Echoes, last_legs, spread

__all__ = ["KIND", "PathKind", "TracedPaths", "kind_names", "reaching"]


class PathKind(IntEnum):
    """What made a path (the ``kind`` code of :class:`TracedPaths`); the names are
    those of a recording's ground truth (``PathKind(code).name``)."""

    direct = 0
    specular = 1
    scatter = 2
    point = 3
    diffraction = 4


#: the path kinds by name (``KIND["specular"]``, ``KIND.specular``)
KIND = PathKind
_NAMES = tuple(k.name for k in PathKind)


def kind_names(codes: np.ndarray) -> list[str]:
    """The names of :class:`PathKind` `codes` (N,)."""
    return [_NAMES[c] for c in codes.tolist()]


@dataclass(frozen=True, eq=False)
class TracedPaths:
    """Every path of one pose (world frame).  N paths; anchor, first leg and strength
    as in the module docstring."""

    anchor_m: np.ndarray
    """(N, 3) the image source, scatterer, point or edge element, m."""
    first_leg_m: np.ndarray
    """(N,) path length from the emitter to the anchor, m (0 for an image source)."""
    strength: np.ndarray
    """(N,) signed pressure gain times the last leg's length, m."""
    position_m: np.ndarray
    """(N, 3) where the echo comes from (last reflection point, scatterer position,
    point reflector, the emitter for the direct path), m."""
    order: np.ndarray
    """(N,) int, reflections."""
    kind: np.ndarray
    """(N,) int, :class:`PathKind` codes."""
    departure: np.ndarray
    """(N, 3) unit direction leaving the emitter."""
    interactions: np.ndarray | None = None
    """(N, K) int, how often the path met each frequency-dependent material
    interaction (:class:`acousim.core.materials.MaterialSpectra` columns; K = 0, the
    default, in a scene without material tables); its strength holds the reference
    gains, the renderer applies the rest."""

    def __post_init__(self) -> None:
        if self.interactions is None:
            object.__setattr__(self, "interactions", np.zeros((self.strength.size, 0), int))

    def __len__(self) -> int:
        return self.strength.size

    def echoes(
        self, mics_world: np.ndarray, emitter_axis: np.ndarray, speed_of_sound_m_s: float
    ) -> Echoes:
        """Delays and gains at microphones (M, 3) in the world frame (the last leg's
        spreading: :func:`acousim.core.echoes.spread`)."""
        delay, gain, length = spread(
            self.anchor_m, self.first_leg_m, self.strength, mics_world, speed_of_sound_m_s
        )
        cos = np.clip(self.departure @ emitter_axis, -1, 1)
        counts = self.interactions if self.interactions.shape[1] else None
        return Echoes(delay, gain, length, self.order.copy(), np.arccos(cos), counts)

    def level_at(self, point: np.ndarray) -> np.ndarray:
        """Magnitude of the pressure gain (N,) of every path at one point (the array
        centre)."""
        return np.abs(self.strength) / np.maximum(
            np.linalg.norm(self.anchor_m - point, axis=1), 1e-6
        )

    def select(self, keep: np.ndarray | slice) -> TracedPaths:
        """The paths at `keep`: indices (K,), a mask (N,) or a slice (the same as
        indexing every array with it; np.take gathers rows faster)."""
        if isinstance(keep, np.ndarray) and keep.ndim == 1:
            if keep.dtype == bool:
                if keep.size != len(self):
                    raise IndexError(f"mask of {keep.size} for {len(self)} paths")
                keep = np.flatnonzero(keep)
            if keep.dtype.kind in "iu":
                return TracedPaths(*(np.take(getattr(self, n), keep, axis=0) for n in _FIELDS))
        return TracedPaths(*(getattr(self, n)[keep] for n in _FIELDS))

    @staticmethod
    def concatenate(parts: list[TracedPaths]) -> TracedPaths:
        if not parts:
            return TracedPaths.empty()
        names = [f.name for f in fields(TracedPaths) if f.name != "interactions"]
        k = max(p.interactions.shape[1] for p in parts)
        counts = [_widened(p.interactions, k) for p in parts]
        return TracedPaths(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in names),
            np.concatenate(counts),
        )

    @staticmethod
    def empty() -> TracedPaths:
        z3, z = np.zeros((0, 3)), np.zeros(0)
        return TracedPaths(z3, z, z, z3, np.zeros(0, int), np.zeros(0, int), z3)


_FIELDS = tuple(f.name for f in fields(TracedPaths))


def _widened(counts: np.ndarray, k: int) -> np.ndarray:
    """Interaction counts (N, K') with zero columns up to K = `k` (as they are when
    K' = K)."""
    if counts.shape[1] == k:
        return counts
    out = np.zeros((counts.shape[0], k), counts.dtype)
    out[:, : counts.shape[1]] = counts
    return out


def reaching(paths, mics_m: np.ndarray, min_path_m: float) -> np.ndarray:
    """The paths (indices) at least `min_path_m` long (m) to some microphone (M, 3):
    their length ``first_leg + |anchor - mic|`` (:class:`TracedPaths`, or
    :class:`~acousim.trace.motion.following.MovingPaths` where they are at the start
    of the emission)."""
    last = last_legs(paths.anchor_m, mics_m)  # (M, N)
    return np.flatnonzero(paths.first_leg_m + last.max(axis=0) >= min_path_m)
