"""The automatic ray budget: how much ray work a pose needs, found rather than guessed.

The rays serve two stages: they find candidate plane sequences for the exact
specular stage (:mod:`.specular`), and their hits on rough or curved faces make the
diffuse tail (:mod:`.scatter`).  First-order glints (:mod:`.glints`), edge
diffraction and explicit points need no rays.  So, per pose (:func:`ray_work`):

1. Plan (:func:`plan`).  Where the planes are few (at most :data:`ENUMERATE_MAX`
   sequences), every sequence of up to ``bounces`` planes (no plane twice in a row)
   goes to the specular stage: image sources with their visibility checks, which no
   ray can miss, whatever their departure (the emitter's directivity weighs them;
   ``beam_deg`` bounds only the rays).  The rays are then needed only if some hit
   can scatter: a material with a diffuse part, or a curved surface met from the
   second reflection on.  A scene that needs neither (the shoebox, the sphere, the
   wall) shoots no ray at all.
2. Otherwise the rays are the deterministic spiral of :func:`.shoot.cone_directions`
   (no random choice: the same rays as a scene whose ``rays`` is that number),
   :data:`START_RAYS` first, then twice as many, and so on, until two successive
   spirals agree: the larger found no new specular path (when the rays find them:
   its new plane sequences are refined at once, and only those that make a path
   are kept) and no curved surface's glint of a higher order (a new surface and
   order among the lobes of :mod:`.scatter`), and the diffuse (Lambert) tail's
   energy in every range bin of :data:`TAIL_BIN_M` holding at least
   ``10^(-TAIL_SPAN_DB/10)`` of the strongest bin's energy moved by less than
   :data:`TAIL_TOLERANCE_DB`; or until the next spiral would pass ``rays_max``.  The
   larger spiral's paths are kept (its rays are what the recording's metadata
   reports); the doubling costs at most as many rays again.

Why these numbers: the spiral's error in a bin's energy falls about as fast as the
rays grow, so when n and 2 n rays agree to 0.25 dB the 2 n estimate is about that
close to its limit, leaving room within the 0.5 dB asked of the tail against ten
times the old fixed budgets (`tests/test_budget.py`), whose own estimate is off by
0.1 to 0.4 dB (the corridor at 20,000 against 50,000 rays).  Bins 20 dB under the
strongest carry a hundredth of its energy: a few rays reach them, their estimate
moves by decibels from one spiral to the next, and they change no image.  1000 rays
is the fewest at which the corridor's strongest bins are within a few tenths of a dB.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .embree import RayCaster
from .geometry import World
from .scatter import Contributions, scatter
from .settings import TraceSettings
from .shoot import shoot
from .specular import refine_sequences

__all__ = [
    "ENUMERATE_MAX",
    "START_RAYS",
    "TAIL_BIN_M",
    "TAIL_SPAN_DB",
    "TAIL_TOLERANCE_DB",
    "RayWork",
    "all_sequences",
    "n_sequences",
    "plan",
    "ray_work",
    "lobes",
    "tail_agrees",
    "tail_energy",
]

log = logging.getLogger(__name__)

#: rays of the automatic budget's first spiral (then doubled)
START_RAYS = 1000
#: range bins (m) in which the diffuse tail's energy must have converged
TAIL_BIN_M = 0.5
#: ... two spirals, one of twice the rays of the other, agreeing to this (dB)
TAIL_TOLERANCE_DB = 0.25
#: ... in the bins holding at least this share (dB) of the strongest bin's energy
TAIL_SPAN_DB = 20.0
#: enumerate every plane sequence (no rays for the specular stage) up to this many
ENUMERATE_MAX = 20000


@dataclass(frozen=True, eq=False)
class RayWork:
    """What the rays of one pose gave: the candidate plane sequences for the exact
    specular stage (tuples, or arrays by length: :func:`.specular.refine_sequences`),
    the scattered contributions at the receiver (None: none), and the
    number of rays shot."""

    sequences: list[tuple[int, ...]] | dict[int, np.ndarray]
    contributions: Contributions | None
    rays: int


def _planar_planes(world: World) -> np.ndarray:
    return world._cached("planar_planes", lambda: np.unique(world.plane[~world.curved]))


def n_sequences(world: World, bounces: int) -> int:
    """How many sequences of up to `bounces` planar planes there are (no plane twice
    in a row): P (1 + (P - 1) + ... + (P - 1)^(bounces - 1))."""
    p = len(_planar_planes(world))
    return int(sum(p * (p - 1) ** k for k in range(bounces)))


def plan(world: World, settings: TraceSettings) -> tuple[bool, bool]:
    """(enumerate, tail): whether every plane sequence goes to the specular stage
    (at most :data:`ENUMERATE_MAX` of them), and whether some hit can scatter (a
    material with a diffuse part, or a curved face reached by a second reflection)."""
    enumerate_all = n_sequences(world, settings.bounces) <= ENUMERATE_MAX
    diffuse = bool(np.any(world.face_values("diffuse") > 0))
    lobes = bool(world.curved.any()) and settings.bounces >= 2
    return enumerate_all, diffuse or lobes


def all_sequences(world: World, bounces: int) -> dict[int, np.ndarray]:
    """Every sequence of 1 to `bounces` planar planes, no plane twice in a row, as
    arrays (S, k) of plane ids by length k, each sorted (computed once per world and
    `bounces`)."""
    return world._cached(("sequences", bounces), lambda: _sequences(world, bounces))


def _sequences(world: World, bounces: int) -> dict[int, np.ndarray]:
    planes = _planar_planes(world)
    out = {1: planes[:, None]}
    for k in range(2, bounces + 1):
        prev = out[k - 1]
        longer = np.repeat(prev, len(planes), axis=0)
        last = np.tile(planes, len(prev))
        keep = longer[:, -1] != last
        out[k] = np.column_stack([longer[keep], last[keep]])
    for rows in out.values():
        rows.flags.writeable = False
    return {k: v for k, v in out.items() if len(v)}


def tail_energy(c: Contributions | None) -> np.ndarray:
    """Energy (intensity at the receiver, 1/m^2) of the diffuse (Lambert) tail per
    range bin of :data:`TAIL_BIN_M` (range: half the path length)."""
    if c is None or len(c) == 0:
        return np.zeros(0)
    rng = (c.first_leg_m[c.lambert] + c.last_leg_m[c.lambert]) / 2
    return np.bincount((rng // TAIL_BIN_M).astype(int), c.intensity[c.lambert])


def lobes(c: Contributions | None) -> set[tuple[int, int]]:
    """The curved surfaces' glints from the second reflection on that the rays
    found (lobes: ``lambert`` false), as (surface, order) pairs."""
    if c is None or len(c) == 0:
        return set()
    return set(zip(c.surface[~c.lambert].tolist(), c.order[~c.lambert].tolist()))


def _valid(world, caster, sequences, emitter, receiver) -> set[tuple[int, ...]]:
    """The sequences among `sequences` that make a specular path (:mod:`.specular`)."""
    paths = refine_sequences(world, caster, sorted(sequences), emitter, receiver)
    return {p.planes for p in paths}


def tail_agrees(energy: np.ndarray, before: np.ndarray) -> bool:
    """Whether two estimates of the tail's energy per bin agree within
    :data:`TAIL_TOLERANCE_DB` in every bin holding at least ``10^(-TAIL_SPAN_DB/10)``
    of the strongest bin's energy in either (module docstring)."""
    width = max(len(energy), len(before))
    a, b = np.pad(energy, (0, width - len(energy))), np.pad(before, (0, width - len(before)))
    top = max(a.max(initial=0.0), b.max(initial=0.0))
    if top == 0:
        return True
    strong = np.maximum(a, b) >= top * 10 ** (-TAIL_SPAN_DB / 10)
    lo, hi = np.minimum(a, b)[strong], np.maximum(a, b)[strong]
    return bool(np.all(hi <= lo * 10 ** (TAIL_TOLERANCE_DB / 10)))


def ray_work(
    world: World,
    caster: RayCaster,
    settings: TraceSettings,
    emitter: np.ndarray,
    receiver: np.ndarray,
    axis: np.ndarray,
) -> RayWork:
    """The automatic budget of one pose (module docstring)."""
    enumerate_all, tail = plan(world, settings)
    every = all_sequences(world, settings.bounces) if enumerate_all else None
    if enumerate_all and not tail:
        return RayWork(every, None, 0)
    n, before, shot_rays = min(START_RAYS, settings.rays_max), None, 0
    tried, sequences, glints = set(), set(), set()
    while True:
        shot = shoot(
            world,
            caster,
            emitter,
            axis,
            n,
            settings.bounces,
            settings.beam_rad,
            settings.max_path_m,
        )
        shot_rays += n
        found = set()
        if not enumerate_all:  # the rays find the plane sequences: keep the paths
            found = _valid(world, caster, set(shot.sequences) - tried, emitter, receiver)
            tried |= set(shot.sequences)
            sequences |= found
        contributions = scatter(world, caster, shot.hits, receiver, settings.max_path_m)
        energy = tail_energy(contributions) if tail else np.zeros(0)
        new_lobes = lobes(contributions) - glints
        glints |= new_lobes
        settled = before is not None and not (found or new_lobes) and tail_agrees(energy, before)
        if settled or 2 * n > settings.rays_max:
            break
        n, before = 2 * n, energy
    log.debug("automatic budget: %d rays (%d shot in all)", n, shot_rays)
    return RayWork(every if enumerate_all else sorted(sequences), contributions, n)
