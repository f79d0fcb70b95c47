"""Stage 6 of the tracer: the energy floor.

1. The level of every path at the receiver (array centre): its pressure gain g (the
   path's energy there is g**2).
2. The direct path is always kept, and so is the strongest echo (gain ``top``); of
   the other echoes, with ``f = 10 ** (energy_floor_db / 10)``:

   * rule "path" (the default): every echo with ``g**2 < f top**2`` is dropped (each
     dropped path is weak; a crowd of them may add up to a strong echo);
   * rule "sum": the weakest echoes are dropped, weakest first, as long as their
     summed energy stays at most ``f top**2`` less what the earlier stages already
     left out (``spent``); the error the floor makes is then bounded whatever the
     number of weak paths (the dropped paths' summed energy, however they add at
     the receiver, is at most ``f top**2``; its amplitude at most ``sqrt(f) top``
     when they add incoherently).

Early pruning (a stage that leaves out candidates weaker than a gain before finding
them, :func:`early_floor`): under "path" that gain is the floor under the strongest
echo found so far (the final floor lies at or above it, so nothing kept is lost);
under "sum" a candidate may be left out only if its energy is below
``EARLY_SHARE * f top**2 / N``, N a bound of the number of candidates the stage can
leave out, so that all of them together stay under ``EARLY_SHARE * f top**2``: the
final stage then drops the weakest found paths within the rest of the budget.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from acousim.scene.model import Diffraction, FloorRule
from acousim.trace.diffraction.btm import _REFINE, DEFAULT_MAX_EXCESS_M
from acousim.trace.diffraction.pairs import BIN
from acousim.trace.diffraction.setup import DiffractingGeometry
from acousim.trace.paths import KIND, TracedPaths

__all__ = [
    "EARLY_SHARE",
    "EarlyFloor",
    "diffraction_candidates",
    "dropped_by_sum",
    "early_floor",
    "energy_floor",
]

log = logging.getLogger(__name__)

#: rule "sum": the share of the floor's energy budget that the early pruning may
#: spend (the final stage spends the rest)
EARLY_SHARE = 0.5


def energy_floor(
    paths: TracedPaths,
    receiver: np.ndarray,
    floor_db: float,
    rule: FloorRule = "path",
    spent: float = 0.0,
) -> TracedPaths:
    """The paths kept by the floor `floor_db` (negative, dB) under `rule` (module
    docstring) at `receiver` (3,); `spent`: rule "sum", the energy (a squared gain at
    the receiver) of the candidates the earlier stages left out (at most the budget
    they were given by :func:`early_floor`)."""
    if len(paths) == 0:
        return paths
    level = paths.level_at(receiver)
    echo = paths.kind != KIND["direct"]
    top = level[echo].max() if echo.any() else level.max()
    if rule == "path":
        keep = ~echo | (level >= top * 10 ** (floor_db / 20))
    elif rule == "sum":
        budget = top**2 * 10 ** (floor_db / 10) - spent
        strongest = np.flatnonzero(echo)[np.argmax(level[echo])] if echo.any() else -1
        weak = echo.copy()
        if strongest >= 0:
            weak[strongest] = False
        keep = np.ones(len(paths), bool)
        keep[np.flatnonzero(weak)[dropped_by_sum(level[weak] ** 2, budget)]] = False
    else:
        raise ValueError(f"energy floor rule: {rule!r} is not one of path, sum")
    if (~keep).any():
        log.debug("dropped %d paths under the %.0f dB %s floor", int((~keep).sum()), floor_db, rule)
    return paths.select(keep)


def dropped_by_sum(energy: np.ndarray, budget: float) -> np.ndarray:
    """Which of the paths of `energy` (N,) (squared gains) to drop: the weakest ones,
    weakest first (ties in the order given), as many as keep their sum at most
    `budget` (an empty set when it is negative).  Boolean (N,)."""
    order = np.argsort(energy, kind="stable")
    total = np.cumsum(energy[order])
    n = int(np.searchsorted(total, budget, side="right"))
    out = np.zeros(energy.size, bool)
    out[order[:n]] = True
    return out


@dataclass(frozen=True)
class EarlyFloor:
    """What a stage that prunes early may leave out: candidates whose gain at the
    receiver is below `level` (0: none); `floor_db` (dB): a floor under the stage's
    own strongest candidate it may also apply (rule "path": the final floor; rule
    "sum": none, -inf, the stage's strongest element may be hidden and only an echo
    found is a reference); `spent`: a bound of the energy (squared gain) of all it
    leaves out, for :func:`energy_floor`."""

    level: float
    floor_db: float
    spent: float


def early_floor(top: float, floor_db: float, rule: FloorRule, candidates: int) -> EarlyFloor:
    """The early floor (module docstring) under the strongest echo found so far `top`
    (a gain at the receiver, 0: none yet) of a stage that can leave out at most
    `candidates` paths, for the final floor `floor_db` (dB) under `rule`.  The final
    floor's reference, the strongest echo of the whole trace, is at least `top`;
    the level is lowered by 1e-9 relative for rounding."""
    if rule == "path":
        return EarlyFloor(top * 10 ** (floor_db / 20) * (1 - 1e-9), floor_db, 0.0)
    share = EARLY_SHARE / max(int(candidates), 1)
    level = top * 10 ** ((floor_db + 10 * np.log10(share)) / 20) * (1 - 1e-9)
    return EarlyFloor(level, -np.inf, EARLY_SHARE * top**2 * 10 ** (floor_db / 10))


def diffraction_candidates(geometry: DiffractingGeometry, settings: Diffraction) -> int:
    """A bound of the number of paths the diffraction stage can leave out for any
    pose (each BTM element of an edge is one path, and each bin of an edge pair):

    * an edge alone: 2 sides of the apex, each at most ``_REFINE + 2`` elements next to
      the apex and one per ``step_m`` of excess path up to ``DEFAULT_MAX_EXCESS_M``;
      a part per image term of a face with a table of its own (3 parts), and with
      ``reflections`` the same again per image of the emitter or the receiver in each
      plane;
    * order 2, each ordered pair of edges that share a plane (the pairs the stage
      can integrate; a pair of rims of a thin plate twice, its two sides), up to
      3 x 3 parts, one path per bin of ``BIN * step_m`` of path up to
      ``DEFAULT_MAX_EXCESS_M`` past its shortest.

    It depends on the geometry and the settings alone: found once per geometry."""
    key = f"floor_candidates {settings.step_m!r} {settings.order} {settings.reflections}"
    return int(geometry.kept(key, lambda: _candidates(geometry, settings)))


def _candidates(geometry: DiffractingGeometry, settings: Diffraction) -> int:
    edges = geometry.edges
    parts = 1 if geometry.face_column is None else 3
    per_side = _REFINE + 2 + int(np.ceil(DEFAULT_MAX_EXCESS_M / settings.step_m))
    images = 1
    if settings.reflections and geometry.planes is not None:
        images += 2 * len(geometry.planes[1])
    n = len(edges) * 2 * parts * per_side * images
    if settings.order >= 2 and geometry.face_plane is not None and len(edges):
        plane = np.asarray(geometry.face_plane, int)
        p_a = plane[edges.faces[:, 0]]
        p_b = np.where(edges.faces[:, 1] >= 0, plane[np.maximum(edges.faces[:, 1], 0)], p_a)
        rim = edges.faces[:, 1] < 0  # a pair of rims: both sides of a thin plate
        owner = np.concatenate([np.arange(len(edges)), np.flatnonzero(p_b != p_a)])
        on = np.concatenate([p_a, p_b[p_b != p_a]])
        n_on = np.bincount(on)
        rims_on = np.bincount(on, weights=rim[owner].astype(float), minlength=n_on.size)
        pairs = np.sum(n_on * (n_on - 1)) + np.sum(rims_on * np.maximum(rims_on - 1, 0))
        bins = _REFINE + 2 + int(np.ceil(DEFAULT_MAX_EXCESS_M / (BIN * settings.step_m)))
        n += int(pairs) * parts**2 * bins
    return n
