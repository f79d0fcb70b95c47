"""Moving point reflectors are hidden by the meshes between them and the sensor, at
the emission instant, as still points are (a person walking out from behind a
pillar; a door closing in front of one)."""

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
C = acousim.Environment().speed_of_sound_m_s


def _scene(meshes, points, times):
    sensor = acousim.Sensor(
        array=ONE,
        call=P.Waveform("linear", 40e3, 40e3, 1e-3),
        direct_path=False,
        poses=tuple(Pose([0.0, 0, 0], time_s=t) for t in times),
    )
    sim = acousim.Simulation(max_range_m=5.0, rays=500, absorption=False)
    return acousim.Scene(meshes=meshes, points=points, sensor=sensor, simulation=sim)


def _screen(y=0.0, velocity=(0.0, 0.0, 0.0)):
    """A 1 m wide, 2 m tall, 10 cm thick screen whose middle is at (2, y, 0)."""
    return acousim.MeshItem(
        trimesh.creation.box((0.1, 1.0, 2.0)),
        acousim.Material("screen", reflection=1.0),
        position_m=(2.0, y, 0.0),
        velocity_m_s=velocity,
    )


def _points_heard(sim, pose):
    """Positions (K, 3) at the emission instant of the point echoes of `pose`."""
    _, pos, kinds, _ = sim.moving_paths(pose)
    return pos[np.asarray(kinds) == "point"]


def test_point_walking_out_from_behind_a_screen_is_heard_once_in_view():
    # behind the screen (x = 3) at y = 0 at t = 0, walking along y at 1 m/s: the
    # line of sight to (3, y) crosses the screen's plane x = 1.95 at 0.65 y, so it
    # clears the screen's edge (y = 0.5) from y = 0.77 on
    walker = acousim.PointItem(position_m=(3.0, 0.0, 0.0), velocity_m_s=(0.0, 1.0, 0.0))
    still = acousim.PointItem(position_m=(1.0, 0.3, 0.0), velocity_m_s=(0.0, 1e-3, 0.0))
    times = (0.0, 0.5, 1.0, 1.5)
    sim = Simulator(_scene([_screen()], [walker, still], times))
    heard = [_points_heard(sim, p) for p in sim.scene.sensor.poses]
    walking = [h[np.abs(h[:, 0] - 3.0) < 1e-9] for h in heard]
    assert [len(w) for w in walking] == [0, 0, 1, 1]
    for t, w in zip(times[2:], walking[2:]):
        assert w[0] == pytest.approx([3.0, t, 0.0])  # where it is at the emission
    # the point in front of the screen is heard at every pose
    assert all(np.sum(np.abs(h[:, 0] - 1.0) < 1e-9) == 1 for h in heard)


def test_screen_sliding_in_front_of_a_point_hides_it_while_in_front():
    # a screen moving along y at 1 m/s from y = -2: in front of the point at (3, 0)
    # (whose line of sight crosses x = 1.95 at y = 0) from t = 1.5 to 2.5
    point = acousim.PointItem(position_m=(3.0, 0.0, 0.0), velocity_m_s=(1e-3, 0.0, 0.0))
    times = (0.0, 2.0, 3.5)
    sim = Simulator(_scene([_screen(-2.0, (0.0, 1.0, 0.0))], [point], times))
    heard = [len(_points_heard(sim, p)) for p in sim.scene.sensor.poses]
    assert heard == [1, 0, 1]


def test_moving_point_echo_delay_when_in_view():
    # in view: the echo of a point closing at v arrives at 2 r / (c + v) (the
    # retarded-time solution for a monostatic sensor and a point moving straight in)
    r, v = 3.0, 1.0
    point = acousim.PointItem(position_m=(r, 0.0, 0.0), velocity_m_s=(-v, 0.0, 0.0))
    sim = Simulator(_scene([_screen(-2.0)], [point], (0.0,)))
    pose = sim.scene.sensor.poses[0]
    moving, _, kinds, _ = sim.moving_paths(pose)
    kin = SensorKinematics(None, pose, ONE, 0.04, 2.5e-4)
    a = arrivals(moving, kin, 1e-3, sim.c, pose.rotation[:, 0])
    assert list(kinds).count("point") == 1
    delay = a.echoes.delay_s[0, list(kinds).index("point")]
    assert delay == pytest.approx(2 * r / (sim.c + v), abs=1e-9)


def test_truth_names_the_moving_point_heard_not_the_hidden_one():
    # two moving points: "point 0" behind the screen (hidden), "point 1" in view at
    # 1.2 m; the recording's truth holds one point path, named "point 1", whose last
    # point is where that point is at the emission, and every field has its row
    hidden = acousim.PointItem(position_m=(3.0, 0.0, 0.0), velocity_m_s=(0.0, 1e-3, 0.0))
    seen = acousim.PointItem(position_m=(1.2, -0.8, 0.0), velocity_m_s=(0.0, 0.0, 1e-3))
    sim = Simulator(_scene([_screen()], [hidden, seen], (0.0,)))
    rec = sim.simulate_pose(sim.scene.sensor.poses[0])
    t = rec.truth
    point = np.flatnonzero(t.kind == "point")
    assert len(point) == 1
    assert len(t.object_index) == len(t.position_world_m) == len(t.last_point_m)
    assert t.object_names[t.object_index[point[0]]] == "point 1"
    assert t.last_point_m[point[0]] == pytest.approx([1.2, -0.8, 0.0])
    # its delay at the array centre: out and back over the distance to the point
    assert t.delay_s[point[0]] == pytest.approx(2 * np.hypot(1.2, 0.8) / C, abs=2e-9)
