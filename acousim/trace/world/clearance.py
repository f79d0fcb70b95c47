"""How far the sensor's emitter and microphones stand from the scene's surfaces.

A real emitter or microphone sits behind its sensor's housing and board: it never
touches a wall.  Nearer than :data:`SENSOR_CLEARANCE_M` the tracer's model does not
hold either (a wall 1 mm away is an image source 2 mm away, an echo of 1/(2 mm), and
a point on a face loses the face): such a pose is refused before it is traced.

The test: from every point, 26 rays (the directions to the neighbours of a cell in a
cube grid, :data:`DIRECTIONS`), each up to ``clearance / cos(COVER_RAD)``: every
direction lies within :data:`COVER_RAD` (27.6 degrees) of one of them, so a face
whose plane is nearer than the clearance is met by a ray (unless it is smaller than
about the clearance: an edge or a thin pole may pass between the rays).  A face met
counts by the distance from the point to its plane (not along the ray), so a face
at 1.05 cm met obliquely (1.13 cm along the ray) is not refused.
"""

from __future__ import annotations

import itertools

import numpy as np
import trimesh

from acousim.trace.world.build import World
from acousim.trace.world.embree import RayCaster
from processing.base.errors import InputError

__all__ = [
    "SENSOR_CLEARANCE_M",
    "DIRECTIONS",
    "COVER_RAD",
    "nearest_surface",
    "too_near",
    "check_clearance",
    "surface_mesh",
    "surface_distance",
]

SENSOR_CLEARANCE_M = 0.01
"""Nearest an emitter or a microphone may be to a mesh surface (m).  1 cm: a choice,
not a measurement; a real sensor's transducers sit behind its housing and board, so
a real sensor cannot put one nearer a wall than that, and nearer the echo model
fails (a wavelength is 14 mm at 25 kHz; the image source of a wall at 1 mm echoes a
thousand times the same wall at 1 m).  Every bundled scene keeps it."""

#: the 26 unit directions to a cube cell's neighbours (faces, edges, corners), (26, 3)
DIRECTIONS = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)], float)
DIRECTIONS /= np.linalg.norm(DIRECTIONS, axis=1)[:, None]
DIRECTIONS.flags.writeable = False


def _cover_angle() -> float:
    """The largest angle from any direction to the nearest of DIRECTIONS (rad): the
    circumradius of the spherical triangle of a face, an edge and a corner direction,
    (1, 0, 0), (1, 1, 0)/sqrt 2, (1, 1, 1)/sqrt 3 (0.4812 rad, 27.57 degrees)."""
    a, b, c = np.array([1.0, 0, 0]), np.array([1.0, 1, 0]) / np.sqrt(2), np.ones(3) / np.sqrt(3)
    centre = np.cross(b - a, c - a)
    return float(np.arccos(abs(centre @ a) / np.linalg.norm(centre)))


#: every direction lies within this angle of one of DIRECTIONS (rad)
COVER_RAD = _cover_angle()


def nearest_surface(
    caster: RayCaster, world: World, points_m: np.ndarray, clearance_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """For each point (K, 3): the distance (K,) to the plane of the nearest face its
    26 rays meet within ``clearance_m / cos(COVER_RAD)`` (m; inf: none) and that
    face's index (K,; -1: none)."""
    pts = np.asarray(points_m, float).reshape(-1, 3)
    k, n = len(pts), len(DIRECTIONS)
    origins = np.repeat(pts, n, axis=0)
    dirs = np.tile(DIRECTIONS, (k, 1))
    t, f = caster.first_hit(origins, dirs, clearance_m / np.cos(COVER_RAD))
    hit = f >= 0
    gap = np.full(k * n, np.inf)
    gap[hit] = t[hit] * np.abs(np.einsum("ij,ij->i", world.normals[f[hit]], dirs[hit]))
    gap = gap.reshape(k, n)
    best = gap.argmin(axis=1)
    rows = np.arange(k)
    return gap[rows, best], np.where(np.isfinite(gap[rows, best]), f.reshape(k, n)[rows, best], -1)


def too_near(
    caster: RayCaster, world: World, points_m: np.ndarray, clearance_m: float = SENSOR_CLEARANCE_M
) -> np.ndarray:
    """Which points (K, 3) the tracer refuses (K,) bool: a face nearer than
    `clearance_m` (m) met by one of their 26 rays (:func:`nearest_surface`).  The
    rule of :func:`check_clearance`, for a caller that redraws a refused point (a
    dataset's random poses) instead of stopping."""
    return nearest_surface(caster, world, points_m, clearance_m)[0] < clearance_m


def surface_mesh(world: World) -> trimesh.Trimesh:
    """The world's faces as a trimesh mesh, unprocessed (the same triangles), for
    :func:`surface_distance` (keep it: its search tree is built on first use)."""
    if world.vertices is not None:
        return trimesh.Trimesh(world.vertices, world.faces, process=False)
    corners = world.triangles.reshape(-1, 3)
    return trimesh.Trimesh(corners, np.arange(len(corners)).reshape(-1, 3), process=False)


def surface_distance(mesh: trimesh.Trimesh, points_m: np.ndarray) -> np.ndarray:
    """The true distance (K,) m from each point (K, 3) to the nearest point of any
    face of `mesh` (:func:`surface_mesh`; trimesh's closest-point queries): unlike
    :func:`nearest_surface`, exact at an edge, a corner or a face smaller than the
    distance."""
    pts = np.asarray(points_m, float).reshape(-1, 3)
    _, distance, _ = trimesh.proximity.closest_point(mesh, pts)
    return np.asarray(distance, float)


def check_clearance(
    caster: RayCaster,
    world: World,
    emitter_m: np.ndarray,
    mics_m: np.ndarray,
    clearance_m: float = SENSOR_CLEARANCE_M,
) -> None:
    """An InputError when the emitter (3,) or a microphone of `mics_m` (M, 3), world
    frame, lies nearer than `clearance_m` to a mesh surface: which one, where, how
    far, the face's material and the clearance."""
    ends = np.vstack([np.reshape(emitter_m, (1, 3)), np.reshape(mics_m, (-1, 3))])
    gap, face = nearest_surface(caster, world, ends, clearance_m)
    near = np.flatnonzero(gap < clearance_m)  # as too_near
    if not near.size:
        return
    i = int(near[np.argmin(gap[near])])
    what = "the emitter" if i == 0 else f"microphone {i - 1}"
    material = world.materials[world.material[face[i]]].name
    raise InputError(
        f"{what} at {np.round(ends[i], 4).tolist()} m is {gap[i]:.3g} m from a mesh surface "
        f"(material {material}); the emitter and every microphone must be at least "
        f"{clearance_m:g} m from every surface (a sensor's housing; nearer, the echo "
        "model does not hold): move the pose"
    )
