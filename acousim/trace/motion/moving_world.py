"""Meshes that move (a person, another robot): the world at each emission instant, and
how the paths that end on a moving mesh follow it during the measurement.

A moving mesh translates rigidly (``MeshItem.velocity_m_s`` or ``track``) and may turn
at a constant rate about its origin (``MeshItem.angular_velocity_rad_s``).  For one
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
3. **Their motion** (:func:`ride`), with u the velocity of the point at the start of
   the emission (``v + w x (x - o)`` on a turning mesh; a glint, on a curved face,
   slides over the turning surface and takes the mesh's translation v), d_in /
   d_out the unit directions in which the sound arrives at / leaves
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

4. **Reflections of second order and up** (:func:`follow_chains`): each specular
   path's reflection points are found again by following its departure through the
   world (:func:`bounces`); if any lies on a moving mesh (seen from the point
   before), the path's image is rebuilt with every plane where it is when the
   sound meets it, at the start of the emission and a little later
   (:func:`ride_chain`; this replaces step 3's law for those paths): within 1 ns of
   the retarded-time solutions of two and three planes in the tests.

   Stated approximation: a scattered or diffracted path that meets a moving mesh
   before its last point is rendered as if the mesh stood where it is at the start
   of the emission (right delay at that instant, no Doppler from it), and a path
   whose reflection points cannot be found again (grazing, at an edge) keeps
   step 3's law.  The error of the image sources against the wall traced again
   at the reflection instant is measured in ``benchmarks/motion.py``.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np

from acousim.scene.model import Scene
from acousim.scene.pose import Pose
from acousim.trace.motion.following import Endpoints, FirstLeg
from acousim.trace.options import TraceSettings
from acousim.trace.paths import KIND, TracedPaths
from acousim.trace.tracer import Tracer
from acousim.trace.world.build import _load, _unreadable
from acousim.trace.world.embree import RayCaster

__all__ = ["MovingWorld", "ride", "bounces", "ride_chain", "follow_chains"]

#: the image of a chain of moving planes is solved at the start of the emission, this
#: much later and half way, and moves on the parabola through the three (a turning
#: plane's image moves on a circle; the calls of the sensors last 1-5 ms)
CHAIN_SPAN_S = 5e-3
#: a scattered path's position (the mean of its hits) may lie this far inside a curved
#: moving mesh and still belong to it (m)
CLUSTER_DEPTH_M = 0.05


@dataclasses.dataclass(frozen=True)
class Motions:
    """K moving meshes at the start of an emission: velocity (K, 3) of their origins
    (m/s), angular velocity (K, 3) (rad/s, world frame) and origin (K, 3) (m)."""

    velocity: np.ndarray
    angular: np.ndarray
    origin: np.ndarray

    def of_points(self, k: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Velocities (N, 3) of points `x` (N, 3) of meshes `k` (N,)."""
        return self.velocity[k] + np.cross(self.angular[k], x - self.origin[k])


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

    def trace(self, pose: Pose, array=None) -> TracedPaths:
        """Every path of `pose` (and `array`: :meth:`Tracer.trace`), the moving meshes
        where they are at ``pose.time_s``."""
        return self.tracer_at(pose.time_s).trace(pose, array)

    def traced(
        self, pose: Pose, array=None, max_path_m: float | None = None, min_path_m=None, direct=None
    ):
        """The paths of `pose` and the rays shot (:meth:`Tracer.traced`)."""
        return self.tracer_at(pose.time_s).traced(pose, array, max_path_m, min_path_m, direct)

    def rays_used(self, pose: Pose, array=None) -> int:
        """How many rays the trace of `pose` (and `array`) shot."""
        return self.tracer_at(pose.time_s).rays_used(pose, array)

    def velocities(self, pose: Pose) -> Motions:
        """The moving meshes' motions at the start of the emission."""
        meshes = [self.scene.meshes[i] for i in self.moving]
        now = [m.at(pose.time_s) for m in meshes]
        return Motions(
            np.array([v for _, v in now], float).reshape(-1, 3),
            np.array([m.angular_velocity_at(pose.time_s) for m in meshes], float).reshape(-1, 3),
            np.array([o for o, _ in now], float).reshape(-1, 3),
        )

    @property
    def turning(self) -> bool:
        """Whether a moving mesh turns."""
        return any(self.scene.meshes[i].turning for i in self.moving)

    def riders(self, paths: TracedPaths, pose: Pose, array=None):
        """Which moving mesh each path's last point lies on (N,) (an index into
        :meth:`velocities`, -1: none), the normal (N, 3) of the face it lies on, and
        whether that face is curved (N,) (a glint there slides over the surface)."""
        on = np.full(len(paths), -1)
        normals = np.zeros((len(paths), 3))
        ask = np.flatnonzero((paths.kind != KIND["direct"]) & (paths.kind != KIND["point"]))
        array = self.scene.sensor.array if array is None else array
        receiver = pose.to_world(array.positions_m.mean(axis=0))
        glint = np.zeros(len(paths), bool)
        on[ask], normals[ask], glint[ask] = self.on_moving(pose, receiver, paths.position_m[ask])
        return on, normals, glint

    def on_moving(self, pose: Pose, origin: np.ndarray, points: np.ndarray):
        """Which moving mesh each of `points` (P, 3) lies on, seen from `origin` (3,)
        (the first surface a ray meets on the way there, at the point), and the
        normal of the face there, and whether that face is curved: (P,) indices (-1:
        none), (P, 3), (P,)."""
        on = np.full(len(points), -1)
        normals = np.zeros((len(points), 3))
        curved = np.zeros(len(points), bool)
        if not len(points) or not self.moving:
            return on, normals, curved
        _, tracer, alone = self._world(pose.time_s)
        d = points - origin
        length = np.linalg.norm(d, axis=1)
        start = np.broadcast_to(origin, d.shape)
        t_world, f_world = tracer.caster.first_hit(start, d)
        tol = 10 * tracer.caster.tolerance_m
        for k, (caster, face_normals) in enumerate(alone):
            t, face = caster.first_hit(start, d)
            hit = (face >= 0) & np.isfinite(t_world)
            hit[hit] = np.abs(t[hit] - t_world[hit]) <= tol  # the first surface met
            hit &= (t <= length + tol) & (t >= length - CLUSTER_DEPTH_M)  # at the point
            hit &= on < 0
            on[hit] = k
            normals[hit] = face_normals[face[hit]]
            curved[hit] = tracer.world.curved[f_world[hit]]
        return on, normals, curved


def bounces(paths: TracedPaths, tracer, emitter: np.ndarray, min_order: int = 2) -> list[tuple]:
    """The reflection points and normals of the specular paths of order `min_order`
    and more, found again by following each path's departure from the emitter (3,)
    through the world of `tracer` (a :class:`~acousim.trace.tracer.Tracer`): a
    specular path's ray meets its own reflection points in turn.  Per order N, a
    tuple (indices (S,), points (S, N, 3), unit normals (S, N, 3) towards the side
    the sound comes from); a path whose ray does not end at its traced last point
    (within 1 um: grazing or an edge) or that meets a curved surface (a glint: no
    plane to mirror in) is left out (it keeps the last-reflection law alone)."""
    out = []
    if tracer.caster is None:
        return out
    specular = paths.kind == KIND["specular"]
    for order in np.unique(paths.order[specular & (paths.order >= min_order)]).tolist():
        idx = np.flatnonzero(specular & (paths.order == order))
        o = np.broadcast_to(emitter, (idx.size, 3)).copy()
        d = paths.departure[idx].copy()
        pts = np.empty((idx.size, order, 3))
        nrm = np.empty((idx.size, order, 3))
        ok = np.ones(idx.size, bool)
        for b in range(order):
            t, f = tracer.caster.first_hit(o, d)
            ok &= f >= 0
            ok &= ~tracer.world.curved[np.where(ok, f, 0)]  # planes only (no glints)
            x = o + np.where(ok, t, 0.0)[:, None] * d
            n = tracer.world.normals[np.where(ok, f, 0)]
            n = np.where((np.einsum("ij,ij->i", n, d) > 0)[:, None], -n, n)
            d = d - 2 * np.einsum("ij,ij->i", d, n)[:, None] * n
            pts[:, b], nrm[:, b] = x, n
            o = x + tracer.caster.offset_m * d
        ok &= np.linalg.norm(pts[:, -1] - paths.position_m[idx], axis=1) < 1e-6
        if ok.any():
            out.append((idx[ok], pts[ok], nrm[ok]))
    return out


def ride(moving, paths: TracedPaths, on, normals, glint, velocities, ends: Endpoints):
    """The :class:`~acousim.trace.motion.following.MovingPaths` `moving` (from `paths`, traced
    with the emitter at ``ends.emitter_m``) with the paths whose last point lies on a
    moving mesh (`on` (N,), an index into `velocities` (:class:`Motions`), -1: none; on a face
    of normal `normals` (N, 3)) following it, by the laws of the module docstring
    (step 3); and the velocity of each path's last point (N, 3), for the ground
    truth."""
    emitter, receiver, c = ends.emitter_m, ends.receiver_m, ends.speed_of_sound_m_s
    truth = moving.velocity_m_s.copy()
    sel = np.flatnonzero(on >= 0)
    if sel.size == 0:
        return moving, truth
    x = paths.position_m[sel]
    a0 = moving.anchor_m[sel]
    d_out = _unit(receiver - x)
    image = paths.first_leg_m[sel] <= 0
    straight = ~image & (
        np.abs(paths.first_leg_m[sel] - np.linalg.norm(x - emitter, axis=1)) <= 1e-9
    )
    # a point of a turning mesh moves at v + w x (x - o); a glint (reached straight,
    # on a curved face: `glint` (N,)) is no material point: it slides over the
    # turning surface, and follows the mesh's translation alone (exact for a body of
    # revolution spinning about its axis, a sphere about its centre)
    glint = straight & glint[sel]
    u = np.where(glint[:, None], velocities.velocity[on[sel]], velocities.of_points(on[sel], x))
    truth[sel] = u
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
    first[sel[straight]] = FirstLeg.exact
    # an image source: the emitter moving by de shortens the way to the plane by
    # d_in . de, so the sound meets the plane (d_in . de) / c sooner
    mirror = moving.mirror.copy()
    mirror[sel[image]] -= u_image[image][:, :, None] * d_in[image][:, None, :] / c
    out = dataclasses.replace(
        moving, anchor_m=anchor, velocity_m_s=velocity, first_leg=first, mirror=mirror
    )
    return out, truth


def ride_chain(moving, base, idx, pts, nrm, on, velocities, ends: Endpoints):
    """`moving` with the image sources `idx` (S,) of N-th order specular paths
    (reflection points `pts` (S, N, 3) at the start of the emission, normals `nrm`
    (S, N, 3), from :func:`bounces`) that meet a moving mesh (`on` (S, N): the mesh
    of each reflection, an index into `velocities` (K, 3), -1: a still face)
    following every moving plane, in the order the sound meets them; `base`: the
    same paths before :func:`ride` (whose law for the last reflection this replaces).

    Each plane b (its point x_b, normal n_b, velocity u_b) at time t is
    ``n_b . y = n_b . x_b + (n_b . u_b) t``.  For the sound emitted at tau the images
    are built in the order the sound meets the planes, each plane where it is when
    the sound meets it: leaving image I along d (the direction it arrives in) it
    meets plane b after s with ``s (n_b . d - n_b . u_b / c) = n_b . x_b +
    (n_b . u_b) tau - n_b . I``, at ``t_b = tau + s / c``, and the next image is I
    mirrored in the plane there (:func:`_chain_image`, which also finds the
    reflection points again for those instants).  The last image is solved so at
    the start of the emission and CHAIN_SPAN_S later and moves linearly between;
    the anchor moves by what the motion adds to the still chain; an emitter moving
    by de makes the sound arrive ``departure . de / c`` sooner.  Against the
    retarded-time solutions of two and three planes: within 1 ns (the tests)."""
    rows = np.flatnonzero((on >= 0).any(axis=1))
    if rows.size == 0:
        return moving
    idx, pts, nrm, on = idx[rows], pts[rows], nrm[rows], on[rows]
    S = idx.size
    receiver, c = ends.receiver_m, ends.speed_of_sound_m_s
    e = np.broadcast_to(ends.emitter_m, (S, 3)).astype(float)
    k = np.maximum(on, 0)
    mov = (on >= 0)[..., None]
    planes = (
        nrm,
        pts,
        np.where(mov, velocities.velocity[k], 0.0),  # (S, N, 3) each
        np.where(mov, velocities.angular[k], 0.0),
        np.where(mov, velocities.origin[k], 0.0),
    )
    still = (nrm, pts, *(np.zeros_like(pts) for _ in range(3)))
    # the image at three emission instants: P0 + V tau + A tau^2 / 2 through them
    h = CHAIN_SPAN_S / 2
    P0, P1, P2 = (_chain_image(tau, e, planes, receiver, c) for tau in (0.0, h, 2 * h))
    V = (4 * P1 - 3 * P0 - P2) / (2 * h)
    A = (P2 - 2 * P1 + P0) / h**2
    P_still = _chain_image(0.0, e, still, receiver, c)
    anchor = moving.anchor_m.copy()
    velocity = moving.velocity_m_s.copy()
    mirror = moving.mirror.copy()
    anchor[idx] = base.anchor_m[idx] + (P0 - P_still)
    velocity[idx] = base.velocity_m_s[idx] + V
    acceleration = moving.acceleration_m_s2.copy()
    acceleration[idx] = base.acceleration_m_s2[idx] + A
    mirror[idx] = base.mirror[idx] - V[:, :, None] * base.departure[idx][:, None, :] / c
    return dataclasses.replace(
        moving,
        anchor_m=anchor,
        velocity_m_s=velocity,
        mirror=mirror,
        acceleration_m_s2=acceleration,
    )


def _turn(w: np.ndarray, vectors: np.ndarray, t) -> np.ndarray:
    """`vectors` (..., 3) turned at angular velocities `w` (..., 3) (rad/s) for `t`
    (...) s (Rodrigues)."""
    rot = w * np.asarray(t, float)[..., None]
    angle = np.linalg.norm(rot, axis=-1, keepdims=True)
    axis = rot / np.where(angle > 0, angle, 1.0)
    cos, sin = np.cos(angle), np.sin(angle)
    along = np.sum(axis * vectors, axis=-1, keepdims=True)
    return vectors * cos + np.cross(axis, vectors) * sin + axis * along * (1 - cos)


def _plane_at(planes, b: int, t: np.ndarray):
    """Normal (S, 3) and offset (S,) of plane b of each chain at times `t` (S,): the
    plane through x_b with normal n_b at time 0, of a mesh moving at v, turning at w
    about its origin o (all (S, N, 3) in `planes`)."""
    n0, x0, v, w, o = (a[:, b] for a in planes)
    if not w.any():  # translating only
        return n0, np.einsum("ij,ij->i", n0, x0 + v * t[:, None])
    n = _turn(w, n0, t)
    q = o + v * t[:, None] + _turn(w, x0 - o, t)
    return n, np.einsum("ij,ij->i", n, q)


def _chain_image(tau, e, planes, receiver, c: float) -> np.ndarray:
    """The last image (S, 3) of the sound emitted at `tau` (s) from `e` (S, 3) by way
    of S chains of N planes (`planes`: normals and points (S, N, 3) at time 0, the
    velocity, angular velocity and origin of each plane's mesh, zero for a still
    one), each plane where it is when the sound meets it (:func:`ride_chain`): the
    instant solved by fixed-point iteration (contracting by about v / c); the
    reflection points, first the traced ones, found again from the receiver (3,)
    back and the chain redone (three times: they move by about (v / c) times the
    path, an effect of second order)."""
    pts = planes[1]
    S, N = pts.shape[:2]
    x = pts
    for _ in range(3):
        prev = np.concatenate([e[:, None], x[:, :-1]], axis=1)
        d = _unit(x - prev)  # the direction the sound meets each plane in
        P = e.copy()
        images, hit = np.empty((S, N, 3)), np.empty((S, N))
        for b in range(N):
            t = np.full(S, float(tau))
            if planes[3][:, b].any():  # turning: when the sound meets it, iterated
                for _ in range(5):
                    n, h = _plane_at(planes, b, t)
                    s = (h - np.einsum("ij,ij->i", n, P)) / np.einsum("ij,ij->i", n, d[:, b])
                    t = tau + s / c
            else:  # translating: n . (P + s d) = n . (x0 + v (tau + s / c)), linear in s
                n, x0, v = planes[0][:, b], planes[1][:, b], planes[2][:, b]
                nv = np.einsum("ij,ij->i", n, v)
                s = (np.einsum("ij,ij->i", n, x0 - P) + nv * tau) / (
                    np.einsum("ij,ij->i", n, d[:, b]) - nv / c
                )
                t = tau + s / c
            n, h = _plane_at(planes, b, t)
            hit[:, b] = t
            P = P - 2 * (np.einsum("ij,ij->i", n, P) - h)[:, None] * n
            images[:, b] = P
        # each point on the line from its image to the next point (the receiver
        # last), on its plane where it is when the sound meets it
        x = np.empty_like(pts)
        towards = np.broadcast_to(receiver, (S, 3))
        for b in range(N - 1, -1, -1):
            n, h = _plane_at(planes, b, hit[:, b])
            A = images[:, b]
            step = (h - np.einsum("ij,ij->i", n, A)) / np.einsum("ij,ij->i", n, towards - A)
            x[:, b] = A + step[:, None] * (towards - A)
            towards = x[:, b]
    return P


def follow_chains(
    world: MovingWorld, moving, base, paths: TracedPaths, pose: Pose, ends: Endpoints
):
    """`moving` with every specular path of order two or more that meets a moving
    mesh following it at each of its reflections (:func:`bounces` in the world of
    the emission instant; each point tested with :meth:`MovingWorld.on_moving` from
    the point before it; :func:`ride_chain`); `base`: the paths before :func:`ride`."""
    velocities = world.velocities(pose)
    offset = world.tracer_at(pose.time_s).caster.offset_m
    # a turning plane's image moves in ways the last-reflection law does not know:
    # then first-order reflections take this way too
    first = 1 if world.turning else 2
    emitter = ends.emitter_m
    for idx, pts, nrm in bounces(paths, world.tracer_at(pose.time_s), emitter, first):
        on = np.full((idx.size, pts.shape[1]), -1)
        for b in range(pts.shape[1]):
            # from the point before (off its face, or it would meet that face first)
            if b == 0:
                origin = emitter
            else:
                origin = pts[:, b - 1] + offset * _unit(pts[:, b] - pts[:, b - 1])
            on[:, b] = world.on_moving(pose, origin, pts[:, b])[0]
        moving = ride_chain(moving, base, idx, pts, nrm, on, velocities, ends)
    return moving


def _caster(item) -> tuple[RayCaster, np.ndarray]:
    """A ray caster of one mesh item alone, and its face normals (F, 3)."""
    mesh = _load(item.mesh, item.transform)
    return RayCaster(np.asarray(mesh.triangles), 1), np.asarray(mesh.face_normals)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _read(path):
    import trimesh

    try:
        return trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds
        raise _unreadable(path, exc) from None


def _with_meshes(scene: Scene, meshes) -> Scene:
    """A shallow copy of `scene` with other meshes (not a new Scene: the caller's
    scene may hold only moving points besides, which a new Scene would refuse)."""
    import copy

    out = copy.copy(scene)
    object.__setattr__(out, "meshes", tuple(meshes))
    return out
