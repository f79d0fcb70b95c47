"""Motion blur in the 3D view and the drive animation: the sensor's sweep over its
measurement window, as geometry (angles computed here from the turn rate and the
window) and as pixels."""

import numpy as np
import pytest

from acousim.scene import Pose, parse_scene
from acousim.simulator import Simulator
from acousim.viz.render3d import SWEEP_COLOR, sensor_sweep, sweep_wedge


def _angle_deg(a, b):
    return np.rad2deg(
        np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))
    )


def test_wedge_spans_the_angle_turned_during_the_window():
    rate_deg_s, window, v = 180.0, 0.036, np.array([1.0, 0.5, 0.0])
    pose = Pose([1.0, 2.0, 0.4], yaw_rad=np.deg2rad(30))
    positions, axes = sensor_sweep(
        pose.position_m, pose.rotation, v, [0, 0, np.deg2rad(rate_deg_s)], window, count=7
    )
    assert _angle_deg(axes[0], pose.rotation[:, 0]) < 1e-9  # starts at the emission pose
    assert _angle_deg(axes[0], axes[-1]) == pytest.approx(rate_deg_s * window, rel=1e-9)
    assert np.cross(axes[0], axes[-1])[2] > 0  # a positive z rate turns left
    assert positions[-1] - positions[0] == pytest.approx(v * window)
    vertices, quads = sweep_wedge(positions, axes, 1.5)
    assert quads.shape == (6, 4)
    # the wedge's first and last edges: the axis at emission and at the end
    first = vertices[quads[0, 1]] - vertices[quads[0, 0]]
    last = vertices[quads[-1, 2]] - vertices[quads[-1, 3]]
    assert np.linalg.norm(first) == pytest.approx(1.5) and np.linalg.norm(last) == pytest.approx(
        1.5
    )
    assert _angle_deg(first, last) == pytest.approx(rate_deg_s * window, rel=1e-9)


def _turning_recording(rate_deg_s):
    sc = parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "direct_path": False,
                "pose": {"velocity_m_s": [0.5, 0, 0], "angular_rate_deg_s": [0, 0, rate_deg_s]},
            },
            "simulation": {"max_range_m": 3.0},
            "points": [{"position_m": [2.0, 0.3, 0.0]}],
        }
    )
    return Simulator(sc).simulate_pose(sc.sensor.poses[0])


def test_recording_sweep_follows_its_stored_motion():
    """The sweep drawn for a recording: from its stored motion over its window."""
    from acousim.imaging.run import _sweep

    rec = _turning_recording(90.0)
    window = rec.samples.shape[1] / rec.sample_rate_hz
    positions, axes = _sweep(rec)
    assert _angle_deg(axes[0], axes[-1]) == pytest.approx(90.0 * window, rel=1e-6)
    assert positions[-1] - positions[0] == pytest.approx([0.5 * window, 0, 0])
    still = parse_scene({"sensor": {"array": "urtis_v1"}, "points": [{"position_m": [2, 0, 0]}]})
    assert _sweep(Simulator(still).simulate_pose(still.sensor.poses[0])) is None


def test_sweep_is_drawn_and_grows_with_the_turn_rate():
    """Pixels changed by drawing the sweep (same camera, same frame otherwise): none
    without it, more at 360 deg/s than at 90 deg/s, and orange among them."""
    pytest.importorskip("pyvista")
    from acousim.viz.render3d import FrameContent, SceneRenderer

    pose = Pose([0.0, 0.0, 0.0])
    renderer = SceneRenderer(None, window_size=(400, 300), with_sweep=True)
    try:
        images = []
        for rate in (None, 90.0, 360.0):
            sweep = sensor_sweep(
                pose.position_m, pose.rotation, np.zeros(3), [0, 0, np.deg2rad(rate or 0)], 0.036
            )
            image = renderer.frame(
                FrameContent(
                    pose.position_m,
                    pose.rotation[:, 0],
                    peaks=np.array([[2.0, 1.0, 0.0]]),
                    sweep=None if rate is None else sweep,
                )
            )
            images.append(np.asarray(image, float) / 255)
    finally:
        renderer.close()
    changed = [np.abs(im - images[0]).max(axis=2) > 0.05 for im in images]
    assert changed[0].sum() == 0 < changed[1].sum() < changed[2].sum()
    orange = np.abs(images[2] - np.array(SWEEP_COLOR)).max(axis=2) < 0.15
    assert (orange & changed[2]).sum() > 20


def test_moving_mesh_drawn_where_it_is_in_each_recording():
    import trimesh

    import acousim
    from acousim.imaging.run import _moving_triangles, _scene_triangles

    wall = acousim.MeshItem(trimesh.creation.box((0.1, 4, 2)), position_m=(3.0, 0, 0))
    box = acousim.MeshItem(
        trimesh.creation.box((0.4, 0.4, 1.0)), position_m=(2.0, -1.0, 0), velocity_m_s=(0, 1, 0)
    )
    sc = acousim.Scene(
        meshes=[wall, box],
        sensor=acousim.Sensor(poses=(Pose([0.0, 0, 0], time_s=0.5),)),
        simulation=acousim.Simulation(rays=500, max_range_m=4.0),
    )
    rec = Simulator(sc).simulate_pose(sc.sensor.poses[0])
    still = _scene_triangles(sc)
    assert still.reshape(-1, 3)[:, 0].min() == pytest.approx(2.95)  # the wall only
    moved = _moving_triangles(sc, rec).reshape(-1, 3)
    # the box 0.5 s later: its centre at y = -1 + 0.5
    assert (moved.min(axis=0) + moved.max(axis=0)) / 2 == pytest.approx([2.0, -0.5, 0.0])
