"""Meshes that move (a person, another robot): the world at each emission instant, and
how the paths that end on a moving mesh follow it during the measurement.

A moving mesh translates rigidly (``MeshItem.velocity_m_s`` or ``track``).  For one
measurement, whose emission starts at ``pose.time_s``:

1. **World per emission instant** (:class:`MovingWorld`): the Embree scene is rebuilt
   with every moving mesh where it is at the start of the emission (the static meshes
   are read from their files once); so which paths exist, and what the moving mesh
   hides, is that of the emission instant.  A scene without moving meshes never comes
   here: it keeps its one world, built once (:class:`~acousim.trace.tracer.Tracer`).
2. **Which paths ride on a moving mesh** (:meth:`MovingWorld.riders`): a path whose
   last reflection or scattering point (``TracedPaths.position_m``) lies on a moving
   mesh, seen from the array centre (a ray to the point meets that mesh first, at the
   point).
3. **Their motion** (:func:`ride`), with u the mesh's velocity at the start of the
   emission, d_in / d_out the unit directions in which the sound arrives at / leaves
   the point, k = c / (c - d_in . u) (the reflection happens later on a receding mesh):

   - an image source (a specular reflection on a plane, any order): it moves at
     ``2 k (n . u) n`` (n the normal of the face hit), from where it is when the
     sound emitted at the start reaches the plane, and when the emitter moves by de
     the sound reaches the plane ``d_in . de / c`` sooner (a term of the path's
     ``mirror``).  Monostatic and head-on this is exact (echo at
     ``2 d / (c + v)``, compressed by ``(c + v) / (c - v)``); otherwise the
     reflection point slides on the plane, which changes the path length only to
     second order (Fermat): 0.3 ns against tracing again at the reflection instant
     for a wall at 1.7 m/s and a sensor at 2 m/s and 180 deg/s;
   - a point reached straight from the emitter (a glint of a curved surface, a
     first-order scatterer or edge element): a point reflector moving with the mesh,
     its first leg solved exactly (retarded time) as for a moving point reflector;
   - higher-order scattered or diffracted paths: the last point moves with the mesh,
     the sound assumed to arrive from the receiver's side (d_in = -d_out), so the
     path lengthens at ``k (d_in - d_out) . u``.

4. **Second-order reflections that meet a moving mesh first** (:func:`ride_first`):
   the first reflection point is recovered from the traced path
   (:func:`first_reflections`), and if it lies on a moving mesh (seen from the
   emitter) the first image moves as above, mirrored in the second plane (within 1 ns
   of the two-plane retarded-time solution in the tests).

   Stated approximation: beyond these, a path that meets a moving mesh before its
   last reflection (third and higher orders, or a scattered path) is rendered as if
   the mesh stood where it is at the start of the emission: right delay at that
   instant, no Doppler from the mesh.  The error of the image sources against the
   wall traced again at the reflection instant is measured in ``benchmarks/motion.py``.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np

from acousim.scene.model import Scene
from acousim.scene.pose import Pose

from .embree import RayCaster
from .geometry import _load
from .paths import KIND, TracedPaths
from .settings import TraceSettings
from .tracer import Tracer

__all__ = ["MovingWorld", "ride", "ride_first", "first_reflections"]

#: a scattered path's position (the mean of its hits) may lie this far inside a curved
#: moving mesh and still belong to it (m)
CLUSTER_DEPTH_M = 0.05


class MovingWorld:
    """The tracer of a scene with moving meshes: a :class:`Tracer` per emission
    instant (the last one kept), same interface (``trace(pose)``)."""

    def __init__(self, scene: Scene, threads: int = 2) -> None:
        # every mesh read from its file once (a trimesh in memory is copied, never
        # changed, by the world's builder)
        meshes = tuple(
            dataclasses.replace(m, mesh=_read(m.mesh)) if m.path is not None else m
            for m in scene.meshes
        )
        self.scene = _with_meshes(scene, meshes)
        self.threads = threads
        self.moving = tuple(i for i, m in enumerate(meshes) if m.moving)
        # the worlds of the last few instants (Simulator.run traces the next pose in
        # a thread while this one renders)
        self._worlds: dict[float, tuple] = {}
        self._lock = threading.Lock()
        self.settings = TraceSettings.from_scene(self.scene)

    @property
    def world(self):
        """The world at time 0: its materials (and their spectra) are those of every
        instant, only the moving meshes' places change."""
        return self.tracer_at(0.0).world

    def forget(self) -> None:
        """Drop the worlds and paths traced so far (a benchmark's repetition pays for
        its traces)."""
        with self._lock:
            self._worlds.clear()

    def tracer_at(self, t_s: float) -> Tracer:
        """The tracer of the world at time `t_s` (moving meshes placed there)."""
        return self._world(t_s)[1]

    def _world(self, t_s: float) -> tuple:
        with self._lock:
            if t_s not in self._worlds:
                meshes = tuple(m.placed_at(t_s) for m in self.scene.meshes)
                tracer = Tracer(_with_meshes(self.scene, meshes), self.threads)
                alone = tuple(_caster(meshes[i]) for i in self.moving)
                if len(self._worlds) >= 3:
                    self._worlds.pop(next(iter(self._worlds)))
                self._worlds[t_s] = (t_s, tracer, alone)
            return self._worlds[t_s]

    def trace(self, pose: Pose) -> TracedPaths:
        """Every path of `pose`, the moving meshes where they are at ``pose.time_s``."""
        return self.tracer_at(pose.time_s).trace(pose)

    def velocities(self, pose: Pose) -> np.ndarray:
        """The moving meshes' velocities (K, 3) at the start of the emission."""
        v = [self.scene.meshes[i].at(pose.time_s)[1] for i in self.moving]
        return np.array(v, float).reshape(-1, 3)

    def riders(self, paths: TracedPaths, pose: Pose):
        """Which moving mesh each path's last point lies on (N,) (an index into
        :meth:`velocities`, -1: none) and the normal (N, 3) of the face it lies on."""
        on = np.full(len(paths), -1)
        normals = np.zeros((len(paths), 3))
        ask = np.flatnonzero((paths.kind != KIND["direct"]) & (paths.kind != KIND["point"]))
        receiver = pose.to_world(self.scene.sensor.array.positions_m.mean(axis=0))
        on[ask], normals[ask] = self.on_moving(pose, receiver, paths.position_m[ask])
        return on, normals

    def on_moving(self, pose: Pose, origin: np.ndarray, points: np.ndarray):
        """Which moving mesh each of `points` (P, 3) lies on, seen from `origin` (3,)
        (the first surface a ray meets on the way there, at the point), and the
        normal of the face there: (P,) indices (-1: none), (P, 3)."""
        on = np.full(len(points), -1)
        normals = np.zeros((len(points), 3))
        if not len(points) or not self.moving:
            return on, normals
        _, tracer, alone = self._world(pose.time_s)
        d = points - origin
        length = np.linalg.norm(d, axis=1)
        start = np.broadcast_to(origin, d.shape)
        t_world, _ = tracer.caster.first_hit(start, d)
        tol = 10 * tracer.caster.tolerance_m
        for k, (caster, face_normals) in enumerate(alone):
            t, face = caster.first_hit(start, d)
            hit = (face >= 0) & np.isfinite(t_world)
            hit[hit] = np.abs(t[hit] - t_world[hit]) <= tol  # the first surface met
            hit &= (t <= length + tol) & (t >= length - CLUSTER_DEPTH_M)  # at the point
            hit &= on < 0
            on[hit] = k
            normals[hit] = face_normals[face[hit]]
        return on, normals


def first_reflections(paths: TracedPaths, emitter: np.ndarray):
    """The first reflection point (S, 3) of each second-order specular path, the
    paths' indices (S,), and their two unit normals (S, 3) each: from the emitter
    (3,), the departure, the last reflection point and the image source (unfolded,
    the first image lies on the line from the last point back along the middle leg at
    the image's distance)."""
    idx = np.flatnonzero((paths.kind == KIND["specular"]) & (paths.order == 2))
    dep, x2, image = paths.departure[idx], paths.position_m[idx], paths.anchor_m[idx]
    w = x2 - emitter
    R = np.linalg.norm(x2 - image, axis=1)
    den = 2 * (R - np.einsum("si,si->s", w, dep))
    s = (R**2 - np.einsum("si,si->s", w, w)) / np.where(np.abs(den) > 1e-12, den, 1.0)
    ok = (np.abs(den) > 1e-12) & (s > 1e-9)
    x1 = emitter + s[:, None] * dep
    mid = _unit(x2 - x1)
    n1 = _unit(mid - dep)
    n2 = _unit(_unit(x2 - image) - mid)
    ok &= np.linalg.norm(x2 - x1, axis=1) > 1e-9  # not both at one point (an edge)
    return x1[ok], idx[ok], n1[ok], n2[ok]


def ride(moving, paths: TracedPaths, on, normals, velocities, emitter, receiver, c: float):
    """The :class:`~acousim.synth.moving.MovingPaths` `moving` (from `paths`, traced
    with the emitter at `emitter` (3,)) with the paths whose last point lies on a
    moving mesh (`on` (N,), an index into `velocities` (K, 3), -1: none; on a face
    of normal `normals` (N, 3)) following it, by the laws of the module docstring
    (step 3); and the velocity of each path's last point (N, 3), for the ground
    truth."""
    from acousim.synth.moving import FIRST_LEG

    truth = moving.velocity_m_s.copy()
    sel = np.flatnonzero(on >= 0)
    if sel.size == 0:
        return moving, truth
    u = velocities[on[sel]]
    truth[sel] = u
    x = paths.position_m[sel]
    a0 = moving.anchor_m[sel]
    d_out = _unit(receiver - x)
    image = paths.first_leg_m[sel] <= 0
    straight = ~image & (
        np.abs(paths.first_leg_m[sel] - np.linalg.norm(x - emitter, axis=1)) <= 1e-9
    )
    n = normals[sel]
    # the sound met the plane along d_out mirrored in it (unknown elsewhere: from
    # the receiver's side)
    mirrored = d_out - 2 * np.einsum("ij,ij->i", d_out, n)[:, None] * n
    d_in = np.where(image[:, None], mirrored, -d_out)
    k = c / (c - np.einsum("ij,ij->i", d_in, u))
    s = np.einsum("ij,ij->i", d_in - d_out, u)
    # image sources: the mirror image of a translating plane
    u_image = 2 * (k * np.einsum("ij,ij->i", n, u))[:, None] * n
    # others: radial rate k s, the rest of the mesh's motion across the line of sight
    across = u - np.einsum("ij,ij->i", d_out, u)[:, None] * d_out
    u_other = k[:, None] * (across - s[:, None] * d_out)
    vel = np.where(image[:, None], u_image, np.where(straight[:, None], u, u_other))
    lead = np.where(image, np.linalg.norm(x - a0, axis=1) / c, 0.0)  # to the plane
    anchor = moving.anchor_m.copy()
    anchor[sel] = a0 + vel * lead[:, None]
    velocity = moving.velocity_m_s.copy()
    velocity[sel] = vel
    first = moving.first_leg.copy()
    first[sel[straight]] = FIRST_LEG["exact"]
    # an image source: the emitter moving by de shortens the way to the plane by
    # d_in . de, so the sound meets the plane (d_in . de) / c sooner
    mirror = moving.mirror.copy()
    mirror[sel[image]] -= u_image[image][:, :, None] * d_in[image][:, None, :] / c
    out = dataclasses.replace(
        moving, anchor_m=anchor, velocity_m_s=velocity, first_leg=first, mirror=mirror
    )
    return out, truth


def ride_first(moving, idx, x1, n1, n2, on1, velocities, emitter, c: float):
    """`moving` with the second-order image sources `idx` (S,) whose first reflection
    (at `x1` (S, 3), normal `n1`; the second plane's normal `n2`) lies on a moving
    mesh (`on1` (S,), -1: none) following it: the first image moves at
    ``2 k (n1 . u) n1`` from when the sound reaches the first plane, mirrored in the
    second plane (k and the emitter's timing as for the last reflection)."""
    sel = on1 >= 0
    if not sel.any():
        return moving
    idx, x1, n1, n2 = idx[sel], x1[sel], n1[sel], n2[sel]
    u = velocities[on1[sel]]
    d_in = _unit(x1 - emitter)
    k = c / (c - np.einsum("ij,ij->i", d_in, u))
    first_image = 2 * (k * np.einsum("ij,ij->i", n1, u))[:, None] * n1
    # mirrored in the second plane
    u_image = first_image - 2 * np.einsum("ij,ij->i", first_image, n2)[:, None] * n2
    lead = np.linalg.norm(x1 - emitter, axis=1) / c
    anchor = moving.anchor_m.copy()
    anchor[idx] += u_image * lead[:, None]
    velocity = moving.velocity_m_s.copy()
    velocity[idx] += u_image
    mirror = moving.mirror.copy()
    mirror[idx] -= u_image[:, :, None] * d_in[:, None, :] / c
    return dataclasses.replace(moving, anchor_m=anchor, velocity_m_s=velocity, mirror=mirror)


def _caster(item) -> tuple[RayCaster, np.ndarray]:
    """A ray caster of one mesh item alone, and its face normals (F, 3)."""
    mesh = _load(item.mesh, item.transform)
    return RayCaster(np.asarray(mesh.triangles), 1), np.asarray(mesh.face_normals)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _read(path):
    import trimesh

    from processing.errors import InputError

    try:
        return trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds
        raise InputError(f"cannot read mesh ({exc})", file=str(path)) from None


def _with_meshes(scene: Scene, meshes) -> Scene:
    """A shallow copy of `scene` with other meshes (not a new Scene: the caller's
    scene may hold only moving points besides, which a new Scene would refuse)."""
    import copy

    out = copy.copy(scene)
    object.__setattr__(out, "meshes", tuple(meshes))
    return out
