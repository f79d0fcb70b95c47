"""From a scene and a pose to paths: shoot rays, refine specular paths, scatter.

Rays leave the emitter on a deterministic equal-area spiral over its beam (a cone of
half-angle ``beam_deg`` around the sensor's axis), so the result is a pure function
of the scene and the pose, and converges as rays are added.  Each ray bounces
specularly up to ``bounces`` times.

* Specular paths: every sequence of planes that a ray met (planar faces only) is a
  candidate; :mod:`acousim.trace.specular` makes it exact or rejects it.
* Scattering: at every hit on a curved face, or on a face whose material has a
  diffuse part, the hit is connected to the receiver (a shadow ray checks the view).
  The ray's power (its solid angle times the reflection factors so far) is
  re-radiated with a Gaussian lobe of width ``lobe_deg`` around the mirror
  direction (curved faces; weight ``(1 - diffuse) R^2``) plus a Lambert lobe
  (weight ``diffuse R^2``).  Contributions of one surface within one delay bin
  add their intensities into one
  point reflector at their intensity-weighted centroid; a bin is the call's range
  resolution ``c / bandwidth`` of path length (``DIFFUSE_BIN_FACTOR`` times that
  for the Lambert tail of planar walls), anchored at the surface's nearest
  contribution so that a glint is never split in two.  For a convex surface this
  converges to the geometric-optics echo (a sphere of radius a at range r:
  a / (2 r^2)) whatever the lobe width.
* The direct path emitter -> microphone and the scene's explicit points.

Paths are stored in one form: a path's length to microphone p is
``first_leg + |anchor - p|`` and its pressure gain ``strength / |anchor - p|``
(an image source with first_leg 0, a scatterer or point at its position).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from acousim.scene.model import Scene
from acousim.scene.pose import Pose
from acousim.synth.echoes import Echoes

from .embree import RayCaster
from .geometry import World, build_world
from .specular import refine_sequences

__all__ = ["TracedPaths", "Tracer", "cone_directions", "KIND"]

log = logging.getLogger(__name__)

KIND = {"direct": 0, "specular": 1, "scatter": 2, "point": 3, "diffraction": 4}
#: diffuse (Lambert) contributions of planar walls are binned this many range
#: resolutions wide (see BENCHMARKS.md for the time it saves and the error it costs)
DIFFUSE_BIN_FACTOR = 4


@dataclass(frozen=True, eq=False)
class TracedPaths:
    """Every path of one pose (world frame).  N paths.

    anchor_m (N, 3), first_leg_m (N,), strength (N,): see the module docstring.
    position_m (N, 3): where the echo comes from (last reflection point, scatterer
    centroid, point reflector, the emitter for the direct path).
    order (N,): reflections; kind (N,): :data:`KIND` codes; departure (N, 3): unit
    direction leaving the emitter.
    """

    anchor_m: np.ndarray
    first_leg_m: np.ndarray
    strength: np.ndarray
    position_m: np.ndarray
    order: np.ndarray
    kind: np.ndarray
    departure: np.ndarray

    def __len__(self) -> int:
        return self.strength.size

    def echoes(
        self, mics_world: np.ndarray, emitter_axis: np.ndarray, speed_of_sound_m_s: float
    ) -> Echoes:
        """Delays and gains at microphones (M, 3) in the world frame."""
        last = np.linalg.norm(self.anchor_m[None, :, :] - mics_world[:, None, :], axis=2)
        last = np.maximum(last, 1e-6)
        length = self.first_leg_m[None, :] + last
        gain = self.strength[None, :] / last
        cos = np.clip(self.departure @ emitter_axis, -1, 1)
        return Echoes(length / speed_of_sound_m_s, gain, length, self.order.copy(), np.arccos(cos))

    def select(self, keep: np.ndarray) -> TracedPaths:
        return TracedPaths(
            *(
                getattr(self, f)[keep]
                for f in (
                    "anchor_m",
                    "first_leg_m",
                    "strength",
                    "position_m",
                    "order",
                    "kind",
                    "departure",
                )
            )
        )

    @staticmethod
    def concatenate(parts: list[TracedPaths]) -> TracedPaths:
        fields = ("anchor_m", "first_leg_m", "strength", "position_m", "order", "kind", "departure")
        return TracedPaths(*(np.concatenate([getattr(p, f) for p in parts]) for f in fields))

    @staticmethod
    def empty() -> TracedPaths:
        z3, z = np.zeros((0, 3)), np.zeros(0)
        return TracedPaths(z3, z, z, z3, np.zeros(0, int), np.zeros(0, int), z3)


def cone_directions(n: int, axis: np.ndarray, half_angle_rad: float) -> np.ndarray:
    """n unit vectors on an equal-area (Fibonacci) spiral over a cone around `axis`."""
    i = np.arange(n) + 0.5
    cos_t = 1 - (1 - np.cos(half_angle_rad)) * i / n
    sin_t = np.sqrt(np.maximum(0, 1 - cos_t**2))
    phi = i * np.pi * (3 - np.sqrt(5))
    local = np.column_stack([cos_t, sin_t * np.cos(phi), sin_t * np.sin(phi)])
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, a)
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    return local @ np.stack([a, u, v])


class Tracer:
    """Paths of a scene for any pose; one Embree scene, built once (only if the scene
    has meshes), and a cache so the same pose is not traced twice."""

    def __init__(self, scene: Scene, threads: int = 2) -> None:
        self.scene = scene
        self.world: World | None = build_world(scene) if scene.meshes else None
        self.caster = RayCaster(self.world.triangles, threads) if self.world else None
        if self.world is None:
            log.debug("scene %r has no meshes: no ray tracing", scene.name)
        self._cache: dict[tuple, TracedPaths] = {}

    def trace(self, pose: Pose) -> TracedPaths:
        key = pose.key()
        if key in self._cache:
            log.debug("pose %s traced before: reusing its paths", key)
            return self._cache[key]
        paths = self._trace(pose)
        if len(self._cache) > 256:
            self._cache.clear()
        self._cache[key] = paths
        return paths

    # -- internals ---------------------------------------------------------------

    def _trace(self, pose: Pose) -> TracedPaths:
        scene, sim = self.scene, self.scene.simulation
        array = scene.sensor.array
        emitter = pose.to_world(array.emitter_m)
        receiver = pose.to_world(array.positions_m.mean(axis=0))
        axis = pose.rotation[:, 0]
        max_len = 2 * sim.max_range_m
        parts = []
        if scene.sensor.direct_path:
            mics = pose.to_world(array.positions_m)
            dep = mics.mean(axis=0) - emitter
            n = np.linalg.norm(dep)
            dep = dep / n if n > 0 else pose.rotation[:, 1]
            parts.append(
                TracedPaths(
                    emitter[None],
                    np.zeros(1),
                    np.ones(1),
                    emitter[None],
                    np.zeros(1, int),
                    np.full(1, KIND["direct"]),
                    dep[None],
                )
            )
        if scene.points:
            parts.append(self._points(emitter, receiver, max_len))
        if self.world is not None and sim.rays > 0:
            self._check_pose(emitter, receiver)
            parts.append(self._rays(emitter, receiver, axis, max_len))
        if self.world is not None and sim.diffraction:
            parts.append(self._diffraction(emitter, receiver, max_len))
        paths = TracedPaths.concatenate(parts) if parts else TracedPaths.empty()
        return self._floor(paths, receiver)

    def _diffraction(self, emitter, receiver, max_len) -> TracedPaths:
        """Edge diffraction (acousim.trace.diffraction), edges found once per scene."""
        from .diffraction import diffract
        from .edges import find_edges, triangles_mesh

        world, sim = self.world, self.scene.simulation
        if not hasattr(self, "_edges"):
            self._edges = find_edges(triangles_mesh(world.triangles))
            first = np.unique(world.plane, return_index=True)[1]
            refl = world.face_values("reflection")
            self._planes = (world.normals[first], world.offsets[first], refl[first])
        d = diffract(
            self._edges,
            self.caster,
            emitter,
            receiver,
            max_len,
            world.face_values("reflection"),
            sim.diffraction_step_m,
            self._planes if sim.diffraction_reflections else None,
            sim.energy_floor_db,
        )
        kind = np.full(len(d), KIND["diffraction"])
        return TracedPaths(
            d.anchor_m, d.first_leg_m, d.strength, d.position_m, d.order, kind, d.departure
        )

    def _check_pose(self, emitter: np.ndarray, receiver: np.ndarray) -> None:
        """A sensor inside a closed wall sees the inside of faces: refuse the pose."""
        dirs = cone_directions(64, np.array([1.0, 0, 0]), np.pi)
        t, f = self.caster.first_hit(np.broadcast_to(emitter, dirs.shape), dirs)
        hit = f >= 0
        if hit.sum() >= 48:
            facing = np.einsum("ij,ij->i", self.world.normals[f[hit]], dirs[hit]) > 0
            closed = not np.isinf(t).any()
            if facing.mean() > 0.9 and closed:
                raise ValueError(
                    f"scene {self.scene.name!r}: the sensor at {np.round(emitter, 3).tolist()} "
                    "is inside a closed mesh (a wall or object): move its pose"
                )

    def _points(self, emitter, receiver, max_len) -> TracedPaths:
        pts = np.array([p.position_m for p in self.scene.points], float)
        a = np.array([p.strength for p in self.scene.points], float)
        r_e = np.linalg.norm(pts - emitter, axis=1)
        r_r = np.linalg.norm(pts - receiver, axis=1)
        keep = (r_e > 0) & (r_e + r_r <= max_len)
        if self.caster is not None and keep.any():
            for src in (emitter, receiver):  # visible from the emitter and the receiver
                d = pts - src
                L = np.linalg.norm(d, axis=1)
                t, f = self.caster.first_hit(np.broadcast_to(src, d.shape), d)
                keep &= ~((f >= 0) & (t < L - 1e-6 * self.caster.scale))
        pts, a, r_e = pts[keep], a[keep], r_e[keep]
        n = len(a)
        return TracedPaths(
            pts,
            r_e,
            a / r_e,
            pts,
            np.ones(n, int),
            np.full(n, KIND["point"]),
            (pts - emitter) / r_e[:, None],
        )

    def _rays(self, emitter, receiver, axis, max_len) -> TracedPaths:
        sim, world, caster = self.scene.simulation, self.world, self.caster
        beam = np.deg2rad(sim.beam_deg)
        n_rays = sim.rays
        dirs = cone_directions(n_rays, axis, beam)
        d_omega = 2 * np.pi * (1 - np.cos(beam)) / n_rays
        eps = 1e-6 * caster.scale + 1e-7
        origin = np.broadcast_to(emitter, dirs.shape).copy()
        length = np.zeros(n_rays)
        power = np.full(n_rays, d_omega)
        departure = dirs.copy()
        planar = np.ones(n_rays, bool)
        seq = np.full((n_rays, sim.bounces), -1)
        alive = np.arange(n_rays)
        refl = world.face_values("reflection")
        diffuse = world.face_values("diffuse")
        lobe = np.deg2rad(world.face_values("lobe_deg"))
        scatter = world.curved | (diffuse > 0)
        n_planes = int(world.plane.max()) + 1
        surface = np.where(world.curved, world.plane.max() + 1 + world.component, world.plane)
        c = self.scene.environment.speed_of_sound_m_s
        lo, hi = self.scene.sensor.call.band_hz
        bin_len = c / (hi - lo)  # the call's range resolution, as a path length
        contributions = []
        sequences: set[tuple[int, ...]] = set()
        for b in range(sim.bounces):
            if alive.size == 0:
                break
            t, f = caster.first_hit(origin[alive], dirs[alive], max_len - length[alive])
            hit = f >= 0
            alive, t, f = alive[hit], t[hit], f[hit]
            x = origin[alive] + t[:, None] * dirs[alive]
            length[alive] += t
            seq[alive, b] = world.plane[f]
            planar[alive] &= ~world.curved[f]
            rows = seq[alive[planar[alive]], : b + 1]
            if rows.size:  # unique rows via one integer code per row (np.unique(axis=0) is slow)
                code = rows @ (n_planes ** np.arange(b + 1)).astype(np.int64)
                _, first = np.unique(code, return_index=True)
                sequences.update(tuple(int(v) for v in rows[i]) for i in first)
            normal = self._normals(x, f)
            inc = dirs[alive]
            flip = np.einsum("ij,ij->i", normal, inc) > 0
            normal[flip] *= -1  # the side the ray came from
            mirror = inc - 2 * np.einsum("ij,ij->i", inc, normal)[:, None] * normal
            sc = scatter[f]
            if sc.any():
                contributions.append(
                    self._scatter(
                        x[sc],
                        normal[sc],
                        mirror[sc],
                        power[alive[sc]],
                        length[alive[sc]],
                        departure[alive[sc]],
                        f[sc],
                        receiver,
                        refl,
                        diffuse,
                        lobe,
                        surface,
                        b + 1,
                        max_len,
                        eps,
                    )
                )
            # continue specularly
            power[alive] *= refl[f] ** 2 * (1 - diffuse[f])
            origin[alive] = x + eps * normal
            dirs[alive] = mirror
            alive = alive[(length[alive] < max_len) & (power[alive] > 0)]
        specular = refine_sequences(world, caster, sorted(sequences), emitter, receiver)
        parts = [self._specular_paths(specular, emitter, max_len)]
        if contributions:
            parts.append(self._cluster(contributions, receiver, bin_len))
        log.debug(
            "traced %d rays: %d candidate sequences, %d specular paths, %d scatterers",
            n_rays,
            len(sequences),
            len(specular),
            len(parts[-1]) if contributions else 0,
        )
        return TracedPaths.concatenate(parts)

    def _normals(self, x: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Face normals, smooth (barycentric interpolation) on curved faces."""
        world = self.world
        n = world.normals[f].copy()
        cv = world.curved[f]
        if cv.any():
            from trimesh.triangles import points_to_barycentric

            b0, b1, b2 = points_to_barycentric(world.triangles[f[cv]], x[cv]).T
            vn = world.vertex_normals[f[cv]]
            sm = b0[:, None] * vn[:, 0] + b1[:, None] * vn[:, 1] + b2[:, None] * vn[:, 2]
            n[cv] = sm / np.linalg.norm(sm, axis=1, keepdims=True)
        return n

    def _scatter(
        self,
        x,
        normal,
        mirror,
        power,
        length,
        departure,
        f,
        receiver,
        refl,
        diffuse,
        lobe,
        surface,
        order,
        max_len,
        eps,
    ):
        v = receiver - x
        r2 = np.linalg.norm(v, axis=1)
        u = v / r2[:, None]
        cos_s = np.einsum("ij,ij->i", u, normal)
        ok = (cos_s > 0) & (length + r2 <= max_len)
        # shadow ray towards the receiver
        idx = np.flatnonzero(ok)
        t, hit = self.caster.first_hit(x[idx] + eps * normal[idx], v[idx])
        blocked = (hit >= 0) & (t < r2[idx] - eps)
        ok[idx[blocked]] = False
        psi = np.arccos(np.clip(np.einsum("ij,ij->i", u, mirror), -1, 1))
        sig = lobe[f]
        R2 = refl[f] ** 2
        spec = np.where(self.world.curved[f], (1 - diffuse[f]) * R2, 0.0)
        pattern = spec * np.exp(-0.5 * (psi / sig) ** 2) / (2 * np.pi * sig**2)
        pattern += diffuse[f] * R2 * cos_s / np.pi
        intensity = np.where(ok, power * pattern / r2**2, 0.0)
        keep = intensity > 0
        return (
            x[keep],
            intensity[keep],
            length[keep],
            r2[keep],
            departure[keep],
            surface[f[keep]],
            np.full(keep.sum(), order),
        )

    def _cluster(self, contributions, receiver, bin_len) -> TracedPaths:
        x, inten, L1, r2, dep, surf, order = (np.concatenate(v) for v in zip(*contributions))
        if inten.size == 0:
            return TracedPaths.empty()
        total = L1 + r2
        _, group = np.unique(surf.astype(np.int64) * 16 + order, return_inverse=True)
        group = group.ravel()
        start = np.full(group.max() + 1, np.inf)
        np.minimum.at(start, group, total)
        # bins anchored at each surface's nearest contribution, so that a compact glint
        # (the specular region of a curved surface) is never split between two bins
        # diffuse scattering from planar walls is a smooth tail: coarser bins there
        planar = surf <= self.world.plane.max()
        width = np.where(planar, DIFFUSE_BIN_FACTOR * bin_len, bin_len)
        bins = np.floor((total - start[group]) / width).astype(np.int64)
        _, inv = np.unique(group.astype(np.int64) * (bins.max() + 1) + bins, return_inverse=True)
        inv = inv.ravel()
        n = inv.max() + 1
        w = np.bincount(inv, inten, n)

        def mean(v):
            return (
                np.stack([np.bincount(inv, inten * v[:, k], n) for k in range(v.shape[1])], axis=1)
                / w[:, None]
            )

        pos = mean(x)
        first = np.bincount(inv, inten * L1, n) / w
        d = mean(dep)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        ordr = np.bincount(inv, order, n) // np.bincount(inv, None, n)
        r_c = np.linalg.norm(receiver - pos, axis=1)
        return TracedPaths(
            pos, first, np.sqrt(w) * r_c, pos, ordr.astype(int), np.full(n, KIND["scatter"]), d
        )

    def _specular_paths(self, specular, emitter, max_len) -> TracedPaths:
        if not specular:
            return TracedPaths.empty()
        image = np.array([p.image_m for p in specular])
        amp = np.array([p.amplitude for p in specular])
        pos = np.array([p.points_m[-1] for p in specular])
        dep = np.array([p.departure for p in specular])
        order = np.array([len(p.planes) for p in specular])
        paths = TracedPaths(
            image, np.zeros(len(amp)), amp, pos, order, np.full(len(amp), KIND["specular"]), dep
        )
        return paths.select(np.linalg.norm(image - emitter, axis=1) <= max_len * 1.01)

    def _floor(self, paths: TracedPaths, receiver: np.ndarray) -> TracedPaths:
        if len(paths) == 0:
            return paths
        level = np.abs(paths.strength) / np.maximum(
            np.linalg.norm(paths.anchor_m - receiver, axis=1), 1e-6
        )  # diffraction paths are signed
        echo = paths.kind != KIND["direct"]
        top = level[echo].max() if echo.any() else level.max()
        keep = ~echo | (level >= top * 10 ** (self.scene.simulation.energy_floor_db / 20))
        if (~keep).any():
            log.debug(
                "dropped %d paths below the %.0f dB energy floor",
                int((~keep).sum()),
                self.scene.simulation.energy_floor_db,
            )
        return paths.select(keep)
