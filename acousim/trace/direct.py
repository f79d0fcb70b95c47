"""Paths that need no rays: the direct path emitter -> array and explicit points."""

from __future__ import annotations

import numpy as np

from acousim.trace.paths import KIND, TracedPaths
from acousim.trace.world.embree import RayCaster
from processing.base.errors import InputError

__all__ = [
    "direct_path",
    "point_paths",
    "heard_points",
    "check_points_clear",
    "point_gaps",
    "MIN_POINT_DISTANCE_M",
]

MIN_POINT_DISTANCE_M = 1e-3
"""Nearest a point reflector may be to the emitter or a microphone (m)."""


def direct_path(emitter: np.ndarray, receiver: np.ndarray, fallback: np.ndarray) -> TracedPaths:
    """The emitter heard at the microphones: anchor the emitter, strength 1; the
    departure points from the emitter to the array centre (`fallback` if they coincide)."""
    dep = receiver - emitter
    n = np.linalg.norm(dep)
    dep = dep / n if n > 0 else np.asarray(fallback, float)
    return TracedPaths(
        emitter[None],
        np.zeros(1),
        np.ones(1),
        emitter[None],
        np.zeros(1, int),
        np.full(1, KIND["direct"]),
        dep[None],
    )


def seen(points_m: np.ndarray, origins, caster: RayCaster) -> np.ndarray:
    """Which of the points (P, 3) every one of `origins` (each (3,)) sees: (P,) bool,
    no face met before the point (less the caster's ray offset: a point on a face
    is seen)."""
    keep = np.ones(len(points_m), bool)
    for src in origins:
        d = points_m - src
        L = np.linalg.norm(d, axis=1)
        t, f = caster.first_hit(np.broadcast_to(src, d.shape), d)
        keep &= ~((f >= 0) & (t < L - caster.offset_m))
    return keep


def heard_points(
    points_m: np.ndarray,
    emitter: np.ndarray,
    receiver: np.ndarray,
    max_path_m: float,
    caster: RayCaster | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Which point reflectors (P, 3) echo (every point reflector, still or moving, is
    selected here): within reach (the way emitter -> point -> receiver at most
    `max_path_m`) and visible from the emitter and from the receiver (if there are
    meshes): (P,) bool, and the distances (P,) from the emitter, m."""
    r_e = np.linalg.norm(points_m - emitter, axis=1)
    r_r = np.linalg.norm(points_m - receiver, axis=1)
    keep = (r_e > 0) & (r_e + r_r <= max_path_m)
    if caster is not None and keep.any():
        keep[keep] = seen(points_m[keep], (emitter, receiver), caster)
    return keep, r_e


def point_paths(
    points_m: np.ndarray,
    strength: np.ndarray,
    emitter: np.ndarray,
    receiver: np.ndarray,
    max_path_m: float,
    caster: RayCaster | None,
) -> TracedPaths:
    """Point reflectors (P, 3) of strength a_k (P,): 1. within reach, 2. visible from
    the emitter and from the receiver (if there are meshes), 3. gain a_k / r_e / r_r."""
    pts, a = np.asarray(points_m, float).reshape(-1, 3), np.asarray(strength, float)
    keep, r_e = heard_points(pts, emitter, receiver, max_path_m, caster)
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


def point_gaps(points, t_s: float, ends_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The point reflectors of `points` (scene items; at least one) where they are at
    time `t_s` (P, 3) m, and each one's distance (P,) m to the nearest of the emitters
    and microphones `ends_m` (K, 3); :func:`check_points_clear` refuses one nearer
    than :data:`MIN_POINT_DISTANCE_M`."""
    pts = np.array([p.at(t_s)[0] if p.moving else p.position_m for p in points])
    gap = np.linalg.norm(pts[:, None, :] - ends_m[None, :, :], axis=2).min(axis=1)
    return pts, gap


def check_points_clear(points, t_s: float, ends_m: np.ndarray, where: str) -> None:
    """An InputError when a point reflector of `points` (scene items, where they are at
    time `t_s`) lies within :data:`MIN_POINT_DISTANCE_M` of an emitter or microphone
    `ends_m` (K, 3): the point model's 1/r spreading would overflow the samples
    (checked before any computation).  `where`: the pose, for the message."""
    if not points:
        return
    pts, gap = point_gaps(points, t_s, ends_m)
    near = np.flatnonzero(gap < MIN_POINT_DISTANCE_M)
    if near.size:
        k = int(near[0])
        raise InputError(
            f"point reflector at {pts[k].tolist()} m is {gap[k]:.3g} m from the emitter "
            f"or a microphone at pose {where}; keep it at least "
            f"{MIN_POINT_DISTANCE_M:g} m away",
            key="points.position_m",
        )
