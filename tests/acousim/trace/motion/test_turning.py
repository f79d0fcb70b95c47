"""Meshes that turn (another robot turning as it passes): a wall turning about an
axis in its own face, against the exact monostatic solution (the echo leaves and
returns along the normal of the wall where it is at the reflection instant); a
sphere spinning about its centre, whose echo must not change at all."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import acousim
import processing as P
from acousim.kinematics import SensorKinematics, arrivals
from acousim.scene import Pose, parse_scene
from acousim.simulator import Simulator
from processing.base.errors import InputError

pytest.importorskip("embreex")

ONE = P.Array("one", np.zeros((1, 3)))  # a microphone on the emitter: monostatic
CALL = P.Waveform("linear", 40e3, 40e3, 2e-3)


def _arrivals(meshes, t0):
    sensor = acousim.Sensor(
        array=ONE, call=CALL, direct_path=False, poses=(Pose([0.0, 0, 0], time_s=t0),)
    )
    sim_settings = acousim.Simulation(max_range_m=4.0, rays=4000, absorption=False, beam_deg=80.0)
    sim = Simulator(acousim.Scene(meshes=meshes, sensor=sensor, simulation=sim_settings))
    pose = sensor.poses[0]
    moving, pos, kinds, vel = sim.moving_paths(pose)
    kin = SensorKinematics(None, pose, ONE, 0.03, 2.5e-4)
    a = arrivals(moving, kin, CALL.duration_s, sim.c, pose.rotation[:, 0])
    return a, np.asarray(kinds), pos, vel, sim.c


@pytest.mark.parametrize("t0", [0.2, 0.5])
def test_wall_turning_about_an_axis_in_its_face(t0):
    """A wall whose face holds a vertical axis 2 m ahead, turning at 90 deg/s."""
    d, w = 2.0, np.deg2rad(90.0)
    wall = acousim.MeshItem(
        wall_box(),
        acousim.Material("w", 1.0),
        position_m=(d, 0, 0),
        angular_velocity_rad_s=(0, 0, w),
    )
    check_turning_wall(wall, t0, d, w)


def wall_box():
    """A 20 m square wall 0.2 m thick, its front face at the mesh's origin."""
    box = trimesh.creation.box((0.2, 20, 20))
    box.apply_translation((0.1, 0, 0))
    return box


def check_turning_wall(wall, t0, d, w):
    """`wall` (its face the plane through (d, 0, 0) with normal (cos wt, sin wt, 0) at
    time t, d cos(wt) from the sensor) against the exact monostatic echo: the sample
    emitted at tau meets it at t1 = tau + D(t1) / c and returns at t1 + D(t1) / c
    (solved here by iteration): the first, middle and last sample within 1 ns, the
    Doppler factor of the turn, the reflection point moving as a point of the wall."""
    a, kinds, pos, vel, c = _arrivals([wall], t0)
    spec = np.flatnonzero(kinds == "specular")
    first = spec[np.argmin(a.echoes.delay_s[0, spec])]

    def exact(tau):
        t1 = tau
        for _ in range(50):
            t1 = tau + d * np.cos(w * (t0 + t1)) / c
        return t1 + d * np.cos(w * (t0 + t1)) / c

    T = CALL.duration_s
    # the renderer's law: the first and last sample's reception times, and the
    # middle one's deviation from the line between (the wall's turn curves it)
    t_first = a.echoes.delay_s[0, first] - a.curvature_s[0, first] * (2 / 3)
    t_last = t_first + T / a.rate[0, first]
    t_mid = 0.5 * (t_first + t_last) + a.curvature_s[0, first]
    for ours, tau in ((t_first, 0.0), (t_mid, T / 2), (t_last, T)):
        assert ours == pytest.approx(exact(tau), abs=1e-9)
    # the turn makes a Doppler factor of (c + v) / (c - v) with v = d w sin(w t)
    v = d * w * np.sin(w * t0)
    assert abs(a.rate[0, first] - 1) > 0.5 * 2 * v / c
    # the ground truth: the reflection point moves as a point of the turning wall
    x = pos[first]
    assert vel[first] == pytest.approx(np.cross([0, 0, w], x - [d, 0, 0]), abs=1e-9)


def test_spinning_sphere_echoes_as_a_still_one():
    """A sphere spinning about its centre (fast: 600 deg/s about a tilted axis): its
    surface slides on itself, so its echo is the still sphere's (the same mesh turned
    as it is at the emission, not turning: the delay within 1 ns, no Doppler)."""
    r, radius = 2.0, 0.3
    axis = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    ball = trimesh.creation.icosphere(5, radius=radius)
    spinning = acousim.MeshItem(
        ball,
        acousim.Material("b", 1.0),
        position_m=(r, 0, 0),
        angular_velocity_rad_s=tuple(np.deg2rad(600.0) * axis),
    )
    still = spinning.placed_at(0.3)  # the same facets where they are then, still
    spun, _, _, _, _ = _arrivals([spinning], 0.3)
    ref, _, _, _, _ = _arrivals([still, _far_wall()], 0.3)  # a mover: the same solver
    glint = np.argmin(spun.echoes.delay_s[0])
    assert spun.echoes.delay_s[0, glint] == pytest.approx(ref.echoes.delay_s[0].min(), abs=1e-9)
    assert spun.rate[0, glint] == pytest.approx(1.0, abs=1e-9)


def _far_wall():
    """A small wall out of reach moving slowly: makes the scene a moving one."""
    return acousim.MeshItem(
        trimesh.creation.box((0.1, 0.1, 0.1)), position_m=(-50.0, 0, 0), velocity_m_s=(0, 0, 1e-3)
    )


def test_turning_mesh_key_in_a_scene_file(tmp_path):
    trimesh.creation.box((0.2, 2, 2)).export(tmp_path / "box.stl")
    base = {
        "sensor": {"array": "urtis_v1"},
        "meshes": [
            {"file": "box.stl", "position_m": [2.0, 0, 0], "angular_rate_deg_s": [0, 0, 90]}
        ],
    }
    sc = parse_scene(base, base_dir=tmp_path)
    assert sc.meshes[0].angular_velocity_rad_s == pytest.approx((0, 0, np.pi / 2))
    assert sc.meshes[0].moving and sc.meshes[0].turning
    bad = {**base, "meshes": [{**base["meshes"][0], "angular_rate_deg_s": [0, 0, 1e5]}]}
    with pytest.raises(InputError, match=r"meshes\[0\]\.angular_rate_deg_s"):
        parse_scene(bad, base_dir=tmp_path)
