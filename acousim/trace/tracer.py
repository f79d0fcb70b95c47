"""From a scene and a pose to paths: a thin orchestrator over the tracer's stages.

For one pose (emitter, receiver = array centre, axis), with :class:`TraceSettings`:

0. Paths without rays (:mod:`.direct`): the direct path and the explicit points.
1. Shoot (:mod:`.shoot`): rays over the beam, followed specularly; their hits and the
   sequences of planes they met.  How many: ``settings.rays``, or (None, the default)
   the automatic budget of :mod:`.budget`, which also enumerates every plane sequence
   where there are few and shoots no ray where nothing scatters.
2. Specular refinement (:mod:`.specular`): every candidate plane sequence made an
   exact image-source path, or rejected; and (:mod:`.glints`) the first-order
   specular points of curved surfaces, found without rays.
3. Edge diffraction (:mod:`.diffraction`, if ``settings.diffraction.enabled``): first-order
   BTM elements of every edge the emitter and the receiver see, optionally with one
   specular reflection before or after the edge, and (``diffraction.order`` 2) edge
   to edge; no rays needed (the edges and the
   plane table of the world are built once, :class:`DiffractingGeometry`).
4. Scattering (:mod:`.scatter`): hits on curved or rough faces connected to the
   receiver.
5. Clustering (:mod:`.cluster`): scattered contributions into point reflectors.
6. Energy floor (:mod:`.floor`): paths far below the strongest echo dropped (each
   under the floor, or the weakest while their summed energy stays under it:
   ``energy_floor_rule``); stage 3 prunes early within what the floor allows.

Every stage returns :class:`TracedPaths` (or a typed intermediate); paths are stored in
one form (see :mod:`.paths`).  First-order echoes of planes (image sources) and of
curved surfaces (glints: a sphere of radius a at distance r from its surface,
a / (2 r (r + a))) are exact geometric optics, independent of the ray budget and of
``lobe_deg``; the rays sample higher orders and the diffuse (Lambert) part.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Protocol

import numpy as np

from acousim.core.cache import LruCache
from acousim.scene.model import Scene
from acousim.scene.pose import Pose
from acousim.trace.diffraction.stage import (
    DiffractingGeometry,
    DiffractionOptions,
    edge_diffraction,
)
from acousim.trace.direct import direct_path, point_paths
from acousim.trace.floor import EarlyFloor, diffraction_candidates, early_floor, energy_floor
from acousim.trace.options import TraceSettings, resolution_length
from acousim.trace.paths import KIND, TracedPaths
from acousim.trace.rays.budget import RayWork, in_beam, ray_work
from acousim.trace.rays.cluster import DIFFUSE_CELL_DEG, cluster
from acousim.trace.rays.emission import Emission
from acousim.trace.rays.glints import curved_groups, glints
from acousim.trace.rays.scatter import scatter
from acousim.trace.rays.shoot import cone_directions, shoot
from acousim.trace.rays.specular import as_paths, refine_sequences
from acousim.trace.world.build import World, build_world
from acousim.trace.world.clearance import check_clearance
from acousim.trace.world.embree import RayCaster
from processing import Array
from processing.base.errors import InputError

__all__ = [
    "TracedPaths",
    "Tracer",
    "PathTracer",
    "TraceSettings",
    "cone_directions",
    "enclosing_materials",
    "trace_pose",
    "KIND",
    "DIFFUSE_CELL_DEG",
    "resolution_length",
]

log = logging.getLogger(__name__)


#: the pose check's 64 rays over the whole sphere (:func:`enclosing_materials`)
_ALL_AROUND = cone_directions(64, np.array([1.0, 0, 0]), np.pi)
_ALL_AROUND.flags.writeable = False


def enclosing_materials(caster: RayCaster, world: World, emitter_m: np.ndarray) -> list[str]:
    """The materials (sorted names) of the closed mesh an emitter at `emitter_m` (3,)
    m stands inside, which the tracer refuses (:meth:`Tracer._check_pose`): of 64
    rays all around, 48 or more meet a face, every one meets a face, and 90 % of
    those meet it from behind (its normal along the ray); [] when it is not inside
    one."""
    dirs = _ALL_AROUND
    t, f = caster.first_hit(np.broadcast_to(emitter_m, dirs.shape), dirs)
    hit = f >= 0
    if hit.sum() < 48:
        return []
    facing = np.einsum("ij,ij->i", world.normals[f[hit]], dirs[hit]) > 0
    closed = not np.isinf(t).any()
    if facing.mean() > 0.9 and closed:
        return sorted({world.materials[m].name for m in world.material[f[hit]]})
    return []


def trace_pose(
    world: World | None,
    caster: RayCaster | None,
    settings: TraceSettings,
    emitter: np.ndarray | Emission,
    receiver: np.ndarray,
    rotation: np.ndarray,
    points: tuple[np.ndarray, np.ndarray] | None = None,
    edges: DiffractingGeometry | None = None,
) -> tuple[TracedPaths, int]:
    """Every path of one pose (world frame), the stages 0 to 6 of the module docstring,
    and the number of rays it shot.

    emitter, receiver (array centre): (3,) each (or the emitter's rays shared with
    other receivers: an :class:`~.rays.emission.Emission`, the same paths);
    rotation (3, 3): the sensor's axes as columns (x: its axis); points: positions
    (P, 3) and strengths (P,) of explicit point reflectors; edges: the world's
    :class:`DiffractingGeometry` (built here, for this pose only, when diffraction
    is on and none is given)."""
    axis = rotation[:, 0]
    emission, emitter = _emitter(emitter)
    parts = []
    # 0. no rays needed
    if settings.direct_path:
        parts.append(direct_path(emitter, receiver, rotation[:, 1]))
    if points is not None and len(points[1]):
        parts.append(point_paths(*points, emitter, receiver, settings.max_path_m, caster))
    work = None
    if world is not None and caster is not None and settings.rays != 0:
        # 1. shoot (and 4. scatter: the automatic budget watches the tail converge)
        work = _ray_work(world, caster, settings, emitter, receiver, axis, emission)
        # 2. specular refinement
        specular = refine_sequences(
            world, caster, work.sequences, emitter, receiver, settings.max_path_m
        )
        specular = in_beam(specular, work, axis, settings.beam_rad)
        parts.append(as_paths(specular, emitter, settings.max_path_m))
        parts.append(
            glints(world, caster, emitter, receiver, axis, settings.beam_rad, settings.max_path_m)
        )
    # 3. edge diffraction
    spent = 0.0  # the energy the early floor may have left out (rule "sum")
    if world is not None and caster is not None and settings.diffraction.enabled:
        geometry = edges if edges is not None else DiffractingGeometry.of(world)
        if len(geometry.edges):
            summed = settings.energy_floor_rule == "sum"
            count = diffraction_candidates(geometry, settings.diffraction) if summed else 1
            early = _floor_so_far(parts, receiver, settings, count)
            spent = early.spent
            options = DiffractionOptions(
                max_path_m=settings.max_path_m,
                settings=settings.diffraction,
                floor_db=early.floor_db,
                floor_level=early.level,
                pair_step_m=settings.diffraction_pair_step_m,
                min_path_m=settings.min_path_m,
            )
            parts.append(edge_diffraction(geometry, caster, emitter, receiver, options))
    if work is not None and work.contributions is not None:
        # 5. clustering
        parts.append(cluster(work.contributions, receiver, settings.resolution_m))
        log.debug("traced %d rays: %d specular paths", work.rays, len(specular))
    # 6. energy floor
    paths = energy_floor(
        TracedPaths.concatenate(parts),
        receiver,
        settings.energy_floor_db,
        settings.energy_floor_rule,
        spent,
    )
    return paths, 0 if work is None else work.rays_shot


def _emitter(emitter) -> tuple[Emission | None, np.ndarray]:
    """(the shared rays or None, the emitter's position (3,)) of trace_pose's
    `emitter`."""
    if isinstance(emitter, Emission):
        return emitter, emitter.emitter
    return None, emitter


def _ray_work(world, caster, settings, emitter, receiver, axis, emission=None) -> RayWork:
    """Stages 1 and 4: the automatic budget (:mod:`.budget`) when ``settings.rays`` is
    None, else exactly ``settings.rays`` rays on the deterministic spiral (shot for
    this trace, or taken from `emission`)."""
    if settings.rays is None:
        return ray_work(world, caster, settings, emitter, receiver, axis, emission=emission)
    if emission is None:
        shot = shoot(
            world,
            caster,
            emitter,
            axis,
            settings.rays,
            settings.bounces,
            settings.beam_rad,
            settings.max_path_m,
        )
    else:  # shoot's rays: the spiral over the beam, each of an equal share of it
        dirs = cone_directions(settings.rays, axis, settings.beam_rad)
        d_omega = 2 * np.pi * (1 - np.cos(settings.beam_rad)) / settings.rays
        shot = emission.shot(
            dirs,
            d_omega,
            bounces=settings.bounces,
            max_path_m=settings.max_path_m,
        )
    contributions = scatter(world, caster, shot.hits, receiver, settings.max_path_m)
    return RayWork(shot.sequences, contributions, shot.rays)


def caster_of(world: World, threads: int = 2) -> RayCaster:
    """The ray caster of a world (its indexed mesh when it has one)."""
    indexed = None if world.vertices is None else (world.vertices, world.faces)
    return RayCaster(world.triangles, threads, indexed=indexed)


def _floor_so_far(
    parts: list[TracedPaths], receiver: np.ndarray, settings: TraceSettings, candidates: int
) -> EarlyFloor:
    """The early floor (:func:`~acousim.trace.floor.early_floor`) under the strongest
    echo of `parts` of a stage that can leave out at most `candidates` paths: the
    final floor (step 6) keeps every path above its level, and (rule "sum") the
    paths it leaves out are within its budget."""
    top = 0.0
    for p in parts:
        echo = p.kind != KIND["direct"]
        if echo.any():
            top = max(top, float(p.select(echo).level_at(receiver).max()))
    return early_floor(top, settings.energy_floor_db, settings.energy_floor_rule, candidates)


def _key(pose: Pose, array: Array | None) -> tuple:
    """The cache key of a trace: the pose, and the ends of another array than the
    scene's sensor's."""
    if array is None:
        return pose.key()
    return (pose.key(), tuple(array.emitter_m), tuple(array.positions_m.mean(axis=0)))


class PathTracer(Protocol):
    """What the simulator asks of a tracer: a scene's one world (:class:`Tracer`) or a
    world per emission instant where meshes move
    (:class:`~acousim.trace.motion.moving_world.MovingWorld`)."""

    scene: Scene

    @property
    def world(self) -> World | None: ...

    def trace(self, pose: Pose, array: Array | None = None) -> TracedPaths: ...

    def traced(
        self,
        pose: Pose,
        array: Array | None = ...,
        max_path_m: float | None = ...,
        min_path_m: float | None = ...,
        direct: bool | None = ...,
    ) -> tuple[TracedPaths, int]: ...

    def tracer_at(self, t_s: float) -> Tracer: ...

    def rays_used(self, pose: Pose, array: Array | None = None) -> int: ...

    def forget(self) -> None: ...


class Tracer:
    """Paths of a scene for any pose; one Embree scene, built once (only if the scene
    has meshes), and a cache so the same pose is not traced twice."""

    def __init__(self, scene: Scene, threads: int = 2) -> None:
        self.scene = scene
        self.settings = TraceSettings.from_scene(scene)
        self.world: World | None = build_world(scene) if scene.meshes else None
        self.caster = caster_of(self.world, threads) if self.world else None
        #: the world's diffracting edges and planes, found once (if diffraction is on)
        self.edges = (
            DiffractingGeometry.of(self.world)
            if self.world is not None and self.settings.diffraction.enabled
            else None
        )
        if self.world is None:
            log.debug("scene %r has no meshes: no ray tracing", scene.name)
        else:
            self._build_tables()
        self._points = None
        still = [p for p in scene.points if not p.moving]  # the moving: per instant
        if still:
            self._points = (
                np.array([p.position_m for p in still], float),
                np.array([p.strength for p in still], float),
            )
        # the traced poses (paths, rays shot), the least recently used dropped first
        self._traced = LruCache(256)
        #: the rays of the emissions traced last (None: each trace shoots its own;
        #: :meth:`share_emissions`)
        self._emissions: LruCache | None = None

    def share_emissions(self, size: int = 8) -> None:
        """Shoot the rays of an emission once for every receiver traced from it (the
        same emitter position and axis: a rig's call heard by several sonars), the
        `size` emissions traced last kept (:mod:`.rays.emission`; the paths are
        those of separate traces, byte for byte); 0: each trace shoots its own."""
        self._emissions = LruCache(size) if size > 0 else None

    def _emission(self, emitter: np.ndarray, axis: np.ndarray) -> Emission | None:
        """The shared rays of `emitter` (3,) along `axis` (3,), world frame (None: not
        shared)."""
        if self._emissions is None or self.world is None:
            return None
        key = (tuple(emitter.tolist()), tuple(axis.tolist()))
        return self._emissions.get(
            key,
            lambda: Emission(
                self.world,
                self.caster,
                emitter,
                bounces=self.settings.bounces,
                max_path_m=self.settings.max_path_m,
            ),
        )

    def _build_tables(self) -> None:
        """What every pose uses, built once here rather than by the first pose:
        Embree's tree (built at the first ray), the planes' tables and boxes and the
        groups of curved faces (preparation and per-pose cost apart)."""
        self.caster.first_hit(self.world.triangles[:1, 0], np.ones((1, 3)))
        _ = self.world.plane_boxes, self.world.surface
        for attr in ("reflection", "diffuse", "lobe_deg"):
            self.world.face_values(attr)
        curved_groups(self.world)

    def trace(self, pose: Pose, array: Array | None = None) -> TracedPaths:
        """The paths of `pose` (traced once; kept for the poses traced last) from the
        emitter of `array` to the centre of its microphones (default: the scene's
        sensor's; a rig's pair of sensors: the emitter of one, the microphones of
        another, both in the emitting sensor's frame)."""
        return self.traced(pose, array)[0]

    def traced(
        self,
        pose: Pose,
        array: Array | None = None,
        max_path_m: float | None = None,
        min_path_m: float | None = None,
        direct: bool | None = None,
    ) -> tuple[TracedPaths, int]:
        """:meth:`trace`'s paths and the rays it shot; `max_path_m`: only the paths up
        to that length (m; None: the scene's, twice its range), for a call heard
        late in another sonar's window (:mod:`acousim.rig`); `min_path_m`: only the
        paths at least that long to some microphone are asked for (m; a call
        emitted before another sonar's window, which keeps those alone:
        :func:`acousim.trace.paths.reaching`); the diffraction stage leaves out
        edges and pairs of edges whose every path is shorter and that cannot be
        the strongest echo (:meth:`DiffractionOptions.needed`): the paths that
        reach are those of the full trace.  `direct`: whether the direct path from
        the emitter is traced (None: as the scene's sensor says; a rig's call heard
        straight by another sonar is crosstalk, whatever its ``direct_path``)."""
        key = _key(pose, array)
        if direct is not None and direct == self.settings.direct_path:
            direct = None
        if max_path_m is not None or min_path_m is not None or direct is not None:
            key = (key, max_path_m, min_path_m, direct)
        return self._traced.get(
            key, lambda: self._trace_now(pose, array, max_path_m, min_path_m, direct)
        )

    def _trace_now(
        self,
        pose: Pose,
        array: Array | None,
        max_path_m: float | None = None,
        min_path_m: float | None = None,
        direct: bool | None = None,
    ) -> tuple[TracedPaths, int]:
        array = self.scene.sensor.array if array is None else array
        emitter = pose.to_world(array.emitter_m)
        receiver = pose.to_world(array.positions_m.mean(axis=0))
        if self.world is not None:
            mics = pose.to_world(array.positions_m)
            check_clearance(self.caster, self.world, emitter, mics)
            if self.settings.rays != 0:
                self._check_pose(emitter)
        settings = self.settings
        if max_path_m is not None and max_path_m < settings.max_path_m:
            settings = dataclasses.replace(settings, max_path_m=float(max_path_m))
        if min_path_m is not None:  # to the centre: the microphones lie this near it
            spread = np.linalg.norm(array.positions_m - array.positions_m.mean(axis=0), axis=1)
            settings = dataclasses.replace(settings, min_path_m=float(min_path_m - spread.max()))
        if direct is not None:
            settings = dataclasses.replace(settings, direct_path=bool(direct))
        shared = self._emission(emitter, pose.rotation[:, 0])
        return trace_pose(
            self.world,
            self.caster,
            settings,
            emitter if shared is None else shared,
            receiver,
            pose.rotation,
            self._points,
            self.edges,
        )

    def tracer_at(self, t_s: float) -> Tracer:
        """The tracer of the world at time `t_s`: this one (its world does not move;
        :class:`acousim.trace.motion.moving_world.MovingWorld` has one per instant)."""
        return self

    def rays_used(self, pose: Pose, array: Array | None = None) -> int:
        """How many rays the trace of `pose` (and `array`, as :meth:`trace`) shot
        (traced now if it was not)."""
        return self.traced(pose, array)[1]

    def forget(self) -> None:
        """Empty the cache of traced poses and shared emissions (the next trace of any
        pose pays in full: for timing)."""
        self._traced.clear()
        if self._emissions is not None:
            self._emissions.clear()

    def _check_pose(self, emitter: np.ndarray) -> None:
        """A sensor inside a closed wall sees the inside of faces: refuse the pose."""
        names = enclosing_materials(self.caster, self.world, emitter)
        if names:
            raise InputError(
                f"the sensor at {np.round(emitter, 3).tolist()} m is inside a closed mesh "
                f"(a wall or object; its faces are of material {', '.join(names)}): "
                "move the pose; or, if it stands in a room, the room's faces must face "
                'into it: its normals may be inverted (docs/scene-format.md, "Meshes")'
            )
