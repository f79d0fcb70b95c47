"""Stage 1 of the tracer: shoot rays from the emitter and follow them specularly.

Rays leave the emitter on a deterministic equal-area spiral over its beam (a cone of
half-angle ``beam_rad`` around the sensor's axis), so the result is a pure function of
the scene and the pose, and converges as rays are added.

1. Directions: :func:`cone_directions`; each ray carries its solid angle as power.
2. For each bounce up to ``bounces``: the first face hit by every live ray (within
   the path budget ``max_path_m``); the hit is recorded (point, normal facing the
   incoming side, mirror direction, incoming power, path length so far, departure).
3. The ray's sequence of planes, while it has met planar faces only, is a candidate
   for the exact specular stage.
4. The ray continues in the mirror direction with its power times ``R^2 (1 -
   diffuse)`` of the face.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from acousim.trace.world.build import World
from acousim.trace.world.embree import RayCaster
from processing.base.kernels import optional_kernel

__all__ = ["Hits", "Legs", "Shot", "aimed", "cone_directions", "follow", "sequences_met", "shoot"]


@dataclass(frozen=True, eq=False)
class Hits:
    """Every hit of every ray on a face, all bounces (world frame).  K hits."""

    point_m: np.ndarray
    """(K, 3) where the ray hit, m."""
    normal: np.ndarray
    """(K, 3) unit face normal, towards the side the ray came from."""
    mirror: np.ndarray
    """(K, 3) unit specular direction."""
    power: np.ndarray
    """(K,) the ray's solid angle (sr) times the reflection factors before this hit."""
    length_m: np.ndarray
    """(K,) path length from the emitter, m."""
    departure: np.ndarray
    """(K, 3) unit direction leaving the emitter."""
    face: np.ndarray
    """(K,) int, the face hit."""
    order: np.ndarray
    """(K,) int, reflections including this one."""
    interactions: np.ndarray | None = None
    """(K, C) int, the frequency-dependent material interactions before this hit
    (C = ``World.n_interactions``, often 0)."""

    def __len__(self) -> int:
        return self.power.size


@dataclass(frozen=True, eq=False)
class Legs:
    """How each hit of a :class:`Shot` was reached, to cut the shot to a shorter path
    budget exactly as if its rays had been followed with it
    (:func:`acousim.trace.rays.emission.cut`).  K hits, R rays, B bounces."""

    ray: np.ndarray
    """(K,) int, the ray of each hit."""
    before_m: np.ndarray
    """(K,) path length from the emitter to the start of the hit's leg, m."""
    leg_m: np.ndarray
    """(K,) the leg's length as the caster returned it, m."""
    planar: np.ndarray
    """(K,) bool, the ray met planar faces only, this hit included."""
    sequence: np.ndarray
    """(R, B) int, the plane met by each ray at each bounce (-1: none)."""


@dataclass(frozen=True, eq=False)
class Shot:
    """What the rays found: their hits and the candidate specular plane sequences
    (and, when asked of :func:`follow`, how each hit was reached)."""

    hits: Hits
    sequences: list[tuple[int, ...]]
    rays: int
    legs: Legs | None = None


@functools.lru_cache(maxsize=8)
def _spiral(n: int, half_angle_rad: float) -> np.ndarray:
    """The spiral of :func:`cone_directions` around +x (n, 3), computed once per
    (n, angle): every pose of a scene shoots the same rays, turned."""
    i = np.arange(n) + 0.5
    cos_t = 1 - (1 - np.cos(half_angle_rad)) * i / n
    sin_t = np.sqrt(np.maximum(0, 1 - cos_t**2))
    phi = i * np.pi * (3 - np.sqrt(5))
    local = np.column_stack([cos_t, sin_t * np.cos(phi), sin_t * np.sin(phi)])
    local.flags.writeable = False
    return local


def cone_directions(n: int, axis: np.ndarray, half_angle_rad: float) -> np.ndarray:
    """n unit vectors on an equal-area (Fibonacci) spiral over a cone around `axis`."""
    local = _spiral(int(n), float(half_angle_rad))
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, a)
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    return local @ np.stack([a, u, v])


def shoot(
    world: World,
    caster: RayCaster,
    emitter: np.ndarray,
    axis: np.ndarray,
    rays: int,
    bounces: int,
    beam_rad: float,
    max_path_m: float,
) -> Shot:
    """Shoot `rays` rays over the beam and follow each for up to `bounces` reflections."""
    # 1. directions and powers
    dirs = cone_directions(rays, axis, beam_rad)
    d_omega = 2 * np.pi * (1 - np.cos(beam_rad)) / rays
    return follow(world, caster, emitter, dirs, d_omega, bounces, max_path_m)


def follow(
    world: World,
    caster: RayCaster,
    emitter: np.ndarray,
    dirs: np.ndarray,
    d_omega: float,
    bounces: int,
    max_path_m: float,
    *,
    legs: bool = False,
) -> Shot:
    """Steps 2 to 4 for rays leaving the emitter in directions `dirs` (R, 3), unit,
    each carrying the solid angle `d_omega` (sr) as power; `legs`: also how each
    hit was reached (:class:`Legs`)."""
    rays = len(dirs)
    dirs = np.array(dirs, float)
    origin = np.broadcast_to(emitter, dirs.shape).copy()
    length = np.zeros(rays)
    power = np.full(rays, d_omega)
    departure = dirs.copy()
    planar = np.ones(rays, bool)
    seq = np.full((rays, bounces), -1)
    alive = np.arange(rays)
    column = world.face_interactions(0)  # specular interactions (None: no tables)
    history = np.zeros((rays, world.n_interactions), int)
    n_planes = world.n_planes
    records = []
    reached = []  # (ray, length before the leg, leg, planar) per bounce, for Legs
    sequences: set[tuple[int, ...]] = set()
    for b in range(bounces):
        if alive.size == 0:
            break
        # 2. first hits of the live rays
        alive, t, f = _first_hits(caster, origin, dirs, alive, max_path_m - length[alive])
        before = length[alive]  # a copy: the lengths before this leg
        # 4. continue specularly (step 3 below: the sequences)
        x, normal, mirror, power_in = _bounce(
            world, caster, (alive, t, f), (origin, dirs, length, power)
        )
        # 3. candidate plane sequences (rays that met planar faces only)
        seq[alive, b] = world.plane[f]
        planar[alive] &= ~world.curved[f]
        rows = _rows(seq, alive[planar[alive]])[:, : b + 1]
        sequences.update(_unique_rows(rows, n_planes))
        reached.append((alive, before, t, planar[alive]))
        geo = (x, normal, mirror, power_in, length[alive], _rows(departure, alive))
        records.append((*geo, f, np.full(f.size, b + 1), _rows(history, alive)))
        if column is not None:
            c = column[f]
            history[alive[c >= 0], c[c >= 0]] += 1
        alive = alive[(length[alive] < max_path_m) & (power[alive] > 0)]
    return Shot(_hits(records, history), sorted(sequences), rays, _legs(reached, seq, legs))


def _bounce(world: World, caster: RayCaster, met: tuple, state: tuple) -> tuple:
    """Steps 2 and 4 of :func:`follow` for the rays that `met` faces (rays, distances
    (m), faces (N,)): their hits (N, 3), the normals there on their side (N, 3), the
    mirrored directions (N, 3) and their power before the hit (N,); the rays'
    `state` (origins (R, 3), directions (R, 3), lengths (R,), powers (R,)) moved on
    in place: compiled (:func:`.bounce_kernel.bounce`) or in numpy, the same."""
    alive, t, f = met
    origin, dirs, length, power = state
    kernel = optional_kernel("acousim.trace.rays.bounce_kernel", "bounce")
    if kernel is not None:  # in one pass
        x, normal, mirror = np.empty((3, f.size, 3))
        power_in = np.empty(f.size)
        tables, lift = _bounce_tables(world), caster.offset_m
        kernel(alive, t, f, origin, dirs, length, power, tables, lift, x, normal, mirror, power_in)
        return x, normal, mirror, power_in
    refl, diffuse = world.face_values("reflection"), world.face_values("diffuse")
    x = origin[alive] + t[:, None] * dirs[alive]
    length[alive] += t
    normal, mirror = _reflect(world.normals_at(x, f), dirs[alive])
    power_in = power[alive]
    power[alive] *= refl[f] ** 2 * (1 - diffuse[f])
    origin[alive] = x + caster.offset_m * normal
    dirs[alive] = mirror
    return x, normal, mirror, power_in


def _rows(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``a[rows]`` of an array (N, ...) by integer rows: the same values, faster."""
    return np.take(a, rows, axis=0)


def _bounce_tables(world: World) -> tuple:
    """What :func:`.bounce_kernel.bounce` reads of a world (once per world): face
    normals, curved, corners, corner normals, reflection and diffuse per face."""
    return world._cached(
        "bounce_tables",
        lambda: (
            world.normals,
            world.curved,
            world.triangles,
            world.vertex_normals,
            np.asarray(world.face_values("reflection"), float),
            np.asarray(world.face_values("diffuse"), float),
        ),
    )


def _first_hits(caster: RayCaster, origin, dirs, alive: np.ndarray, reach_m: np.ndarray):
    """The first hits of the rays `alive` (indices into `origin`, `dirs` (R, 3)), each
    within its `reach_m`: those that hit (indices), their distances (m) and faces
    (np.take: rows of (R, 3) arrays several times faster than ``a[alive]``)."""
    t, f = caster.first_hit(_rows(origin, alive), _rows(dirs, alive), reach_m)
    hit = f >= 0
    return alive[hit], t[hit], f[hit]


def sequences_met(
    world: World,
    caster: RayCaster,
    emitter: np.ndarray,
    dirs: np.ndarray,
    d_omega: float,
    bounces: int,
    max_path_m: float,
    wanted: set[tuple[int, ...]],
) -> set[tuple[int, ...]]:
    """The sequences among `wanted` that :func:`follow`'s rays (the same arguments)
    meet: ``set(follow(...).sequences) & wanted``, each ray followed as there (its
    hits, reflections, length and power) but only while its planes so far begin
    some wanted sequence, and only the rays :func:`aimed` at one cast (the rays are
    independent: the others change nothing)."""
    if not wanted:
        return set()
    P = world.n_planes
    longest = min(bounces, max(len(w) for w in wanted))
    weights = P ** np.arange(longest)
    refl, diffuse = world.face_values("reflection"), world.face_values("diffuse")
    dirs = np.array(dirs, float)
    origin = np.broadcast_to(emitter, dirs.shape).copy()
    length = np.zeros(len(dirs))
    power = np.full(len(dirs), d_omega)
    seq = np.full((len(dirs), longest), -1)
    alive = np.flatnonzero(aimed(world, caster, emitter, dirs, wanted))
    met: set[tuple[int, ...]] = set()
    for b in range(longest):
        if alive.size == 0:
            break
        alive, t, f = _first_hits(caster, origin, dirs, alive, max_path_m - length[alive])
        x = _rows(origin, alive) + t[:, None] * _rows(dirs, alive)
        length[alive] += t
        seq[alive, b] = world.plane[f]
        planar = ~world.curved[f]  # a ray that met a curved face adds no sequence
        alive, t, f, x = alive[planar], t[planar], f[planar], x[planar]
        met |= set(_unique_rows(seq[alive, : b + 1], P)) & wanted
        # on: the rays whose planes so far begin a longer wanted sequence
        on = {w[: b + 1] for w in wanted if len(w) > b + 1}
        if not on or b + 1 == longest:
            break
        code = seq[alive, : b + 1] @ weights[: b + 1]
        keep = np.isin(code, [np.dot(w, weights[: b + 1]) for w in on])
        alive, f, x = alive[keep], f[keep], x[keep]
        normal, mirror = _reflect(world.normals_at(x, f), dirs[alive])
        power[alive] *= refl[f] ** 2 * (1 - diffuse[f])
        origin[alive] = x + caster.offset_m * normal
        dirs[alive] = mirror
        alive = alive[(length[alive] < max_path_m) & (power[alive] > 0)]
    return met


def aimed(
    world: World,
    caster: RayCaster,
    emitter: np.ndarray,
    dirs: np.ndarray,
    wanted: set[tuple[int, ...]],
) -> np.ndarray:
    """(R,) bool: the rays from `emitter` in directions `dirs` (R, 3), unit, that may
    meet a sequence of `wanted` (planar planes), by geometry alone: the ray passes
    through the box of the sequence's first plane, its mirror image in that
    (infinite) plane through the box of the next, and so on, each box grown by ten
    times the caster's distance tolerance (Embree's float32 hits, the planes' own
    grouping to 1e-6 in the normal and 10 um in the offset, are far within it).  A
    ray refused here cannot meet any of them; one kept may not (it is cast).  Compiled
    (:mod:`.aim_kernel`) or, without numba, in numpy: the same arithmetic, the same
    rays."""
    grow = 10 * caster.tolerance_m
    first = world.plane_first
    normal, offset = world.normals[first], world.offsets[first]
    lo, hi = world.plane_boxes[:, 0] - grow, world.plane_boxes[:, 1] + grow
    dirs = np.ascontiguousarray(dirs, float)
    out = np.zeros(len(dirs), bool)
    kernel = optional_kernel("acousim.trace.rays.aim_kernel", "aimed")
    if kernel is None:
        return _aimed_numpy((normal, offset, lo, hi), emitter, dirs, wanted, grow, out)
    seqs = sorted(wanted)
    lens = np.array([len(w) for w in seqs], np.int64)
    table = np.full((len(seqs), int(lens.max())), -1, np.int64)
    for i, w in enumerate(seqs):
        table[i, : len(w)] = w
    e = np.ascontiguousarray(emitter, float)
    kernel(e, dirs, table, lens, normal, offset, lo, hi, float(grow), out)
    return out


def _aimed_numpy(planes, emitter, dirs, wanted, grow, out) -> np.ndarray:
    """:func:`aimed` in numpy (the compiled kernel's twin): `planes` (normal, offset,
    lo, hi) of every plane, the boxes grown by `grow`; `out` (R,) set and returned."""
    normal, offset, lo, hi = planes
    # level by level: the (ray, prefix) pairs that passed the prefix's boxes, each
    # ray from its mirror image in the prefix's last plane
    prefixes: list[tuple[int, ...]] = [()]
    rays, pre = np.arange(len(dirs)), np.zeros(len(dirs), int)
    o, d = np.broadcast_to(np.asarray(emitter, float), dirs.shape), dirs
    for k in range(max(len(w) for w in wanted)):
        nxt = sorted({w[k] for w in wanted if len(w) > k})
        if rays.size == 0 or not nxt:
            break
        through = _through(o, d, lo[nxt], hi[nxt], grow)  # (K, B)
        # (prefix, next plane) -> whether wanted, whether some wanted goes on
        ends = np.array([[(*q, p) in wanted for p in nxt] for q in prefixes])
        going = {w[: k + 1] for w in wanted if len(w) > k + 1}
        on = np.array([[(*q, p) in going for p in nxt] for q in prefixes])
        pair, b = np.nonzero(through & (ends | on)[pre])
        out[rays[pair[ends[pre[pair], b]]]] = True
        keep = on[pre[pair], b]
        pair, b = pair[keep], b[keep]
        plane = np.asarray(nxt)[b]
        n, oa, da = normal[plane], o[pair], d[pair]
        dn = _dot(da, n)
        flat = np.abs(dn) < 1e-9  # along the plane: no mirror image to follow, kept
        out[rays[pair[flat]]] = True
        pair, b, n, oa, da, dn = pair[~flat], b[~flat], n[~flat], oa[~flat], da[~flat], dn[~flat]
        t = (offset[np.asarray(nxt)[b]] - _dot(oa, n)) / dn
        names = {q: i for i, q in enumerate(sorted(going))}
        table = np.array([[names.get((*q, p), -1) for p in nxt] for q in prefixes], int)
        prefixes, pre = sorted(going), table[pre[pair], b]
        rays, o, d = rays[pair], oa + t[:, None] * da, da - 2 * dn[:, None] * n
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row by row a . b (N,) of (N, 3) arrays, summed in the order x, y, z (as the
    compiled kernel sums them)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _through(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray, slack: float):
    """(R, B) bool: the rays o + t d (R, 3), t >= -slack, that pass through each of
    the boxes [lo, hi] (B, 3) (slab test; along an axis on which a ray does not move,
    the box holds it if its origin is inside)."""
    inv = np.ascontiguousarray((1.0 / np.where(d == 0.0, 1e-300, d)).T)  # (3, R); no 0 / 0
    o = np.ascontiguousarray(np.broadcast_to(o, d.shape).T)  # per axis: (B, R) arrays,
    enter = leave = None  # numpy being slow on a last axis of three
    for i in range(3):
        t1 = (lo[:, i, None] - o[i]) * inv[i]
        t2 = (hi[:, i, None] - o[i]) * inv[i]
        near, far = np.minimum(t1, t2), np.maximum(t1, t2)
        enter = near if enter is None else np.maximum(enter, near)
        leave = far if leave is None else np.minimum(leave, far)
    return ((leave >= enter) & (leave >= -slack)).T


def _legs(reached: list, sequence: np.ndarray, wanted: bool) -> Legs | None:
    """The :class:`Legs` of the hits `reached` (per bounce: rays, lengths before the
    leg, legs, planar so far) and the rays' plane `sequence` (None: not `wanted`)."""
    if not wanted:
        return None
    if not reached:
        return Legs(np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0, bool), sequence)
    return Legs(*(np.concatenate(v) for v in zip(*reached)), sequence)


def _unique_rows(rows: np.ndarray, n_planes: int) -> list[tuple[int, ...]]:
    """The distinct rows (plane sequences) of `rows` (N, B), via one integer code per
    row (np.unique(axis=0) is slow)."""
    if not rows.size:
        return []
    k = rows.shape[1]
    code = rows[:, 0].astype(np.int64)  # sum of rows[:, i] P^i (an integer matmul is slow)
    for i in range(1, k):
        code = code + rows[:, i] * np.int64(n_planes**i)
    # the distinct codes, read back digit by digit (the rows' values are in [0, P))
    distinct = np.unique(code)
    digits = distinct[:, None] // (n_planes ** np.arange(k))[None, :] % n_planes
    return list(map(tuple, digits.tolist()))


def _reflect(normal: np.ndarray, inc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(normals (N, 3) turned to the side the rays `inc` (N, 3) came from, the
    mirrored directions (N, 3))."""
    flip = np.einsum("ij,ij->i", normal, inc) > 0
    normal[flip] *= -1  # the side the ray came from
    mirror = inc - 2 * np.einsum("ij,ij->i", inc, normal)[:, None] * normal
    return normal, mirror


def _hits(records: list, history: np.ndarray) -> Hits:
    """The hits of every bounce, concatenated (none: empty arrays)."""
    if records:
        return Hits(*(np.concatenate(v) for v in zip(*records)))
    z3, z = np.zeros((0, 3)), np.zeros(0)
    return Hits(z3, z3, z3, z, z, z3, np.zeros(0, int), np.zeros(0, int), history[:0])
