"""What the sensor sees of each traced path, for the ground truth
(:class:`processing.GroundTruth`): its delay and arrival direction at the array
centre, its apparent position, the first and last points of its chain and the
object it touched.

Every imaging sonar puts an echo along the direction it arrives from, at half its
path length: the apparent position ``centre + u c tau / 2`` (u the unit arrival
direction at the array centre, tau the two-way delay there).  For a first-order
echo it is the reflection point; a two-bounce echo (across a hallway and back) is
shown beyond its last reflection, where no surface is.

A static path's delay at the centre r is ``(first_leg + |anchor - r|) / c`` and it
arrives from its anchor (the image source, scatterer, point or edge element): the
renderer's law (:mod:`acousim.trace.paths`) at r.  In motion
(:mod:`acousim.kinematics.seen`), the reception time of the call's first sample at
the moving centre solves the retarded-time equation of
:mod:`acousim.kinematics.retarded` there; its direction is the anchor's from the
centre then, in the sensor's frame then.

Objects: a mesh's faces of one material are one object, ``"<mesh>/<material>"``
(the mesh's file name without its suffix, or ``mesh <i>``); a point reflector is
``point <i>`` (its index in the scene's points).  A path's object is that of its
last interaction, found by one ray from the array centre to its last point (the
last leg is free by construction; an edge point or a cluster of scattered hits a
little off its face is aimed beside, up to six more rays); its first point by one
ray along its departure (second order and up).  About two rays a path, nothing per
microphone.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acousim.core.vectors import row_norms
from acousim.trace.paths import KIND, TracedPaths
from processing.base.kernels import optional_kernel

__all__ = [
    "Seen",
    "apparent",
    "chain_fields",
    "chain_points",
    "object_table",
    "point_objects",
    "seen_static",
]

#: a ray to a path's last point may meet its face this far before or after it (m,
#: plus the same fraction of the distance): a cluster of scattered hits on a curved
#: face lies slightly off it
FACE_TOLERANCE_M = 0.02
#: the directions a missed point is aimed beside (unit, scaled by half the tolerance)
_NUDGES = np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])


@dataclass(frozen=True, eq=False)
class Seen:
    """What the sensor sees of N paths (the fields of the same names of
    :class:`processing.GroundTruth`; sensor frame of the pose at the start of the
    emission, world frame, SI units)."""

    delay_s: np.ndarray
    arrival_sensor: np.ndarray
    apparent_position_sensor_m: np.ndarray
    apparent_position_world_m: np.ndarray

    def fields(self) -> dict[str, np.ndarray]:
        """The four arrays by their GroundTruth names."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def apparent(
    delay_s: np.ndarray,
    arrival_sensor: np.ndarray,
    centre_sensor_m: np.ndarray,
    speed_of_sound_m_s: float,
) -> np.ndarray:
    """Apparent positions (N, 3), sensor frame (m): the array centre (3,) plus the
    unit arrival directions (N, 3) times half the path length ``c delay / 2``."""
    half = 0.5 * speed_of_sound_m_s * np.asarray(delay_s, float)
    return np.asarray(centre_sensor_m, float) + np.asarray(arrival_sensor, float) * half[:, None]


def seen_static(paths: TracedPaths, pose, centre_sensor_m: np.ndarray, c: float) -> Seen:
    """What the sensor sees of static `paths` at `pose` (a
    :class:`~acousim.scene.pose.Pose`): the renderer's delays at the array centre
    (`centre_sensor_m` (3,), sensor frame) and the anchors' directions from it."""
    centre = pose.to_world(np.asarray(centre_sensor_m, float)[None])[0]
    to = paths.anchor_m - centre
    last = np.maximum(np.linalg.norm(to, axis=1), 1e-9)
    delay = (paths.first_leg_m + last) / c
    u = (to / last[:, None]) @ pose.rotation  # world -> sensor: R^T u
    app = apparent(delay, u, centre_sensor_m, c)
    return Seen(delay, u, app, pose.to_world(app))


def object_table(scene, world) -> tuple[tuple[str, ...], np.ndarray]:
    """The scene's objects: their names (O,) (meshes' materials first, then the
    point reflectors in the scene's order) and the object of each face (F,) of
    `world` (-1: not known, a world without its faces' owners)."""
    names: list[str] = []
    faces = np.full(0 if world is None else world.n_faces, -1)
    if world is not None and world.owner is not None:
        labels = _mesh_labels(scene.meshes)
        pairs, inverse = np.unique(
            np.column_stack([world.owner, world.material]), axis=0, return_inverse=True
        )
        names += [f"{labels[m]}/{world.materials[k].name}" for m, k in pairs.tolist()]
        faces = inverse.reshape(-1)
    names += [f"point {i}" for i in range(len(scene.points))]
    return tuple(names), faces


def _mesh_labels(meshes) -> list[str]:
    """A short name per mesh: its file's stem (made unique with its index), else
    ``mesh <i>``."""
    stems = [Path(m.path).stem if m.path is not None else None for m in meshes]
    out = []
    for i, s in enumerate(stems):
        out.append(f"mesh {i}" if s is None else s if stems.count(s) == 1 else f"{s} {i}")
    return out


def chain_points(
    paths: TracedPaths,
    emitter_m: np.ndarray,
    receiver_m: np.ndarray,
    caster,
    face_object: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First points (N, 3), last points (N, 3) (world, m; NaN for the direct path)
    and the object index of each path's last interaction (N,) (-1: none found):
    see the module docstring.  `caster`: the world's
    :class:`~acousim.trace.world.embree.RayCaster` (None: no meshes)."""
    n = len(paths)
    last = paths.position_m.astype(float, copy=True)
    direct = paths.kind == KIND["direct"]
    last[direct] = np.nan
    first = last.copy()
    obj = np.full(n, -1)
    if caster is None or not n:
        return first, last, obj
    todo = np.flatnonzero(~direct & (paths.kind != KIND["point"]))
    # straight at the point, then (an edge, a cluster off its face) a little beside it
    receiver_m = np.asarray(receiver_m, float)
    for nudge in _NUDGES:
        if not todo.size:
            break
        aim, d = _aim(last, todo, receiver_m, nudge * (FACE_TOLERANCE_M / 2))
        hit = caster.first_hit(np.broadcast_to(receiver_m, aim.shape), aim)
        todo = _accept(todo, hit, d, face_object, obj)
    deep = np.flatnonzero(~direct & (paths.order > 1) & (paths.kind != KIND["point"]))
    if deep.size:
        t, face = caster.first_hit(
            np.broadcast_to(emitter_m, (deep.size, 3)), paths.departure[deep]
        )
        hit = np.isfinite(t)
        first[deep[hit]] = emitter_m + t[hit, None] * _unit(paths.departure[deep[hit]])
    return first, last, obj


def _aim(last, todo, receiver_m, shift) -> tuple[np.ndarray, np.ndarray]:
    """The rays (K, 3) from `receiver_m` (3,) at the points ``last[todo]`` moved by
    `shift` (3,) times one plus their distance, and their lengths (K,) (m)."""
    compiled = optional_kernel("acousim.trace._chain_kernel", "aim")
    if compiled is not None:
        out, dist = np.empty((todo.size, 3)), np.empty(todo.size)
        compiled(last, todo, receiver_m, np.asarray(shift, float), out, dist)
        return out, dist
    to = last[todo] - receiver_m
    d = np.linalg.norm(to, axis=1)
    out = to + shift * (1 + d[:, None])
    return out, np.linalg.norm(out, axis=1)


def _accept(todo, hit, dist, face_object, obj) -> np.ndarray:
    """The paths of `todo` whose ray (`hit`: distances and faces, :meth:`RayCaster.
    first_hit`) met no face within the tolerance of `dist` (m); the object of
    each that did written into `obj`."""
    compiled = optional_kernel("acousim.trace._chain_kernel", "accept")
    if compiled is not None:
        todo = np.array(todo)  # (compacted in place)
        return todo[: compiled(todo, hit, dist, FACE_TOLERANCE_M, face_object, obj)]
    t, face = hit
    ok = (face >= 0) & (np.abs(t - dist) <= FACE_TOLERANCE_M * (1 + dist))
    obj[todo[ok]] = face_object[face[ok]]
    return todo[~ok]


def chain_fields(
    tracer,
    scene,
    paths: TracedPaths,
    emitter_m: np.ndarray,
    receiver_m: np.ndarray,
    moving_points: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict:
    """The ground truth's chain fields (``first_point_m``, ``last_point_m``,
    ``object_index``, ``object_names``: :class:`processing.GroundTruth`) of the traced
    `paths`, found in `tracer`'s world (that of the emission instant), and after them
    of the moving point reflectors' paths: `moving_points` (their positions (K, 3), m,
    and indices (K,) into ``scene.points``)."""
    world = tracer.world
    names, faces = (
        object_table(scene, None)
        if world is None
        else world._cached("objects", lambda: object_table(scene, world))
    )
    first, last, obj = chain_points(paths, emitter_m, receiver_m, tracer.caster, faces)
    n_mesh = len(names) - len(scene.points)
    still = np.flatnonzero(paths.kind == KIND["point"])
    if still.size:
        where = np.array([p.position_m for p in scene.points], float)
        obj[still] = point_objects(paths.position_m[still], where, n_mesh)
    if moving_points is not None and len(moving_points[1]):
        at, index = moving_points
        first = np.concatenate([first, at])
        last = np.concatenate([last, at])
        obj = np.concatenate([obj, n_mesh + np.asarray(index, int)])
    return {
        "first_point_m": first,
        "last_point_m": last,
        "object_index": obj,
        "object_names": names,
    }


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(row_norms(v, keepdims=True), 1e-300)


def point_objects(positions_m: np.ndarray, scene_points_m: np.ndarray, start: int) -> np.ndarray:
    """The object index (N,) of point-reflector paths at `positions_m` (N, 3): that of
    the scene's point (P, 3) at the same place (``start + its index``; -1: none)."""
    pos = np.asarray(positions_m, float).reshape(-1, 3)
    pts = np.asarray(scene_points_m, float).reshape(-1, 3)
    if not len(pts) or not len(pos):
        return np.full(len(pos), -1)
    d = np.linalg.norm(pos[:, None] - pts[None], axis=2)
    k = np.argmin(d, axis=1)
    return np.where(
        d[np.arange(len(pos)), k] <= 1e-9 * (1 + np.abs(pts[k]).max(axis=1)), start + k, -1
    )
