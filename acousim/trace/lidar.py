"""A LiDAR scan of the scene: the beams of :class:`acousim.scene.lidar.Lidar` cast
with Embree (:class:`acousim.trace.world.embree.RayCaster`), each hit's distance then made
exact in float64 on the face Embree found (the plane ``n . x = offset`` of
:class:`acousim.trace.world.build.World`), as the tracer does for its paths.

The scan starts at the pose (the start of the sonar's emission). A sensor that moves
(its :class:`~acousim.scene.trajectory.Trajectory`) fires every azimuth from where it
is at that azimuth's firing time, and each point is reported in the LiDAR frame of
that instant, as a real spinning unit reports it (uncorrected for the motion).
Moving meshes are scanned where they are at the start of the scan. Explicit point
reflectors have no surface: a LiDAR does not see them.
"""

from __future__ import annotations

import numpy as np

from acousim.scene.lidar import Lidar
from acousim.scene.pose import Pose
from acousim.trace.world.build import World
from acousim.trace.world.embree import RayCaster
from processing import PointCloud

__all__ = ["scan", "beam_directions"]


def beam_directions(lidar: Lidar) -> np.ndarray:
    """Unit beam directions in the LiDAR frame, shape (A, C, 3): azimuths in firing
    order, channels lowest first."""
    az, el = lidar.azimuths_rad()[:, None], lidar.elevations_rad()[None, :]
    return np.stack(
        np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), -1
    )


def scan(
    world: World | None,
    caster: RayCaster | None,
    lidar: Lidar,
    pose: Pose,
    *,
    motion=None,
    seed: int = 0,
) -> PointCloud:
    """One scan starting at `pose` (`motion`: the sensor's trajectory, None: still).

    Points (P, 3) in the LiDAR frame, ordered by firing (azimuth, then channel);
    intensity the cosine of the angle of incidence (a Lambertian surface; 0..1);
    `range_noise_m` adds Gaussian noise of that standard deviation to each range
    (seeded by `seed`: the same seed gives the same points).
    """
    mount = lidar.to_sensor()
    d_lidar = beam_directions(lidar)  # (A, C, 3)
    A, C = d_lidar.shape[:2]
    times = lidar.firing_times_s()  # (A,)
    if motion is None:
        R = np.broadcast_to(pose.rotation, (A, 3, 3))
        p = np.broadcast_to(pose.position_m, (A, 3))
    else:
        R = motion.rotation(pose.time_s + times)
        p = motion.position(pose.time_s + times)
    R_l = R @ mount[:3, :3]  # LiDAR -> world, per azimuth
    origin = p + R @ mount[:3, 3]  # (A, 3)
    d_world = np.einsum("aij,acj->aci", R_l, d_lidar).reshape(-1, 3)
    o_world = np.repeat(origin, C, axis=0)
    ring = np.tile(np.arange(C), A)
    when = np.repeat(times, C)
    empty = PointCloud(np.zeros((0, 3)), np.zeros(0), mount, np.zeros(0, int), np.zeros(0),
                       lidar.name, lidar.rate_hz)  # fmt: skip
    if world is None or caster is None:  # a scene of point reflectors only
        return empty
    lo, hi = lidar.range_m
    _, face = caster.first_hit(o_world, d_world, hi * (1 + 1e-6) + caster.tolerance_m)
    hit = face >= 0
    f = face[hit]
    n = world.normals[f]
    cos = np.einsum("ij,ij->i", n, d_world[hit])
    ok = np.abs(cos) > 1e-12
    t = np.full(hit.sum(), np.inf)
    t[ok] = (world.offsets[f][ok] - np.einsum("ij,ij->i", n[ok], o_world[hit][ok])) / cos[ok]
    if lidar.range_noise_m > 0:
        t = t + np.random.default_rng(seed).normal(0.0, lidar.range_noise_m, t.shape)
    keep = (t >= lo) & (t <= hi)
    idx = np.flatnonzero(hit)[keep]
    if not idx.size:
        return empty
    points = d_lidar.reshape(-1, 3)[idx] * t[keep][:, None]
    return PointCloud(points, np.abs(cos[keep]), mount, ring[idx], when[idx], lidar.name,
                      lidar.rate_hz)  # fmt: skip
