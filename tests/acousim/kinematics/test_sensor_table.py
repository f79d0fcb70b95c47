"""The sensor's tabulated kinematics over a knot of its trajectory, where its turn
rate jumps: no polynomial of degree up to POLY_DEGREE fits the table (found with one
fit, the same as trying every degree: the reference, written here), and the table's
positions are the trajectory's (evaluated directly) within the linear
interpolation's error; within one segment a polynomial fits, as before."""

import numpy as np
import pytest

from acousim.kinematics.sensor import POLY_DEGREE, POLY_FIT_M, SensorKinematics, _none_fits
from acousim.scene import Pose
from acousim.scene.trajectory import Trajectory
from processing import Array

ARRAY = Array("two", np.array([[0.02, 0.0, 0.0], [0.0, 0.03, 0.0]]))
STEP = 2.5e-4


def turning_then_straight() -> Trajectory:
    """Poses 0.1 s apart: turning left at 50 deg/s, then straight on from 0.1 s (the
    turn rate jumps at that knot), driving at about 1 m/s."""
    yaw = np.deg2rad([0.0, 5.0, 5.0, 5.0])
    return Trajectory.through(
        [Pose([0.1 * i, 0.01 * min(i, 1), 0.0], yaw[i], time_s=0.1 * i) for i in range(4)]
    )


def fits_at_some_degree(kin: SensorKinematics) -> bool:
    """The reference: every degree from 1 to POLY_DEGREE tried on the table."""
    table = np.concatenate([kin.emitter_table[:, None], kin.mic_table], axis=1)
    flat = table.reshape(table.shape[0], -1)
    x = (kin.grid - kin.mid) / kin.half
    for degree in range(1, POLY_DEGREE + 1):
        coef = np.polynomial.polynomial.polyfit(x, flat, degree)
        if np.max(np.abs(np.polynomial.polynomial.polyval(x, coef).T - flat)) < POLY_FIT_M:
            return True
    return False


@pytest.mark.parametrize("start_s", [0.06, 0.08, 0.099])
def test_over_a_knot_no_polynomial_fits_and_the_table_is_the_trajectory(start_s):
    tr = turning_then_straight()
    kin = SensorKinematics(tr, tr.pose(start_s), ARRAY, 0.06, STEP)
    assert kin.poly is None and not fits_at_some_degree(kin)
    table = np.concatenate([kin.emitter_table[:, None], kin.mic_table], axis=1)
    x = (kin.grid - kin.mid) / kin.half
    assert _none_fits(x, table.reshape(table.shape[0], -1))
    t = np.linspace(0.0, 0.06, 241)
    exact = tr.to_world(ARRAY.positions_m, start_s + t)  # (T, M, 3)
    got = kin.mics(np.broadcast_to(t, (2, t.size)))  # (M, T, 3)
    # linear interpolation of a turn at 50 deg/s carrying 3 cm: below 1e-9 m
    assert np.max(np.abs(got - exact.transpose(1, 0, 2))) < 1e-8


def test_within_one_segment_a_polynomial_fits():
    tr = turning_then_straight()
    kin = SensorKinematics(tr, tr.pose(0.02), ARRAY, 0.06, STEP)
    assert kin.poly is not None and fits_at_some_degree(kin)
    t = np.linspace(0.0, 0.06, 241)
    exact = tr.to_world(ARRAY.positions_m, 0.02 + t)
    got = kin.mics(np.broadcast_to(t, (2, t.size)))
    assert np.max(np.abs(got - exact.transpose(1, 0, 2))) < 1e-9


@pytest.mark.parametrize("start_s", [0.06, 0.08, 0.099])
def test_over_a_knot_a_polynomial_per_piece_is_the_trajectory(start_s):
    # the window cut at the knot (0.1 s): each piece's polynomial within 1e-10 m of
    # the trajectory evaluated directly, on either side of the knot; its velocity
    # (only Newton's slope: it moves no root) within 1e-5 m/s of the trajectory's
    # central differences, also over a piece of 1 ms
    tr = turning_then_straight()
    kin = SensorKinematics(tr, tr.pose(start_s), ARRAY, 0.06, STEP)
    pieces = kin.pieces
    assert pieces is not None and np.allclose(pieces.bounds, [0.1 - start_s])
    t = np.linspace(0.0, kin.grid[-1], 1001)
    j = np.searchsorted(pieces.bounds, t, side="right")
    x = (t - pieces.mid[j]) / pieces.half[j]
    D = pieces.mic_poly.shape[2] - 1
    got = np.einsum("tk,tmki->tmi", x[:, None] ** np.arange(D + 1), pieces.mic_poly[j])
    exact = tr.to_world(ARRAY.positions_m, start_s + t)
    assert np.max(np.abs(got - exact)) < POLY_FIT_M
    h = 1e-6
    ahead = tr.to_world(ARRAY.positions_m, start_s + t + h)
    behind = tr.to_world(ARRAY.positions_m, start_s + t - h)
    vel = np.einsum("tk,tmki->tmi", x[:, None] ** np.arange(D), pieces.mic_poly_v[j])
    away = np.abs(t - pieces.bounds[0]) > 2 * h
    assert np.max(np.abs(vel - (ahead - behind) / (2 * h))[away]) < 1e-5
    # the turn rate jumps at the knot: the two pieces' velocities there differ
    end = np.einsum("k,mki->mi", np.ones(D), pieces.mic_poly_v[0])  # x = 1
    start = np.einsum("k,mki->mi", (-1.0) ** np.arange(D), pieces.mic_poly_v[1])  # x = -1
    assert np.max(np.abs(end - start)) > 1e-4


def test_rotations_within_and_across_segments_are_scipys_slerp():
    """The trajectory's rotations (one segment's times at once, or several segments')
    against scipy's Slerp through the poses (the reference its docstring names)."""
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(2)
    poses = [Pose(rng.uniform(-1, 1, 3), *rng.uniform(-1, 1, 3), time_s=0.1 * i) for i in range(5)]
    traj = Trajectory.through(poses)
    slerp = Slerp([p.time_s for p in poses], Rotation.from_matrix([p.rotation for p in poses]))
    for t in (0.1 + 0.099 * rng.random(150), 0.4 * rng.random((6, 7)), np.array([0.25])):
        ref = slerp(t.ravel()).as_matrix().reshape(*t.shape, 3, 3)
        assert np.abs(traj.rotation(t) - ref).max() < 1e-12


def test_velocity_polynomial_is_numpys_derivative_of_the_position_one():
    """Within one segment: the velocities' coefficients are numpy's polyder of the
    positions' over the half window, to the bit, and the positions' derivative in
    time (a central difference of the polynomial)."""
    kin = SensorKinematics(turning_then_straight(), Pose([0.0, 0.0, 0.0], 0.0), ARRAY, 0.02, STEP)
    assert kin.poly is not None
    flat = kin.poly.reshape(kin.poly.shape[0], -1)
    want = np.polynomial.polynomial.polyder(flat) / kin.half
    assert kin.poly_v.reshape(want.shape).tobytes() == want.tobytes()
    x, h = 0.3, 1e-6  # normalised time, and a step of it
    pos = np.polynomial.polynomial.polyval([x - h, x + h], flat)
    slope = (pos[:, 1] - pos[:, 0]) / (2 * h * kin.half)  # m/s
    vel = np.polynomial.polynomial.polyval(x, kin.poly_v.reshape(want.shape))
    assert np.allclose(vel, slope, rtol=0, atol=1e-6)
