"""A mesh on a track that also gives its orientation (another robot turning as it
drives by): rows [t, x, y, z, roll, pitch, yaw].

Independent references: the exact monostatic echo of a wall turning about an axis in
its own face (the sample emitted at tau meets the wall at t1 = tau + D(t1) / c, D the
distance to the wall's plane at t1, and returns at t1 + D(t1) / c, solved here by
iteration), as in tests/test_moving_mesh_turning.py, now with the turn given by the
track's rows instead of a rate; the velocity of a point of a turning body
``w x (x - o)``."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import acousim
import processing as P
from acousim.scene import Pose, parse_scene
from acousim.simulator import Simulator
from acousim.synth.moving import SensorKinematics, arrivals
from processing.errors import InputError

pytest.importorskip("embreex")

ONE = P.Array("one", np.zeros((1, 3)))  # a microphone on the emitter: monostatic
CALL = P.Waveform("linear", 40e3, 40e3, 2e-3)
D, W = 2.0, np.deg2rad(90.0)  # the wall 2 m ahead, turning at 90 deg/s about z


def _wall_box():
    box = trimesh.creation.box((0.2, 20, 20))
    box.apply_translation((0.1, 0, 0))  # the face at the mesh's origin
    return box


def _track(times):
    """The wall standing at (D, 0, 0), its yaw W t (rad)."""
    return [[t, D, 0.0, 0.0, 0.0, 0.0, W * t] for t in times]


def _arrivals(mesh, t0):
    sensor = acousim.Sensor(
        array=ONE, call=CALL, direct_path=False, poses=(Pose([0.0, 0, 0], time_s=t0),)
    )
    sim_settings = acousim.Simulation(max_range_m=4.0, rays=4000, absorption=False, beam_deg=80.0)
    sim = Simulator(acousim.Scene(meshes=[mesh], sensor=sensor, simulation=sim_settings))
    pose = sensor.poses[0]
    moving, pos, kinds, vel = sim.moving_paths(pose)
    kin = SensorKinematics(None, pose, ONE, 0.03, 2.5e-4)
    a = arrivals(moving, kin, CALL.duration_s, sim.c, pose.rotation[:, 0])
    return a, np.asarray(kinds), pos, vel, sim.c


@pytest.mark.parametrize("t0", [0.2, 0.55])
def test_wall_turned_by_its_track_against_the_exact_echo(t0):
    """Rows every 0.25 s with the yaw W t: the first, middle and last sample of the
    echo within 1 ns of the exact reception times, and the reflection point moving
    as a point of the turning wall."""
    wall = acousim.MeshItem(
        _wall_box(), acousim.Material("w", 1.0), track=_track(np.arange(0.0, 1.01, 0.25))
    )
    assert wall.turning
    a, kinds, pos, vel, c = _arrivals(wall, t0)
    spec = np.flatnonzero(kinds == "specular")
    first = spec[np.argmin(a.echoes.delay_s[0, spec])]

    def exact(tau):
        t1 = tau
        for _ in range(50):
            t1 = tau + D * np.cos(W * (t0 + t1)) / c
        return t1 + D * np.cos(W * (t0 + t1)) / c

    T = CALL.duration_s
    t_first = a.echoes.delay_s[0, first] - a.curvature_s[0, first] * (2 / 3)
    t_last = t_first + T / a.rate[0, first]
    t_mid = 0.5 * (t_first + t_last) + a.curvature_s[0, first]
    for ours, tau in ((t_first, 0.0), (t_mid, T / 2), (t_last, T)):
        assert ours == pytest.approx(exact(tau), abs=1e-9)
    x = pos[first]
    assert vel[first] == pytest.approx(np.cross([0, 0, W], x - [D, 0, 0]), abs=1e-9)


def test_track_turns_in_a_scene_file_are_degrees(tmp_path):
    """The file's roll, pitch, yaw are degrees (as rotation_deg); bad rows are named."""
    trimesh.creation.box((0.2, 2, 2)).export(tmp_path / "box.stl")
    rows = [[0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 2.0, 1.0, 0.0, 10.0, 0.0, 90.0]]
    base = {"sensor": {"array": "urtis_v1"}, "meshes": [{"file": "box.stl", "track": rows}]}
    mesh = parse_scene(base, base_dir=tmp_path).meshes[0]
    assert mesh.turning
    # half way: yaw 45 deg about z after a roll of 5 deg about x (a smooth rotation
    # spline between two rows is the constant-rate turn between them)
    half = mesh.rotation_at(0.5)
    turn = np.deg2rad([10.0, 0.0, 90.0])
    from scipy.spatial.transform import Rotation

    end = Rotation.from_euler("ZYX", turn[::-1])
    expected = Rotation.from_rotvec(end.as_rotvec() / 2).as_matrix()
    assert half == pytest.approx(expected, abs=1e-9)
    assert mesh.angular_velocity_at(0.5) == pytest.approx(end.as_rotvec(), abs=1e-9)
    assert mesh.at(0.5)[0] == pytest.approx([2.0, 0.5, 0.0], abs=1e-9)

    def refused(mesh_table, match):
        bad = {**base, "meshes": [{"file": "box.stl", **mesh_table}]}
        with pytest.raises(InputError, match=match):
            parse_scene(bad, base_dir=tmp_path)

    fast = [[0.0, 2, 0, 0, 0, 0, 0], [0.01, 2, 0, 0, 0, 0, 90]]  # 9000 deg/s
    refused({"track": fast}, r"meshes\[0\]\.track.*turns faster")
    refused({"track": [r[:6] for r in rows]}, r"meshes\[0\]\.track.*roll, pitch, yaw")
    refused({"track": rows, "angular_rate_deg_s": [0, 0, 30]}, r"angular_rate_deg_s")
    point = {"sensor": {"array": "urtis_v1"}, "points": [{"track": rows}]}
    with pytest.raises(InputError, match=r"points\[0\]\.track"):
        parse_scene(point)
