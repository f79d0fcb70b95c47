"""A corridor drive with a LiDAR: its scans at the sonar's captures in the ROS 2 bag
(PointCloud2, read back with rosbags), in CHIRP (lidar_00 on the acoustic time grid)
and in the 3D picture."""

import dataclasses

import h5py
import numpy as np
import pytest

import processing as P
from acousim.bundled import resolve
from acousim.cli import main
from acousim.scene import load_scene
from acousim.scene.lidar import lidar_preset
from acousim.simulator import Simulator


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    scene = load_scene(resolve("scenes", "corridor"))
    lidar = lidar_preset("vlp16", azimuth_step_deg=1.0, position_m=(0.0, 0.0, 0.15))
    scene = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, lidar=lidar))
    recs = Simulator(scene).run([0, 1])
    path = tmp_path_factory.mktemp("drive") / "drive.h5"
    P.save_recordings(path, recs)
    return path, P.load_recordings(path)


def test_rosbag_pointcloud2(drive, tmp_path):
    pytest.importorskip("rosbags", reason="rosbags not installed (pip install 'acousim[ros]')")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path, recs = drive
    bag = tmp_path / "bag"
    assert main(["export", str(path), "--out", str(bag), "--method", "das", "--step", "10"]) == 0
    clouds = []
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for conn, stamp, raw in reader.messages():
            if conn.topic == "/acousim/lidar":
                assert conn.msgtype == "sensor_msgs/msg/PointCloud2"
                clouds.append((stamp, reader.deserialize(raw, conn.msgtype)))
    assert [s for s, _ in clouds] == [0, 100_000_000]  # the drive's 10 Hz captures
    for (_, msg), rec in zip(clouds, recs):
        assert msg.header.frame_id == "acousim_sensor" and msg.width == len(rec.lidar)
        names = [(f.name, f.offset, f.datatype) for f in msg.fields]
        assert names == [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7),
                         ("time", 16, 7), ("ring", 20, 4)]  # fmt: skip
        raw = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.width, msg.point_step)
        xyz = raw[:, :12].copy().view("<f4").reshape(-1, 3)
        # the scan's points moved into the sonar frame by the 15 cm mounting
        expect = rec.lidar.points_m + [0, 0, 0.15]
        np.testing.assert_allclose(xyz, expect, atol=2e-6)
        ring = raw[:, 20:22].copy().view("<u2").ravel()
        np.testing.assert_array_equal(ring, rec.lidar.ring)


def test_chirp_lidar_on_the_acoustic_grid(drive, tmp_path):
    _, recs = drive
    P.write_chirp(tmp_path / "c.h5", recs)
    with h5py.File(tmp_path / "c.h5") as f:
        lidar, ac = f["sensors/lidar_00"], f["sensors/acoustic_transmitter_00"]
        np.testing.assert_array_equal(lidar["data/timestamps"][()], ac["data/timestamps"][()])
        np.testing.assert_allclose(lidar["calibration/to_origin"][:3, 3], [0, 0, 0.15])
        counts = lidar["data/point_counts"][()]
        pts = lidar["data/points"][()]
        assert counts.tolist() == [len(r.lidar) for r in recs]
        for k in range(2):
            assert np.isfinite(pts[k, : counts[k]]).all() and np.isnan(pts[k, counts[k] :]).all()
        # the floor (z = 0 in the world, the LiDAR 0.45 + 0.15 m above it): many points
        # on it, none below it
        z = pts[0, : counts[0], 2]
        assert (np.abs(z + 0.60) < 1e-3).sum() > 150 and z.min() > -0.60 - 1e-3
    chirppy = pytest.importorskip(
        "chirppy", reason="cosys-chirppy not installed (pip install cosys-chirppy)"
    )
    with chirppy.CHIRPDataset(tmp_path / "c.h5") as ds:
        lidar = ds.get_lidar(0)
        for k, rec in enumerate(recs):
            got = ds.transform_points(lidar.get_all_points(k), "lidar_00", "acoustic_sensor_00")
            np.testing.assert_allclose(got[:, :3], rec.lidar.in_sensor(), atol=2e-6)
            np.testing.assert_allclose(got[:, 3], rec.lidar.intensity, atol=1e-6)
            assert ds[k]["lidar_00"]["point_count"] == len(rec.lidar)


def test_3d_picture_shows_the_scan(drive, tmp_path):
    pytest.importorskip("pyvista", reason="pyvista not installed (pip install 'acousim[viz]')")
    from acousim.imaging.run import lidar_in_world
    from acousim.trace.world.build import build_world
    from acousim.viz.render3d import LIDAR_COLOR, FrameContent, render_scene

    _, recs = drive
    rec = recs[1]
    pose = rec.metadata["pose"]
    yaw = np.deg2rad(pose["yaw_deg"])
    tri = build_world(load_scene(resolve("scenes", "corridor"))).triangles
    at = (np.array(pose["position_m"]), np.array([np.cos(yaw), np.sin(yaw), 0.0]))
    scan = FrameContent(*at, lidar=lidar_in_world(rec))
    with_scan = render_scene(tmp_path / "a.png", scan, triangles=tri)
    without = render_scene(None, FrameContent(*at), triangles=tri)
    assert LIDAR_COLOR[1] > max(LIDAR_COLOR[0], LIDAR_COLOR[2]) + 0.3  # green

    def greens(img):
        """Greenish pixels: the points seen through the translucent walls are the
        LiDAR's green blended with grey (the view itself, no legend in it)."""
        rgb = img[..., :3].astype(int)
        return int((rgb[..., 1] - np.maximum(rgb[..., 0], rgb[..., 2]) > 25).sum())

    assert greens(with_scan) > 300 and greens(without) == 0


def test_full_capture_sensors_are_aligned(drive, tmp_path):
    """A CHIRP file (not of ours) whose LiDAR and odometry store their own streams
    (sync_mode full_capture, as Cosys-Lab's recordings do): the LiDAR by the nearest
    timestamp, the odometry through sync_to_reference_index."""
    _, recs = drive
    path = tmp_path / "full.h5"
    P.write_chirp(path, recs)
    with h5py.File(path, "a") as f:
        del f["acousim"]
        g = f["sensors/lidar_00"]
        g.attrs["sync_mode"] = "full_capture"
        pts, n = g["data/points"][()], g["data/point_counts"][()]
        # three scans at 0.03, 0.07 and 0.12 s: nearest to the captures at 0 and 0.1 s
        # are the first and the third (which holds capture 1's points)
        for name, data in (("points", pts[[0, 0, 1]]), ("point_counts", n[[0, 0, 1]]),
                           ("timestamps", np.array([0.03, 0.07, 0.12])),):  # fmt: skip
            del g[f"data/{name}"]
            g[f"data/{name}"] = data
        o = f["sensors/odometry_00"]
        o.attrs["sync_mode"] = "full_capture"
        for name in ("position", "orientation"):
            d = o[f"data/{name}"][()]
            del o[f"data/{name}"]
            o[f"data/{name}"] = d[[1, 0]]  # stored in the other order ...
        o["data/sync_to_reference_index"] = np.array([1, 0])  # ... and mapped back
    back = P.load_recordings(path)
    for a, b in zip(recs, back):
        np.testing.assert_allclose(b.lidar.in_sensor(), a.lidar.in_sensor(), atol=2e-6)
        np.testing.assert_allclose(
            b.metadata["pose"]["position_m"], a.metadata["pose"]["position_m"], atol=1e-12
        )
        assert b.metadata["pose"]["yaw_deg"] == pytest.approx(a.metadata["pose"]["yaw_deg"])
