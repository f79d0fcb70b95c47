"""The automatic ray budget: how much ray work a pose needs, found rather than guessed.

The rays serve two stages: they find candidate plane sequences for the exact
specular stage (:mod:`.specular`), and their hits on rough or curved faces make the
diffuse tail (:mod:`.scatter`).  First-order glints (:mod:`.glints`), edge
diffraction and explicit points need no rays.  So, per pose (:func:`ray_work`):

1. Plan (:func:`plan`).  Where the planes are few (at most :data:`ENUMERATE_MAX`
   sequences), every sequence of up to ``bounces`` planes (no plane twice in a row)
   goes to the specular stage: image sources with their visibility checks, which no
   ray can miss; those that leave the emitter within the beam (``beam_deg``, the
   cone the rays fill) are kept, and any other whose sequence a ray met (as a fixed
   budget keeps it).  The rays are then needed only if some hit can scatter: a
   material with a diffuse part, or a curved surface met from the second
   reflection on.  A scene that needs neither (the shoebox, the plate, the wall)
   shoots no ray if its beam is the whole sphere, else one batch that tells which
   sequences a ray in the beam meets (a wall along the axis, whose path leaves at
   the beam's edge, is then kept on either side of it): a :class:`Probe`, asked
   only about the paths that leave outside the beam (none: no ray), its rays aimed
   by geometry before any is cast; the sphere (no planes) none.
2. Otherwise the rays go out in batches: the deterministic spiral of
   :func:`.shoot.cone_directions` of :data:`START_RAYS` rays, then the same spiral
   shifted in both of its lattice coordinates by golden-ratio steps (no random
   choice; every batch covers the beam evenly, between the others' rays), each
   batch as many rays as all before it.  After each batch the rays stop if that
   batch found no new specular path (when the rays find the plane sequences: its
   new sequences are refined at once, and only those that make a path are kept)
   and no new curved-surface glint of a higher order (a surface and order among
   the lobes of :mod:`.scatter`), and if its own estimate of the diffuse
   (Lambert) tail's energy agrees with that of all the batches before it within
   :data:`TAIL_TOLERANCE_DB` in every range bin of :data:`TAIL_BIN_M` holding at
   least ``10^(-TAIL_SPAN_DB/10)`` of the strongest bin's energy; or before the
   next batch would pass ``rays_max``.  All batches' hits make the paths, each ray
   weighted by the beam's solid angle over all the rays; the recording's metadata
   reports how many.

Why these numbers: the batch and the batches before it are two independent
estimates of as many rays each; when they agree to 0.4 dB, their mean is about half
that (0.2 dB) from its limit (two independent errors differ by about 1.4 times
either, their mean is 0.7 times either), leaving room within the 0.5 dB asked of the
tail against ten times the old fixed budgets (`tests/acousim/trace/rays/test_budget.py`), whose own
estimate is 0.1 to 0.4 dB off (the corridor's spiral at 20,000 against 50,000
rays).  Bins 20 dB under the strongest carry a hundredth of its energy: few rays
reach them, their estimate moves by decibels from one batch to the next, and they
change no image.  1000 rays is where the corridor's strongest bins agree within a
few tenths of a dB; the corridor's poses stop at 2000 or 4000 rays (it used to set
5000).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
from dataclasses import dataclass, fields

import numpy as np

from acousim.trace.options import TraceSettings
from acousim.trace.rays.emission import Emission
from acousim.trace.rays.scatter import Contributions, scatter, scatter_rows, take
from acousim.trace.rays.shoot import Hits, Shot, follow, sequences_met
from acousim.trace.rays.specular import refine_sequences
from acousim.trace.world.build import World
from acousim.trace.world.embree import RayCaster

__all__ = [
    "ENUMERATE_MAX",
    "Probe",
    "START_RAYS",
    "TAIL_BIN_M",
    "TAIL_SPAN_DB",
    "TAIL_TOLERANCE_DB",
    "RayWork",
    "all_sequences",
    "in_beam",
    "n_sequences",
    "plan",
    "ray_work",
    "lobes",
    "tail_agrees",
    "tail_energy",
]

log = logging.getLogger(__name__)

#: rays of the automatic budget's first batch (each next batch: all the rays before)
START_RAYS = 1000
#: range bins (m) in which the diffuse tail's energy must have converged
TAIL_BIN_M = 0.5
#: ... a batch and all the batches before it agreeing to this (dB)
TAIL_TOLERANCE_DB = 0.4
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
    #: enumerated sequences: those the rays met (None: the sequences are the rays')
    met: frozenset[tuple[int, ...]] | None = None
    #: enumerated sequences and nothing that scatters: the probe that tells which of
    #: them a ray in the beam meets, shot only if some path leaves outside the beam
    #: (:func:`in_beam`; None: none)
    probe: Probe | None = None

    @property
    def rays_shot(self) -> int:
        """The rays shot: :attr:`rays` and the probe's, if it was shot."""
        return self.rays + (0 if self.probe is None else self.probe.rays)


class Probe:
    """One batch of :data:`START_RAYS` rays over the beam (:func:`_probe`), shot when
    first asked which plane sequences it meets (:meth:`met`); :attr:`rays`: how many
    it shot (0: not asked, or asked of none)."""

    def __init__(self, world, caster, settings, emitter, axis, emission=None) -> None:
        self._args = (world, caster, settings, emitter, axis, emission)
        self.rays = 0

    def met(self, wanted: set[tuple[int, ...]]) -> set[tuple[int, ...]]:
        """The sequences among `wanted` that a ray of the batch meets (its rays
        followed only as far as those need: :func:`.shoot.sequences_met`)."""
        if not wanted:
            return set()
        world, caster, settings, emitter, axis, emission = self._args
        n = min(START_RAYS, settings.rays_max)
        dirs = batch_directions(n, axis, settings.beam_rad, 0)
        d_omega = 2 * np.pi * (1 - np.cos(settings.beam_rad)) / n
        self.rays = n
        if emission is not None:  # the emission's rays, shot once for every receiver
            shot = _shot(world, caster, settings, emitter, dirs, d_omega, emission)
            return set(shot.sequences) & wanted
        bounces, reach = settings.bounces, settings.max_path_m
        return sequences_met(world, caster, emitter, dirs, d_omega, bounces, reach, wanted)


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


def _valid(world, caster, sequences, ends, max_path_m) -> set[tuple[int, ...]]:
    """The sequences among `sequences` that make a specular path within reach
    (:mod:`.specular`); ends: (emitter, receiver)."""
    paths = refine_sequences(world, caster, sorted(sequences), *ends, max_path_m)
    return {p.planes for p in paths}


def tail_agrees(energy: np.ndarray, before: np.ndarray) -> bool:
    """Whether two estimates of the tail's energy per bin agree within
    :data:`TAIL_TOLERANCE_DB` in every bin holding at least ``10^(-TAIL_SPAN_DB/10)``
    of the strongest bin's energy in either (module docstring)."""
    width = max(len(energy), len(before))
    a, b = _padded(energy, width), _padded(before, width)
    top = max(a.max(initial=0.0), b.max(initial=0.0))
    if top == 0:
        return True
    strong = np.maximum(a, b) >= top * 10 ** (-TAIL_SPAN_DB / 10)
    lo, hi = np.minimum(a, b)[strong], np.maximum(a, b)[strong]
    return bool(np.all(hi <= lo * 10 ** (TAIL_TOLERANCE_DB / 10)))


@functools.lru_cache(maxsize=16)
def _batch_spiral(n: int, half_angle_rad: float, batch: int) -> np.ndarray:
    """Batch `batch` of the automatic budget around +x (n, 3): the spiral of
    :func:`.shoot.cone_directions` (batch 0 is that spiral), its lattice shifted in
    both coordinates by the golden-ratio sequences of the batch (deterministic: no
    random choice), so that every batch covers the beam evenly, elsewhere."""
    u = (0.5 + batch * 0.6180339887498949) % 1.0
    v = (batch * 0.7548776662466927) % 1.0
    i = np.arange(n)
    cos_t = 1 - (1 - np.cos(half_angle_rad)) * (i + u) / n
    sin_t = np.sqrt(np.maximum(0, 1 - cos_t**2))
    phi = (i + u) * np.pi * (3 - np.sqrt(5)) + 2 * np.pi * v
    local = np.column_stack([cos_t, sin_t * np.cos(phi), sin_t * np.sin(phi)])
    local.flags.writeable = False  # cached: every pose turns the same batches
    return local


def batch_directions(n: int, axis: np.ndarray, half_angle_rad: float, batch: int) -> np.ndarray:
    """Batch `batch` (n, 3) of the automatic budget's rays, turned onto `axis`
    (read-only: the last few kept, by the axis's exact value, for the poses of a
    still sensor)."""
    axis = tuple(np.asarray(axis, float).tolist())
    return _turned_batch(int(n), float(half_angle_rad), int(batch), axis)


@functools.lru_cache(maxsize=16)
def _turned_batch(n: int, half_angle_rad: float, batch: int, axis: tuple) -> np.ndarray:
    a = np.array(axis) / np.linalg.norm(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, a)
    u /= np.linalg.norm(u)
    out = _batch_spiral(n, half_angle_rad, batch) @ np.stack([a, u, np.cross(a, u)])
    out.flags.writeable = False
    return out


def _mean(a: np.ndarray | None, n_a: int, b: np.ndarray, n_b: int) -> np.ndarray:
    """The mean of two estimates per bin, of n_a and n_b rays (a None: b)."""
    if a is None:
        return b
    width = max(len(a), len(b))
    return (_padded(a, width) * n_a + _padded(b, width) * n_b) / (n_a + n_b)


def _padded(a: np.ndarray, width: int) -> np.ndarray:
    """`a` (n,) followed by zeros up to `width` (``np.pad``'s result, without its cost)."""
    out = np.zeros(width, a.dtype)
    out[: len(a)] = a
    return out


def _merged(parts: list[tuple[Contributions, int]], total: int, early) -> Contributions:
    """:func:`_merge` of the batches `parts` (each: its contributions, its rays) of
    `total` rays; where they are the first two batches of :func:`_first_two` whole
    (`early`: its third item), those contributions as they are, their intensities
    halved (the same numbers: the two batches are its two halves in order, of as
    many rays each), instead of a copy of each array."""
    if early is not None and len(early) == 3 and len(parts) == 2:
        whole = early[2]
        return dataclasses.replace(whole, intensity=whole.intensity * (parts[0][1] / total))
    return _merge([(c, n / total) for c, n in parts])


def _merge(parts: list[tuple[Contributions, float]]) -> Contributions:
    """Batches of contributions as one sample, each batch's intensities times its
    weight (its share of the rays)."""
    out = {
        f.name: np.concatenate([getattr(c, f.name) for c, _ in parts])
        for f in fields(Contributions)
    }
    out["intensity"] = np.concatenate([c.intensity * w for c, w in parts])
    return Contributions(**out)


def ray_work(
    world: World,
    caster: RayCaster,
    settings: TraceSettings,
    emitter: np.ndarray,
    receiver: np.ndarray,
    axis: np.ndarray,
    *,
    emission: Emission | None = None,
) -> RayWork:
    """The automatic budget of one pose (module docstring); `emission`: the rays of
    this emitter and axis shot for other receivers (:mod:`.emission`; None: shot
    here), the same batches whichever receiver asks first."""
    enumerate_all, tail = plan(world, settings)
    every = all_sequences(world, settings.bounces) if enumerate_all else None
    if enumerate_all and not tail:
        return _probe(world, caster, settings, emitter, axis, every, emission)
    tried, sequences, glints, parts, met = set(), set(), set(), [], set()
    total, before, ends = 0, None, (emitter, receiver, axis)
    first = max(1, min(START_RAYS, settings.rays_max))
    # the first two batches are always shot: where each batch's sequences are not
    # needed apart, both followed and scattered at once (the same hits, in order)
    at_once = enumerate_all and emission is None and 2 * first <= settings.rays_max
    early = _first_two(world, caster, settings, ends, first) if at_once else None
    for batch in range(64):
        n = first if batch < 2 else total
        if total + n > settings.rays_max:
            break
        met_now, part = _batch(world, caster, settings, ends, (batch, n), emission, early)
        found = set()
        if enumerate_all:
            met |= set(met_now)
        else:  # the rays find the plane sequences: keep the paths
            new = set(met_now) - tried
            found = _valid(world, caster, new, (emitter, receiver), settings.max_path_m)
            tried |= set(met_now)
            sequences |= found
        new_lobes = lobes(part) - glints
        glints |= new_lobes
        energy = tail_energy(part) if tail else np.zeros(0)
        settled = before is not None and not (found or new_lobes) and tail_agrees(energy, before)
        parts.append((part, n))
        before = _mean(before, total, energy, n)
        total += n
        log.debug(
            "batch %d: %d rays, %d new paths, %d new glints, tail agrees %s",
            batch,
            n,
            len(found),
            len(new_lobes),
            settled,
        )
        if settled:
            break
    log.debug("automatic budget: %d rays", total)
    contributions = _merged(parts, total, early)
    if enumerate_all:
        return RayWork(every, contributions, total, frozenset(met))
    return RayWork(sorted(sequences), contributions, total)


def _batch(world, caster, settings, ends, batch: tuple[int, int], emission, early) -> tuple:
    """Batch `batch` (its number, its rays n) of the automatic budget: (the plane
    sequences its rays met, their contributions); taken from `early` (batches 0 and
    1 at once: :func:`_first_two`; None: none) or shot (or taken from `emission`)
    and scattered.  ends: (emitter, receiver, axis)."""
    (number, n), (emitter, receiver, axis) = batch, ends
    if early is not None and number < 2:
        return early[number]
    omega = 2 * np.pi * (1 - np.cos(settings.beam_rad))
    dirs = batch_directions(n, axis, settings.beam_rad, number)
    shot = _shot(world, caster, settings, emitter, dirs, omega / n, emission)
    return shot.sequences, scatter(world, caster, shot.hits, receiver, settings.max_path_m)


def _first_two(world, caster, settings, ends, n: int) -> list:
    """Batches 0 and 1 of `n` rays each, followed and scattered in one pass: per
    batch, (the plane sequences met, all of them given to batch 0, the
    contributions); the contributions of each batch are those it makes alone, in
    the same order (without frequency-dependent materials, a third item: the two
    batches' contributions, batch 0's then batch 1's, as one).  ends: (emitter,
    receiver, axis)."""
    emitter, receiver, axis = ends
    omega = 2 * np.pi * (1 - np.cos(settings.beam_rad))
    dirs = np.concatenate([batch_directions(n, axis, settings.beam_rad, b) for b in (0, 1)])
    reach = settings.max_path_m
    shot = follow(world, caster, emitter, dirs, omega / n, settings.bounces, reach, legs=True)
    # the hits batch by batch (each in its order), so that the contributions are too
    hits, second = _batch_major(shot, n)
    both, rows = scatter_rows(world, caster, hits, receiver, reach)
    if world.spectra is not None:  # two parts per hit: the contributions taken apart
        return [(shot.sequences, take(both, ~second[rows])), ((), take(both, second[rows]))]
    k = int(np.searchsorted(rows, np.count_nonzero(~second)))
    return [(shot.sequences, take(both, slice(0, k))), ((), take(both, slice(k, None))), both]


def _batch_major(shot: Shot, n: int) -> tuple[Hits, np.ndarray]:
    """The hits of `shot` (bounce by bounce, each bounce's rays ascending) reordered:
    those of the rays before ray n bounce by bounce, then the others' (slices, no
    sort); and (K,) whether each is of a ray from n on."""
    ray, bounce = shot.legs.ray, shot.hits.order
    ends = [0, *(np.flatnonzero(np.diff(bounce)) + 1).tolist(), len(ray)]
    cut = [a + int(np.searchsorted(ray[a:b], n)) for a, b in zip(ends[:-1], ends[1:])]
    parts = [slice(a, c) for a, c in zip(ends[:-1], cut)]
    parts += [slice(c, b) for c, b in zip(cut, ends[1:])]
    hits = Hits(
        *(None if v is None else np.concatenate([v[p] for p in parts]) for v in _values(shot.hits))
    )
    return hits, np.concatenate([ray[p] for p in parts]) >= n


def _values(obj) -> list:
    """The fields of a dataclass instance, in order."""
    return [getattr(obj, f.name) for f in fields(obj)]


def _shot(world, caster, settings, emitter, dirs, d_omega, emission) -> Shot:
    """The rays `dirs` followed (:func:`.shoot.follow`), or taken from `emission`
    (shot once for every receiver, cut to this trace's budget)."""
    if emission is None:
        return follow(world, caster, emitter, dirs, d_omega, settings.bounces, settings.max_path_m)
    return emission.shot(dirs, d_omega, bounces=settings.bounces, max_path_m=settings.max_path_m)


def _probe(world, caster, settings, emitter, axis, every, emission=None) -> RayWork:
    """Enumerated sequences and nothing that scatters: no rays, unless the beam is
    narrower than the whole sphere; then one batch of :data:`START_RAYS` finds the
    sequences a ray in the beam meets (a wall along the axis, whose path leaves the
    emitter at the beam's edge, is kept whichever side of it the path leaves): a
    :class:`Probe`, shot by :func:`in_beam` if some path leaves outside the beam."""
    if settings.beam_rad >= np.pi or not every:
        return RayWork(every, None, 0, frozenset())
    return RayWork(every, None, 0, probe=Probe(world, caster, settings, emitter, axis, emission))


def in_beam(specular: list, work: RayWork, axis: np.ndarray, beam_rad: float) -> list:
    """The specular paths of enumerated sequences that leave the emitter within the
    beam (``beam_deg``: the emitter's cone, as for the rays), or whose sequence the
    rays met (a ray in the beam found it, as a fixed budget would; the probe's rays,
    :class:`Probe`, asked about those that leave outside it); all paths when the
    sequences are the rays' own."""
    if work.met is None and work.probe is None:
        return specular
    low = np.cos(beam_rad) - 1e-9
    within = [bool(p.departure @ axis >= low) for p in specular]
    met = work.met
    if work.probe is not None:
        met = work.probe.met({p.planes for p, w in zip(specular, within) if not w})
    return [p for p, w in zip(specular, within) if w or p.planes in met]
