"""The diffraction stage's paths (:class:`DiffractedPaths`) and how they are put
together: from edge elements, empty, one after the other."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.trace.diffraction.btm import EdgeElements

__all__ = ["DiffractedPaths", "concatenate", "element_paths", "empty_paths", "ELEMENT_FIELDS"]

#: the fields of :class:`acousim.trace.diffraction.btm.EdgeElements`, in order
ELEMENT_FIELDS = ("point_m", "first_leg_m", "second_leg_m", "amplitude")
_PATH_FIELDS = ("anchor_m", "first_leg_m", "strength", "position_m", "departure", "edge", "order")


@dataclass(frozen=True, eq=False)
class DiffractedPaths:
    """N diffraction paths in the tracer's path form (world frame, metres)."""

    anchor_m: np.ndarray
    """(N, 3) the element's point on the edge (or, for a reflection after the edge,
    its image), m."""
    first_leg_m: np.ndarray
    """(N,) path length from the emitter (or its image) to the element, m."""
    strength: np.ndarray
    """(N,) signed: the gain at a microphone p is ``strength / |anchor - p|``, m."""
    position_m: np.ndarray
    """(N, 3) the element's point on the edge, m."""
    departure: np.ndarray
    """(N, 3) unit direction leaving the emitter."""
    edge: np.ndarray
    """(N,) int, index into the Edges."""
    order: np.ndarray
    """(N,) int, interactions (1: the edge alone, 2: a reflection and the edge, or two
    edges)."""
    counts: np.ndarray | None = None
    """(N, K) int, the path's interactions with frequency-dependent materials (a
    face's image term, a reflection before or after the edge; K = 0 without tables)."""

    def __post_init__(self):
        if self.counts is None:
            object.__setattr__(self, "counts", np.zeros((self.strength.size, 0), int))

    def __len__(self) -> int:
        return self.strength.size


def empty_paths() -> DiffractedPaths:
    """No paths."""
    z3, z = np.zeros((0, 3)), np.zeros(0)
    return DiffractedPaths(z3, z, z, z3, z3, np.zeros(0, int), np.zeros(0, int))


def concatenate(parts: list[DiffractedPaths]) -> DiffractedPaths:
    """The paths of `parts` one after the other (their counts padded to the widest)."""
    parts = [p for p in parts if len(p)]
    if not parts:
        return empty_paths()
    k = max(p.counts.shape[1] for p in parts)
    counts = np.concatenate([_widened(p.counts, k) for p in parts])
    fields = (np.concatenate([getattr(p, f) for p in parts]) for f in _PATH_FIELDS)
    return DiffractedPaths(*fields, counts)


def _widened(counts: np.ndarray, k: int) -> np.ndarray:
    """counts (N, C) padded with zero columns to (N, k)."""
    if counts.shape[1] == k:
        return counts
    out = np.zeros((counts.shape[0], k), counts.dtype)
    out[:, : counts.shape[1]] = counts
    return out


def element_paths(
    el: EdgeElements, owner: np.ndarray, ok: np.ndarray, source: np.ndarray, counts=None
) -> DiffractedPaths:
    """First-order paths of the elements `el` (of edges `owner` (K,)) where `ok` (K,):
    anchor on the edge, first leg from `source` (3,); counts (K, C) or None."""
    k = np.flatnonzero(ok)
    points = np.take(el.point_m, k, axis=0)  # (faster than indexing)
    dep = points - source
    dep /= np.maximum(np.linalg.norm(dep, axis=1, keepdims=True), 1e-12)
    return DiffractedPaths(
        points,
        el.first_leg_m[k],
        el.amplitude[k] * el.second_leg_m[k],
        points,
        dep,
        owner[k],
        np.full(k.size, 1),
        None if counts is None else counts[k],
    )


def select_elements(el: EdgeElements, keep: np.ndarray) -> EdgeElements:
    """The elements of `el` where `keep` (a mask or indices)."""
    return EdgeElements(*(getattr(el, f)[keep] for f in ELEMENT_FIELDS))
