"""A moving mesh met before the last reflection: third-order paths between two
parallel walls, one of them moving, against the exact one-dimensional solution
(each reflection solved at its own instant, written here)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import acousim
import processing as P
from acousim.kinematics import SensorKinematics, arrivals
from acousim.scene import Pose
from acousim.simulator import Simulator

pytest.importorskip("embreex")

ONE = P.Array("one", np.zeros((1, 3)))  # a microphone on the emitter: monostatic
CALL = P.Waveform("linear", 40e3, 40e3, 2e-3)
A, B = 1.0, 1.5  # m: the right wall's front face at x = A, the left one's at x = -B


def _wall(x_front, facing, velocity=(0.0, 0.0, 0.0)):
    """A 20 m x 20 m wall, 0.2 m thick, its front face at x = x_front facing
    `facing` (+1: +x)."""
    return acousim.MeshItem(
        trimesh.creation.box((0.2, 20, 20)),
        acousim.Material("wall", reflection=1.0),
        position_m=(x_front - 0.1 * facing, 0, 0),
        velocity_m_s=velocity,
    )


def _exact(tau, w_right, w_left, c):
    """Reception time of the sample emitted at `tau` along S -> right -> left ->
    right -> S (on the x axis), the walls' faces at x = A + w_right t and
    x = -B + w_left t: every leg solved at the instant the sound reaches its wall
    (a linear equation each)."""
    t1 = (tau + A / c) / (1 - w_right / c)  # t1 = tau + (A + w_r t1) / c
    # t2 = t1 + (A + w_r t1 + B - w_l t2) / c
    t2 = (t1 + (A + w_right * t1 + B) / c) / (1 + w_left / c)
    # t3 = t2 + (A + w_r t3 + B - w_l t2) / c
    t3 = (t2 + (A + B - w_left * t2) / c) / (1 - w_right / c)
    return t3 + (A + w_right * t3) / c


@pytest.mark.parametrize("w_right, w_left", [(0.0, 1.0), (0.0, -1.5), (1.0, 0.0), (-0.8, 1.2)])
def test_third_order_between_walls_moving(w_right, w_left):
    """The path right -> left -> right: a moving left wall is met in the middle, a
    moving right wall first and last."""
    sensor = acousim.Sensor(array=ONE, call=CALL, direct_path=False, poses=(Pose([0.0, 0, 0]),))
    scene = acousim.Scene(
        meshes=[_wall(A, -1, (w_right, 0, 0)), _wall(-B, +1, (w_left, 0, 0))],
        sensor=sensor,
        simulation=acousim.Simulation(max_range_m=6.0, rays=4000, bounces=3, absorption=False),
    )
    sim = Simulator(scene)
    pose = sensor.poses[0]
    moving, _, kinds, _ = sim.moving_paths(pose)
    kin = SensorKinematics(None, pose, ONE, 0.05, 2.5e-4)
    arr = arrivals(moving, kin, CALL.duration_s, sim.c, pose.rotation[:, 0])
    c = sim.c
    pick = (
        (np.asarray(kinds) == "specular") & (moving.order == 3) & (moving.departure[:, 0] > 0.999)
    )
    assert pick.sum() == 1
    t0, t1 = _exact(0.0, w_right, w_left, c), _exact(CALL.duration_s, w_right, w_left, c)
    assert arr.echoes.delay_s[0, pick][0] == pytest.approx(t0, abs=1e-9)
    assert arr.rate[0, pick][0] == pytest.approx(CALL.duration_s / (t1 - t0), abs=1e-7)
    # walls frozen where they are at the emission would be off by microseconds
    assert abs(2 * (A + A + B) / c - t0) > 5e-6
