"""The simulated LiDAR (acousim.trace.lidar) against ranges computed here: ray-plane
intersections with the bundled wall (the plane x = 2 m, |y|, |z| <= 5 m) and the
shoebox room (the box [-1, 3.2] x [-1.6, 1.9] x [-1.1, 1.5] m, seen from inside)."""

import dataclasses

import numpy as np
import pytest

import processing as P
from acousim.bundled import resolve
from acousim.scene import load_scene
from acousim.scene.lidar import LIDAR_PRESETS, Lidar, lidar_preset
from acousim.scene.load import parse_scene
from acousim.scene.trajectory import Trajectory
from acousim.simulator import Simulator
from processing.base.errors import InputError
from tests.oracles.analytic import rotation_zyx


def _beams(lidar: Lidar):
    """Every beam (azimuth, elevation) in firing order, from the data sheet numbers."""
    lo, hi = lidar.azimuth_deg
    n = int(round((hi - lo) / lidar.azimuth_step_deg))
    az = np.deg2rad(hi - lidar.azimuth_step_deg * np.arange(n))  # a full turn: n columns
    el = np.deg2rad(np.linspace(*lidar.elevation_deg, lidar.channels))
    A, E = np.meshgrid(az, el, indexing="ij")
    return np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1)


def _with_lidar(name: str, lidar: Lidar, motion=None):
    scene = load_scene(resolve("scenes", name))
    sensor = dataclasses.replace(scene.sensor, lidar=lidar, motion=motion)
    return dataclasses.replace(scene, sensor=sensor)


def _beam_of(pc: P.PointCloud, lidar: Lidar):
    """(azimuth index, channel) of each point, from its firing time and ring."""
    col = np.rint(pc.time_s * lidar.rate_hz * 360 / lidar.azimuth_step_deg).astype(int)
    return col, pc.ring


def test_presets():
    vlp, hdl = LIDAR_PRESETS["vlp16"], LIDAR_PRESETS["hdl32e"]
    assert np.allclose(np.diff(np.rad2deg(vlp.elevations_rad())), 2.0)
    np.testing.assert_allclose(np.rad2deg(vlp.elevations_rad()[[0, -1]]), [-15.0, 15.0])
    assert hdl.channels == 32 and np.allclose(np.diff(np.rad2deg(hdl.elevations_rad())), 41.34 / 31)
    assert len(vlp.azimuths_rad()) == 1800  # 0.2 degrees, a full turn, no column twice
    assert vlp.firing_times_s()[-1] == pytest.approx(0.1 * 1799 / 1800)


def test_wall_ranges():
    """VLP-16 mounted off-centre and tilted, on the sensor turned 15 degrees."""
    lidar = lidar_preset("vlp16", position_m=(0.03, -0.05, 0.08), rotation_deg=(2.0, 5.0, -10.0))
    scene = _with_lidar("wall", lidar)
    pose = scene.sensor.poses[0]
    pc = Simulator(scene).lidar_scan(pose)
    R = rotation_zyx(pose.yaw_rad) @ rotation_zyx(*np.deg2rad([-10.0, 5.0, 2.0]))
    o = pose.position_m + rotation_zyx(pose.yaw_rad) @ np.array([0.03, -0.05, 0.08])
    d = _beams(lidar) @ R.T  # (A, C, 3) world
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (2.0 - o[0]) / d[..., 0]
    at = o + t[..., None] * d
    inside = (d[..., 0] > 0) & (np.abs(at[..., 1]) < 5) & (np.abs(at[..., 2]) < 5)
    edge = inside & (np.maximum(np.abs(at[..., 1]), np.abs(at[..., 2])) > 5 - 1e-3)
    col, ring = _beam_of(pc, lidar)
    assert inside[col, ring].all()
    assert inside.sum() - edge.sum() <= len(pc) <= inside.sum()
    assert len(pc) > 5000
    err = np.abs(pc.range_m() - t[col, ring])
    assert err.max() < 1e-3
    # the points are where the beams say, in the LiDAR frame; in the world on the wall
    world = pc.in_sensor() @ pose.rotation.T + pose.position_m
    assert np.abs(world[:, 0] - 2.0).max() < 1e-3
    cos = np.abs(d[col, ring, 0])  # the wall's normal is -x
    np.testing.assert_allclose(pc.intensity, cos, atol=1e-9)


def test_shoebox_ranges():
    """HDL-32E inside the room: every beam returns, at the nearest wall."""
    lidar = LIDAR_PRESETS["hdl32e"]
    scene = _with_lidar("shoebox", lidar)
    pose = scene.sensor.poses[0]
    pc = Simulator(scene).lidar_scan(pose)
    d = _beams(lidar)
    assert len(pc) == d.shape[0] * d.shape[1]
    lo, hi = np.array([-1.0, -1.6, -1.1]), np.array([3.2, 1.9, 1.5])
    with np.errstate(divide="ignore"):
        t = np.where(d > 0, hi / d, lo / d)  # the sensor is at the origin
    t = np.where(np.isfinite(t) & (t > 0), t, np.inf).min(axis=-1)
    col, ring = _beam_of(pc, lidar)
    assert np.abs(pc.range_m() - t[col, ring]).max() < 1e-3


def test_moving_sensor_scans_from_where_it_is():
    """Driving at 2 m/s towards the wall: each azimuth fires from its own position."""
    lidar = lidar_preset("vlp16", azimuth_deg=(-60.0, 60.0), rate_hz=5.0)
    scene = load_scene(resolve("scenes", "wall"))
    pose = scene.sensor.poses[0]
    motion = Trajectory.constant(pose, (2.0, 0.0, 0.0))
    scene = _with_lidar("wall", lidar, motion)
    pc = Simulator(scene).lidar_scan(pose, motion=motion)
    x0 = 2.0 * pc.time_s  # sensor's x at each point's firing time
    d = pc.points_m / pc.range_m()[:, None] @ rotation_zyx(pose.yaw_rad).T
    np.testing.assert_allclose(pc.range_m(), (2.0 - x0) / d[:, 0], atol=1e-3)
    assert pc.time_s.max() > 0.06  # a third of a turn at 5 Hz


def test_range_noise_is_seeded():
    lidar = lidar_preset("vlp16", range_noise_m=0.03)
    scene = _with_lidar("shoebox", lidar)
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    a, b, c = sim.lidar_scan(pose, 0), sim.lidar_scan(pose, 0), sim.lidar_scan(pose, 1)
    np.testing.assert_array_equal(a.points_m, b.points_m)
    exact = Simulator(_with_lidar("shoebox", LIDAR_PRESETS["vlp16"])).lidar_scan(pose)
    diff = a.range_m() - exact.range_m()
    assert abs(diff.std() - 0.03) < 0.002 and abs(diff.mean()) < 0.002
    assert not np.array_equal(a.points_m, c.points_m)


def test_scene_file_table(tmp_path):
    base = {
        "sensor": {"lidar": {"preset": "hdl32e", "range_m": [0.5, 30.0]}},
        "meshes": [{"file": str(resolve("scenes", "wall").parent / "meshes" / "wall.stl")}],
    }
    scene = parse_scene(base)
    assert scene.sensor.lidar == dataclasses.replace(LIDAR_PRESETS["hdl32e"], range_m=(0.5, 30.0))
    base["sensor"]["lidar"] = {"preset": "vlp32"}
    with pytest.raises(InputError, match="sensor.lidar.preset"):
        parse_scene(base)
    base["sensor"]["lidar"] = {"channel": 8}
    with pytest.raises(InputError, match="did you mean 'channels'"):
        parse_scene(base)
    base["sensor"]["lidar"] = {"channels": 0}
    with pytest.raises(InputError, match="sensor.lidar.channels"):
        parse_scene(base)
    assert parse_scene({**base, "sensor": {}}).sensor.lidar is None


def test_recordings_carry_the_scan(tmp_path):
    scene = _with_lidar("wall", LIDAR_PRESETS["vlp16"])
    rec = Simulator(scene).run()[0]
    assert rec.lidar is not None and len(rec.lidar) > 5000
    P.save_recording(tmp_path / "r.h5", rec)
    back = P.load_recording(tmp_path / "r.h5")
    np.testing.assert_allclose(back.lidar.points_m, rec.lidar.points_m, atol=1e-6)  # float32
    np.testing.assert_array_equal(back.lidar.ring, rec.lidar.ring)
    assert back.lidar.name == "VLP-16" and back.lidar.rate_hz == 10.0
    P.write_chirp(tmp_path / "c.h5", [back])
    again = P.load_recording(tmp_path / "c.h5")
    np.testing.assert_array_equal(again.lidar.points_m, back.lidar.points_m)
    np.testing.assert_array_equal(again.lidar.time_s, back.lidar.time_s)


def test_damaged_scan_is_refused(tmp_path):
    import h5py

    rec = Simulator(_with_lidar("wall", LIDAR_PRESETS["vlp16"])).run()[0]
    path = tmp_path / "r.h5"
    P.save_recording(path, rec)
    with h5py.File(path, "a") as f:
        f["recordings/000000/lidar/to_sensor"][0, 0] = 3.0
    with pytest.raises(
        P.RecordingFileError, match="lidar: point cloud: to_sensor must be a rigid transform"
    ):
        P.load_recording(path)
