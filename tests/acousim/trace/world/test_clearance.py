"""A sensor whose emitter or a microphone stands nearer than the clearance to a mesh
surface is refused, naming the scene file, the pose, the point and its distance
(computed here from the geometry); a sensor just beyond it is traced."""

import re

import numpy as np
import pytest
import trimesh

from acousim.scene.load import load_scene
from acousim.simulator import Simulator
from acousim.trace.world.clearance import SENSOR_CLEARANCE_M, nearest_surface
from processing.base.errors import InputError

WALL_X = 2.0  # the wall's front face (m)


def _scene(tmp_path, position, yaw_deg=0.0, rotation_deg=(0, 0, 0)):
    """A scene file: a 10 cm thick, 4 x 4 m wall whose front face is the plane x = 2 m
    (turned about the point (2, 0, 0) by `rotation_deg`, about x, y, z) and the uRTIS
    at `position` (m)."""
    wall = trimesh.creation.box((0.1, 4.0, 4.0))
    wall.apply_translation([0.05, 0, 0])  # its front face through the origin
    wall.apply_transform(trimesh.transformations.euler_matrix(*np.deg2rad(rotation_deg), "sxyz"))
    wall.apply_translation([WALL_X, 0, 0])
    wall.export(tmp_path / "wall.stl")
    pos = ", ".join(repr(float(v)) for v in position)
    (tmp_path / "near.toml").write_text(
        f'[sensor]\narray = "urtis_v1"\ndirect_path = false\n'
        f"[sensor.pose]\nposition_m = [{pos}]\nyaw_deg = {yaw_deg}\n"
        f"[simulation]\nmax_range_m = 3.0\nbounces = 1\n"
        f'[[meshes]]\nfile = "wall.stl"\n'
    )
    return load_scene(tmp_path / "near.toml")


def _refusal(scene) -> str:
    with pytest.raises(InputError) as info:
        Simulator(scene).simulate_pose(scene.sensor.poses[0], 0)
    return str(info.value)


def _distance(message: str) -> float:
    return float(re.search(r"is ([0-9.e+-]+) m from a mesh surface", message).group(1))


@pytest.mark.parametrize("gap", [0.0, 0.001, 0.005, 0.0099])
def test_an_emitter_facing_a_wall_nearer_than_the_clearance_is_refused(tmp_path, gap):
    scene = _scene(tmp_path, (WALL_X - gap, 0.0, 0.0))
    msg = _refusal(scene)
    assert msg.startswith(f"{tmp_path / 'near.toml'}: pose 0: ")
    assert "the emitter at [" in msg and "material default" in msg
    assert f"at least {SENSOR_CLEARANCE_M:g} m" in msg
    assert _distance(msg) == pytest.approx(gap, abs=2e-5)  # float32 geometry


def test_a_microphone_nearer_than_the_clearance_is_named(tmp_path):
    """Turned 90 degrees left, the array's y axis points at -x: its microphones at
    sensor y = -9.6 mm stand 9.6 mm nearer the wall than the emitter, 5 mm behind it."""
    scene = _scene(tmp_path, (WALL_X - 0.005 - 0.009625, 1.0, 0.0), yaw_deg=90.0)
    mics_x = scene.sensor.poses[0].to_world(scene.sensor.array.positions_m)[:, 0]
    msg = _refusal(scene)
    k = int(re.search(r"microphone (\d+) at", msg).group(1))
    assert mics_x[k] == pytest.approx(mics_x.max())
    assert _distance(msg) == pytest.approx(WALL_X - mics_x.max(), abs=2e-5)
    assert _distance(msg) == pytest.approx(0.005, abs=2e-5)


def test_a_sensor_just_beyond_the_clearance_is_traced(tmp_path):
    gap = 0.0101
    scene = _scene(tmp_path, (WALL_X - gap, 0.0, 0.0))
    paths = Simulator(scene).paths(scene.sensor.poses[0])
    # the wall's echo: the image source of the emitter, mirrored in the plane x = 2 m
    first = paths.anchor_m[paths.order == 1]
    assert np.abs(first - [WALL_X + gap, 0.0, 0.0]).sum(axis=1).min() < 1e-6


@pytest.mark.parametrize("seed", range(4))
def test_an_oblique_wall_is_found_whatever_its_orientation(tmp_path, seed):
    """A wall turned anyhow, points at random places before it: every point nearer
    than the clearance to its plane is found, at its distance from the plane (not
    along a ray); the farther ones are not."""
    rng = np.random.default_rng(seed)
    rot = rng.uniform(-60, 60, 3)
    scene = _scene(tmp_path, (0.0, 0.0, 0.0), rotation_deg=rot)
    tracer = Simulator(scene).tracer
    R = trimesh.transformations.euler_matrix(*np.deg2rad(rot), "sxyz")[:3, :3]
    normal = R @ [-1.0, 0, 0]  # the front face's outward normal
    across = R @ np.c_[np.zeros(50), rng.uniform(-1, 1, (50, 2))].T  # on the face
    gaps = np.r_[rng.uniform(0, 0.0099, 25), rng.uniform(0.0101, 0.02, 25)]
    points = np.array([WALL_X, 0.0, 0.0]) + across.T + gaps[:, None] * normal
    found, _ = nearest_surface(tracer.caster, tracer.world, points, SENSOR_CLEARANCE_M)
    near = gaps < SENSOR_CLEARANCE_M
    np.testing.assert_allclose(found[near], gaps[near], atol=5e-5)  # float32 geometry
    assert np.all(found[~near] >= SENSOR_CLEARANCE_M)
