"""What a moving sensor sees: the compiled fixed point at the moving array centre
(:mod:`acousim.kinematics._seen_kernel`) against the equation it solves (the
trajectory evaluated exactly, a loop written here) and against the array version;
the polynomial kinematics' shortcut past degrees that cannot fit."""

from __future__ import annotations

import numpy as np
import pytest

import processing as P
from acousim.kinematics import seen as seen_module
from acousim.kinematics.seen import seen_moving
from acousim.kinematics.sensor import POLY_FIT_M, TABLE_STEP_S, SensorKinematics, _ruled_out
from acousim.scene import Pose
from acousim.scene.trajectory import Trajectory
from acousim.trace.motion.following import MovingPaths

pytest.importorskip("numba")

C = 343.0


#: the array centre as the uRTIS has it (at the sensor's origin) and moved off it
OFFSETS = [(0.0, 0.0, 0.0), (0.1, 0.05, -0.02)]


def _case(offset=(0.0, 0.0, 0.0)):
    arr = P.preset("urtis_v1")
    pose = Pose([0.5, -0.2, 0.1], yaw_rad=0.3)
    traj = Trajectory.constant(pose, [1.2, 0.4, 0.0], np.deg2rad([0, 0, 90]))
    kin = SensorKinematics(traj, pose, arr, 0.04, TABLE_STEP_S)
    rng = np.random.default_rng(5)
    N = 80
    anchor = np.column_stack([rng.uniform(0.5, 6, N), rng.uniform(-3, 3, N), rng.uniform(-1, 1, N)])
    first = rng.uniform(0.5, 4, N)
    paths = MovingPaths(
        anchor,
        first,
        np.ones(N),
        np.tile([1.0, 0, 0], (N, 1)),
        np.ones(N, int),
        np.tile(np.eye(3), (N, 1, 1)),
        np.zeros(N, int),
        np.zeros((N, 3)),
        first,
    )
    centre = arr.positions_m.mean(axis=0) + offset
    return paths, kin, traj, pose, centre


@pytest.mark.parametrize("offset", OFFSETS)
def test_centre_times_solve_the_equation_on_the_trajectory(offset):
    paths, kin, traj, pose, centre = _case(offset)
    seen = seen_moving(paths, kin, traj, pose, centre, C)
    # t = t_r + |R(t) centre + p(t) - A| / c, the trajectory itself, to the last bit
    t_r = paths.first_leg_m / C
    t = t_r.copy()
    for _ in range(60):
        where = traj.to_world(centre[None], pose.time_s + t)[:, 0]
        new = t_r + np.linalg.norm(where - paths.anchor_m, axis=1) / C
        if np.array_equal(new, t):
            break
        t = new
    # the table's rotations interpolated linearly at 0.5 ms: w^2 h^2 / 8 = 8e-8 rad at
    # 90 deg/s, times |centre| in the centre's position (under 1 nm at the uRTIS's)
    assert np.abs(seen.delay_s - t).max() < 1e-11 + 1e-7 * np.linalg.norm(centre) / C
    u = paths.anchor_m - where
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    R = traj.rotation(pose.time_s + t)
    # the rotation's table interpolated linearly: w^2 h^2 / 8 = 8e-8 at 90 deg/s
    assert np.abs(np.einsum("nji,nj->ni", R, u) - seen.arrival_sensor).max() < 1e-7
    # the apparent positions: the centre plus the arrival times c t / 2, sensor frame,
    # and that point in the world through the pose (written here)
    app = centre + seen.arrival_sensor * (C * seen.delay_s / 2)[:, None]
    assert np.abs(seen.apparent_position_sensor_m - app).max() < 1e-13
    world = np.array([pose.rotation @ a + pose.position_m for a in app])
    assert np.abs(seen.apparent_position_world_m - world).max() < 1e-13


@pytest.mark.parametrize("offset", OFFSETS)
def test_compiled_and_array_versions_agree(monkeypatch, offset):
    paths, kin, traj, pose, centre = _case(offset)
    fast = seen_moving(paths, kin, traj, pose, centre, C)
    monkeypatch.setattr(seen_module, "optional_kernel", lambda module, name=None: None)
    plain = seen_moving(paths, kin, traj, pose, centre, C)
    assert np.abs(fast.delay_s - plain.delay_s).max() < 1e-17
    assert np.abs(fast.arrival_sensor - plain.arrival_sensor).max() < 1e-14
    assert np.abs(fast.apparent_position_world_m - plain.apparent_position_world_m).max() < 1e-13


@pytest.mark.parametrize("seed", range(6))
def test_degrees_skipped_are_those_no_fit_reaches(seed):
    """Whenever numpy's least-squares fit of a degree is within POLY_FIT_M of a table,
    that degree is not ruled out; a table curved beyond a degree is."""
    rng = np.random.default_rng(seed)
    x = np.linspace(-1, 1, 153)
    scale = 10.0 ** -rng.uniform(0, 12, (7, 1))
    coef = rng.normal(0, 1, (7, 12)) * scale
    coef[0] += rng.uniform(-20, 20, 12)  # metres from the origin
    flat = np.polynomial.polynomial.polyval(x, coef).T + rng.normal(0, 1e-12, (153, 12))
    out = _ruled_out(x, flat)
    for degree in range(1, 7):
        fit = np.polynomial.polynomial.polyfit(x, flat, degree)
        if np.max(np.abs(np.polynomial.polynomial.polyval(x, fit).T - flat)) < POLY_FIT_M:
            assert not out[degree - 1]
    bent = np.outer(1e-6 * x**3 + 5.0, np.ones(3))  # 1 um of a cubic: no quadratic fits
    assert list(_ruled_out(x, bent)) == [True, True, False, False, False, False]
