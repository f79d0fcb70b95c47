"""The paths of one measurement in motion, and the tracer of a scene.

A measurement in motion (the sensor moves or turns, a point reflector or a mesh
moves) takes the paths traced at the pose of the start of the emission and says how
each follows the motion (:class:`~acousim.trace.motion.following.MovingPaths`):

1. trace the paths at the emission pose (moving meshes placed where they are then);
2. make each follow the emitter (:meth:`MovingPaths.from_traced`);
3. moving meshes: a path on a moving face rides it (:func:`.moving_world.ride`), and
   reflections of second order and up follow every moving plane of their chain
   (:func:`.moving_world.follow_chains`);
4. moving point reflectors: placed where they are at the start of the emission,
   those within reach and seen from the emitter and the receiver kept
   (:func:`acousim.trace.direct.heard_points`), appended after the traced paths.

A frozen measurement is the same paths with nothing moving: the simulator takes the
static stage for it (the same paths, no kinematics to solve).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.scene.model import PointItem, Scene
from acousim.scene.pose import Pose
from acousim.trace.direct import heard_points
from acousim.trace.motion.following import Endpoints, MovingPaths
from acousim.trace.motion.moving_world import MovingWorld, follow_chains, ride
from acousim.trace.paths import KIND, TracedPaths, kind_names
from acousim.trace.tracer import PathTracer, Tracer
from processing import Array

__all__ = ["InMotion", "paths_in_motion", "tracer_for"]


def tracer_for(scene: Scene, threads: int = 2) -> PathTracer:
    """The tracer of `scene`: its one world (:class:`~acousim.trace.tracer.Tracer`),
    or, where meshes move, a world per emission instant (:class:`MovingWorld`).
    Either sees the still point reflectors only: the moving ones are placed per
    emission instant (:func:`paths_in_motion`)."""
    if any(m.moving for m in scene.meshes):
        return MovingWorld(scene, threads)
    return Tracer(scene, threads)


@dataclass(frozen=True, eq=False)
class InMotion:
    """The paths of a measurement in motion (N paths: the traced ones first, the
    moving point reflectors' after).

    moving : how each path follows the motion (N paths)
    traced : the traced paths at the emission pose (the first len(traced) of N)
    position_m : (N, 3) where each path last reflects at the start of the emission, m
    kind_codes : (N,) int, the paths' :class:`~acousim.trace.paths.PathKind` codes
    velocity_m_s : (N, 3) the velocity of each reflecting point, m/s
    points : (K,) indices into the scene's point reflectors of the moving ones heard
    rays : the rays the trace shot
    """

    moving: MovingPaths
    traced: TracedPaths
    position_m: np.ndarray
    kind_codes: np.ndarray
    velocity_m_s: np.ndarray
    points: np.ndarray
    rays: int

    @property
    def kinds(self) -> list[str]:
        """(N,) the paths' kind names."""
        return kind_names(self.kind_codes)

    @property
    def interactions(self) -> np.ndarray:
        """(N, K) the material interactions of each path (:mod:`acousim.core.materials`):
        the traced paths', zeros for the moving point reflectors after them."""
        counts = self.traced.interactions
        extra = np.zeros((len(self.moving) - len(counts), counts.shape[1]), int)
        return np.concatenate([counts, extra])


def paths_in_motion(
    tracer: PathTracer,
    pose: Pose,
    array: Array | None,
    *,
    traced: tuple[TracedPaths, int],
    points: tuple[PointItem, ...],
    speed_of_sound_m_s: float,
    reach_m: float,
) -> InMotion:
    """The paths of a measurement in motion starting at `pose` (see the module's
    steps): `traced` the paths at the pose and the rays shot (:meth:`Tracer.traced`
    of `pose` and `array`), `array` the sensor's (None: the tracer's scene's),
    `points` the scene's point reflectors (the moving ones are placed here),
    `reach_m` the longest way emitter -> point -> receiver heard (m)."""
    arr = tracer.scene.sensor.array if array is None else array
    paths, rays = traced
    emitter = pose.to_world(arr.emitter_m)
    receiver = pose.to_world(arr.positions_m.mean(axis=0))
    moving = MovingPaths.from_traced(paths, emitter)
    velocity = moving.velocity_m_s
    if isinstance(tracer, MovingWorld):
        on, normals, glint = tracer.riders(paths, pose, arr)
        ends = Endpoints(emitter, receiver, speed_of_sound_m_s)
        still = moving
        moving, velocity = ride(moving, paths, on, normals, glint, tracer.velocities(pose), ends)
        moving = follow_chains(tracer, moving, still, paths, pose, ends)
    position, kinds = paths.position_m, paths.kind
    index = np.array([i for i, p in enumerate(points) if p.moving], int)
    if index.size:
        now = [points[i].at(pose.time_s) for i in index]
        pos = np.array([x for x, _ in now], float)
        v = np.array([u for _, u in now], float)
        a = np.array([points[i].strength for i in index], float)
        caster = tracer.tracer_at(pose.time_s).caster
        keep, _ = heard_points(pos, emitter, receiver, reach_m, caster)
        extra = MovingPaths.points(pos[keep], a[keep], v[keep], emitter)
        moving = MovingPaths.concatenate([moving, extra])
        position = np.concatenate([position, pos[keep]])
        kinds = np.concatenate([kinds, np.full(int(keep.sum()), KIND.point, kinds.dtype)])
        velocity = np.concatenate([velocity, extra.velocity_m_s])
        index = index[keep]
    return InMotion(moving, paths, position, kinds, velocity, index, rays)
