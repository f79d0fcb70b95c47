"""The rays of one emission, shot once and shared by every receiver that hears it.

A rig's call is traced once per sonar that hears it (its own microphones, and
those of another sonar: a bistatic trace, :mod:`acousim.rig`), each trace from the
same emitter at the same instant.  The rays (stage 1, :mod:`.shoot`) depend on the
emitter alone: their directions, hits, powers and plane sequences.  What depends on
the receiver is what the tracer does with them: the automatic budget's stopping
test, the scattering towards the receiver, the specular refinement, the glints and
the diffraction.  So an :class:`Emission` keeps each batch of rays it was asked for,
followed once up to the longest path of the scene, and hands every trace the batch
cut to that trace's own path budget (:func:`cut`): the same hits, in the same order,
and the same plane sequences as rays followed with that budget (a call heard late
in another sonar's window is traced only as far as it can be heard).  Every
receiver's trace is thus the one it would be alone (byte for byte), while the rays
are shot once per emission instead of once per receiver.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from acousim.core.cache import LruCache
from acousim.trace.rays.shoot import Hits, Shot, _unique_rows, follow
from acousim.trace.world.build import World
from acousim.trace.world.embree import RayCaster

__all__ = ["Emission", "cut"]

#: batches kept per emission (the automatic budget stops long before)
_BATCHES = 64


class Emission:
    """The rays shot from one emitter position (world frame, (3,)) into a world:
    each batch (the same directions and power) followed once up to `max_path_m` (m)
    for `bounces` reflections, and cut to the budget of each trace that asks for it."""

    def __init__(
        self,
        world: World,
        caster: RayCaster,
        emitter: np.ndarray,
        *,
        bounces: int,
        max_path_m: float,
    ) -> None:
        self.world, self.caster = world, caster
        self.emitter = np.array(emitter, float)
        self.bounces, self.max_path_m = int(bounces), float(max_path_m)
        self._shots = LruCache(_BATCHES)
        #: batches followed (for tests and benchmarks: the rest were shared)
        self.followed = 0

    def shot(self, dirs: np.ndarray, d_omega: float, *, bounces: int, max_path_m: float) -> Shot:
        """The rays in directions `dirs` (R, 3), each of solid angle `d_omega` (sr),
        as :func:`~acousim.trace.rays.shoot.follow` with `bounces` and `max_path_m`
        would give them; followed once (a batch is known by its directions and
        power), cut for each budget."""
        if bounces != self.bounces or max_path_m > self.max_path_m:  # not this emission's
            return follow(self.world, self.caster, self.emitter, dirs, d_omega, bounces, max_path_m)
        key = (float(d_omega), np.ascontiguousarray(dirs, float).tobytes())
        full = self._shots.get(key, lambda: self._follow(dirs, d_omega))
        return full if max_path_m == self.max_path_m else cut(full, max_path_m)

    def _follow(self, dirs: np.ndarray, d_omega: float) -> Shot:
        self.followed += 1
        return follow(
            self.world,
            self.caster,
            self.emitter,
            dirs,
            d_omega,
            self.bounces,
            self.max_path_m,
            legs=True,
        )


def cut(shot: Shot, max_path_m: float) -> Shot:
    """`shot` (followed with its :class:`~acousim.trace.rays.shoot.Legs`) as if its
    rays had been followed with the budget `max_path_m` (m, at most the one they
    were): a ray goes on while its path is shorter than the budget, and a leg hits
    when the caster's single-precision distance limit (the budget less the path so
    far) admits it, as in :func:`~acousim.trace.rays.shoot.follow`."""
    legs = shot.legs
    if legs is None:
        raise ValueError("cut() needs a shot followed with legs=True")
    hits = shot.hits
    cap = (max_path_m - legs.before_m).astype(np.float32)  # follow's limit per leg
    within = (legs.before_m < max_path_m) & (legs.leg_m <= cap)
    keep = np.zeros(len(hits), bool)
    alive = np.ones(shot.rays, bool)  # rays still followed in the cut
    sequences: set[tuple[int, ...]] = set()
    for b in range(1, legs.sequence.shape[1] + 1):
        h = np.flatnonzero(hits.order == b)
        ok = within[h] & alive[legs.ray[h]]
        keep[h] = ok
        alive = np.zeros(shot.rays, bool)
        alive[legs.ray[h[ok]]] = True
        planar = h[ok & legs.planar[h]]
        rows = legs.sequence[legs.ray[planar], :b]
        sequences.update(_unique_rows(rows, int(rows.max(initial=0)) + 1))
    sub = Hits(*(getattr(hits, f.name)[keep] for f in dataclasses.fields(Hits)))
    return Shot(sub, sorted(sequences), shot.rays)
