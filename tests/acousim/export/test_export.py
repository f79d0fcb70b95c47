"""Files other tools read, read back WITHOUT our code (plain h5py, csv, rosbags):
the images with their axes, the peaks, and the ROS 2 bag.  One point reflector at a
direction worked out by hand, seen from a sensor at a known pose."""

import csv
import io
import json
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

import processing as P
from acousim.cli import main
from tests import REPO
from tests.oracles.scenes import PAPER_SENSOR_TOML

ROOT = REPO

# the sensor at (0.5, -0.2, 0.3), turned 30 deg to the left (yaw); the reflector at
# 1.0 m forward, 0.5 m left and 0.2 m up in the sensor frame
YAW = np.deg2rad(30.0)
POS = np.array([0.5, -0.2, 0.3])
ROT = np.array([[np.cos(YAW), -np.sin(YAW), 0], [np.sin(YAW), np.cos(YAW), 0], [0, 0, 1]])
P_SENSOR = np.array([1.0, 0.5, 0.2])
P_WORLD = POS + ROT @ P_SENSOR
RANGE = float(np.linalg.norm(P_SENSOR))
AZ = np.rad2deg(np.arctan2(0.5, 1.0))  # 26.57 deg, left
EL = np.rad2deg(np.arctan2(0.2, np.hypot(1.0, 0.5)))  # 10.13 deg, up


@pytest.fixture(scope="module")
def recording_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    scene = d / "left.toml"
    scene.write_text(
        '[scene]\nname = "left"\n'
        + PAPER_SENSOR_TOML
        + f"""[sensor.pose]
position_m = [{POS[0]}, {POS[1]}, {POS[2]}]
yaw_deg = 30.0
[simulation]
max_range_m = 2.0
snr_db = 20.0
absorption = false
seed = 5
[[points]]
position_m = [{P_WORLD[0]:.9f}, {P_WORLD[1]:.9f}, {P_WORLD[2]:.9f}]
"""
    )
    out = d / "left.h5"
    assert main(["simulate", str(scene), "--out", str(out)]) == 0
    return out


ARGS = ["--method", "das,music-fbss", "--step", "1", "--energy-fraction", "0.3"]


def test_images_and_peaks_read_back_with_plain_h5py_and_csv(recording_file, tmp_path):
    out = tmp_path / "img"
    assert (
        main(["image", str(recording_file), "--out", str(out), "--no-3d", "--images-h5", *ARGS])
        == 0
    )
    with h5py.File(out / "images.h5", "r") as f:
        assert f.attrs["format"] == "acousim-images"
        (name,) = list(f)
        g = f[name]
        assert g.attrs["index"] == 0
        for method in ("das", "music-fbss"):
            d = g[method]
            assert d.attrs["units"] == "dB" and d.ndim == 3
            # the axes are attached as dimension scales, with units
            rng, el, az = (d.dims[k][0] for k in range(3))
            assert [rng.name.rsplit("/", 1)[1], el.name.rsplit("/", 1)[1]] == [
                "range_m",
                "elevation_deg",
            ]
            assert az.attrs["units"] == "degree" and rng.attrs["units"] == "m"
            level = d[()]
            i, j, k = np.unravel_index(np.nanargmax(level), level.shape)
            assert np.nanmax(level) == 0.0
            # the strongest cell is the reflector: range from the array centre
            assert abs(rng[i] - RANGE) < 0.03
            assert abs(az[k] - AZ) <= 3.0 and abs(el[j] - EL) <= 3.0, (az[k], el[j])
            assert np.diff(rng[()]).std() < 1e-9  # a regular range axis
            # the truth label map beside it: the point's object where the point shows
            obj = g[f"{method}_object"][()]
            assert obj.shape == level.shape and obj[i, j, k] == 0
            assert [x.decode() for x in g["object_names"][()]] == ["point 0"]
            assert g[f"{method}_order"][i, j, k] == 1
            # its peaks, with their truth, as peaks.csv has them
            p = g["peaks"][method]
            assert p["level_db"][0] == 0.0 and p["truth_kind"][0].decode() == "point"
            assert p["truth_object"][0].decode() == "point 0" and p["truth_order"][0] == 1
    with open(out / "peaks.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert rows and rows[0]["recording"] == "0"
    with h5py.File(out / "images.h5", "r") as f:  # a peak's cell: exactly on the axes
        g = f["recording_000000"]
        axes = {k: set(g[k][()].tolist()) for k in ("range_m", "azimuth_deg", "elevation_deg")}
    for r in rows:
        for k, values in axes.items():
            assert float(r[k]) in values, (k, r[k])
    for method in ("das", "music-fbss"):
        top = [r for r in rows if r["method"] == method][0]  # strongest first
        assert float(top["level_db"]) == 0.0
        assert (
            abs(float(top["azimuth_deg"]) - AZ) <= 3 and abs(float(top["elevation_deg"]) - EL) <= 3
        )
        s = np.array([float(top[c]) for c in ("x_m", "y_m", "z_m")])
        w = np.array([float(top[c]) for c in ("world_x_m", "world_y_m", "world_z_m")])
        assert np.linalg.norm(s - P_SENSOR) < 0.06
        assert np.linalg.norm(w - P_WORLD) < 0.06
        # the peak's traced reflector: the point placed by hand, inside the grid
        assert top["on_grid_edge"] == "0" and top["truth_kind"] == "point"
        t = np.array([float(top[c]) for c in ("truth_x_m", "truth_y_m", "truth_z_m")])
        np.testing.assert_allclose(t, P_SENSOR, atol=1e-6)
        assert float(top["truth_level_db"]) == 0.0 and top["truth_behind"] == "0"
        assert float(top["truth_offset_deg"]) <= 3.0
        assert top["provenance"] == "simulated"
    from acousim.dataset.info import describe

    lines = describe(out / "images.h5")
    assert lines[0].endswith("images of 1 recording(s) (format acousim-images)")
    assert "[0] simulated (left): das, music-fbss" in lines[1]


def test_rosbag_reads_back_with_rosbags(recording_file, tmp_path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "bag"
    assert main(["export", str(recording_file), "--out", str(bag), *ARGS]) == 0
    assert (bag / "metadata.yaml").is_file() and list(bag.glob("*.mcap"))
    rec = P.load_recording(recording_file)
    msgs = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for conn, stamp, raw in reader.messages():
            msgs[conn.topic] = (conn.msgtype, stamp, reader.deserialize(raw, conn.msgtype))
    assert set(msgs) == {
        "/acousim/raw",
        "/acousim/info",
        "/acousim/peaks",
        "/acousim/fan",
        "/tf",
        "/clock",
        "/acousim/reflectors",  # the point reflector; no mesh, so no /acousim/scene
    }
    # raw samples: (microphone, sample), row major, float32
    kind, stamp, raw = msgs["/acousim/raw"]
    assert kind == "std_msgs/msg/Float32MultiArray" and stamp == 0
    dims = raw.layout.dim
    assert [d.label for d in dims] == ["microphone", "sample"]
    assert (dims[0].size, dims[1].size) == rec.samples.shape == (64, rec.n_samples)
    np.testing.assert_array_equal(
        np.asarray(raw.data).reshape(dims[0].size, dims[1].size), rec.samples.astype(np.float32)
    )
    info = json.loads(msgs["/acousim/info"][2].data)
    assert info["provenance"] == "simulated" and info["fan"]["dynamic_range_db"] == 30
    assert info["sample_rate_hz"] == 500e3 and len(info["mic_positions_m"]) == 64
    assert info["image_method"] == "music-fbss"
    # the pose as TF: world -> sensor, translation and a 30 deg yaw
    (tf,) = msgs["/tf"][2].transforms
    assert (tf.header.frame_id, tf.child_frame_id) == ("world", "acousim_sensor")
    t, q = tf.transform.translation, tf.transform.rotation
    np.testing.assert_allclose([t.x, t.y, t.z], POS, atol=1e-9)
    np.testing.assert_allclose(
        [q.x, q.y, q.z, q.w], [0, 0, np.sin(YAW / 2), np.cos(YAW / 2)], atol=1e-9
    )
    # peaks: PointCloud2 of float32 x, y, z, level_db, range_m in the sensor frame
    cloud = msgs["/acousim/peaks"][2]
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "level_db", "range_m"]
    assert all(f.datatype == 7 for f in cloud.fields) and cloud.point_step == 20
    pts = np.frombuffer(bytes(cloud.data), "<f4").reshape(cloud.width, 5)
    assert cloud.header.frame_id == "acousim_sensor"
    best = pts[np.argmax(pts[:, 3])]
    assert best[3] == 0.0
    assert np.linalg.norm(best[:3] - P_SENSOR) < 0.06
    assert abs(best[4] - RANGE) < 0.03
    # fan image: 32FC1 dB, row 0 the farthest x, column 0 the largest y (left)
    img = msgs["/acousim/fan"][2]
    assert img.encoding == "32FC1" and img.step == 4 * img.width
    fan = np.frombuffer(bytes(img.data), "<f4").reshape(img.height, img.width)
    e = info["fan"]["extent_m"]
    r, c = np.unravel_index(np.nanargmax(fan), fan.shape)
    y = e["y_left"] + (c + 0.5) * (e["y_right"] - e["y_left"]) / img.width
    x = e["x_far"] - (r + 0.5) * (e["x_far"] - e["x_near"]) / img.height
    # the fan collapses elevation: the echo lies at its slant range along its azimuth
    expect = RANGE * np.array([np.sin(np.deg2rad(AZ)), np.cos(np.deg2rad(AZ))])
    assert np.hypot(y - expect[0], x - expect[1]) < 0.08, (y, x, expect)
    # a second export never overwrites
    assert main(["export", str(recording_file), "--out", str(bag), *ARGS]) == 2


def test_rosbag_carries_clock_scene_meshes_and_traced_reflectors(tmp_path):
    """The bag alone shows the scene: /clock at every recording's stamp, the wall's
    triangles as a marker in the world frame, the traced reflection point as a cloud
    in the sensor frame where geometry puts it (the wall's nearest point)."""
    import trimesh
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from acousim.bundled import find_scene

    rec_file, bag = tmp_path / "wall.h5", tmp_path / "bag"
    assert main(["simulate", "wall", "--out", str(rec_file)]) == 0
    assert main(["export", str(rec_file), "--out", str(bag), "--method", "das"]) == 0
    msgs: dict = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for conn, stamp, raw in reader.messages():
            msgs.setdefault(conn.topic, []).append((stamp, reader.deserialize(raw, conn.msgtype)))
    ((stamp, clock),) = msgs["/clock"]
    assert clock.clock.sec * 10**9 + clock.clock.nanosec == stamp == msgs["/tf"][0][0]
    # the scene: one TRIANGLE_LIST marker holding every triangle of wall.stl
    ((_, array),) = msgs["/acousim/scene"]
    (marker,) = array.markers
    assert marker.type == 11 and marker.header.frame_id == "world"  # TRIANGLE_LIST
    mesh = trimesh.load(find_scene("wall").parent / "meshes" / "wall.stl")
    pts = np.array([[p.x, p.y, p.z] for p in marker.points])
    assert len(pts) == 3 * len(mesh.faces)
    ours = sorted(map(tuple, np.round(pts, 6)))
    assert ours == sorted(map(tuple, np.round(mesh.triangles.reshape(-1, 3), 6)))
    # the reflectors: the specular point is the wall's point nearest the sensor
    ((_, cloud),) = msgs["/acousim/reflectors"]
    names = ["x", "y", "z", "level_db", "order", "apparent_x", "apparent_y", "apparent_z"]
    assert [f.name for f in cloud.fields] == [*names, "delay_s", "object", "emitter"]
    assert cloud.header.frame_id == "acousim_sensor"
    table = np.frombuffer(bytes(cloud.data), "<f4").reshape(cloud.width, 11)
    assert np.all(table[:, 10] == 0)  # one sensor: every path carries its own call
    best = table[np.argmax(table[:, 3])]
    foot, _, _ = trimesh.proximity.closest_point(mesh, [[0.0, 0.0, 0.0]])
    yaw = np.deg2rad(15.0)  # wall.toml's sensor pose: at the origin, yaw 15 deg
    to_sensor = np.array([[np.cos(yaw), np.sin(yaw), 0], [-np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    np.testing.assert_allclose(best[:3], to_sensor @ foot[0], atol=0.02)
    assert best[3] == 0.0 and best[4] == 1
    # a first-order echo is seen about where it reflected (the emitter sits 1-2 cm
    # off the array centre), half its delay's path away
    np.testing.assert_allclose(best[5:8], best[:3], atol=0.02)
    assert 343.0 * best[8] / 2 == pytest.approx(np.linalg.norm(best[5:8]), abs=0.02)
    assert best[9] == 0  # the only object, the wall
    info = json.loads(msgs["/acousim/info"][0][1].data)  # what the indices name
    assert info["emitters"] == ["acousim_sensor"] and info["sensor"] is None
    assert info["object_names"][0].startswith("wall")
    assert info["crosstalk"] == [] and info["mount"] is None
    from acousim.dataset.info import describe

    lines = describe(bag)
    assert "8 message(s)" in lines[0] and "recordings: 1 simulated" in lines[1]  # 8 topics
    assert "  /acousim/scene: visualization_msgs/msg/MarkerArray, 1 message(s)" in lines


def test_interrupted_image_leaves_no_partial_file(recording_file, tmp_path, monkeypatch):
    import acousim.export.images as images_mod

    def boom(*a, **k):
        raise KeyboardInterrupt

    out = tmp_path / "img"
    monkeypatch.setattr(images_mod.csv, "writer", boom)  # after images.h5, mid-CSV
    code = main(["image", str(recording_file), "--out", str(out), "--no-3d", *ARGS])
    assert code == 130
    # nothing complete was written (no --images-h5): no peaks.csv, no picture, no
    # temporary file, and the folder the run created is removed, empty
    assert not out.exists(), sorted(p.name for p in out.iterdir())


@pytest.mark.parametrize("delay_s", [0.3, 1.0, 2.0])
def test_ctrl_c_during_image_stops_cleanly(recording_file, tmp_path, delay_s):
    """A real SIGINT at several moments (during the imports of numpy/matplotlib/VTK,
    the imaging, the writing): a clean stop (or 0 if it finished), and no temporary
    file."""
    out = tmp_path / "img"
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "acousim.cli",
            "image",
            str(recording_file),
            "--out",
            str(out),
            *ARGS,
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        # a test run in the background inherits an ignored SIGINT: restore the default
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    time.sleep(delay_s)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    # 130: main() caught the interrupt; -SIGINT: Python died of SIGINT, as it does when
    # the interrupt lands before main() (numpy's import) or inside some C extension's
    # import (the shell sees 130 either way); never a crash (SIGSEGV, SIGABRT)
    assert proc.returncode in (0, 130, -signal.SIGINT), err.decode()[-2000:]
    if out.exists():
        assert not [p.name for p in out.iterdir() if p.name.startswith(".")]


def test_images_open_as_netcdf_in_xarray(recording_file, tmp_path):
    """xarray (through h5netcdf, not our code) sees each image with its axes as
    coordinates; the strongest cell is the reflector worked out by hand."""
    import xarray as xr  # with h5netcdf: the dev extra, installed by `make`

    out = tmp_path / "img"
    assert (
        main(["image", str(recording_file), "--out", str(out), "--no-3d", "--images-h5", *ARGS])
        == 0
    )
    group = "recording_000000"
    with xr.open_dataset(
        out / "images.h5", engine="h5netcdf", group=group, phony_dims="sort"
    ) as ds:
        das = ds["das"]
        assert das.dims == ("range_m", "elevation_deg", "azimuth_deg")
        top = das.where(das == das.max(), drop=True)
        assert abs(float(top.range_m[0]) - RANGE) < 0.03
        assert abs(float(top.azimuth_deg[0]) - AZ) <= 3.0
        assert abs(float(top.elevation_deg[0]) - EL) <= 3.0
        assert ds.attrs["index"] == 0


@pytest.mark.parametrize("compression", ["lzf", "gzip", None])
def test_images_h5_holds_the_levels_and_nan_at_gated_bins(recording_file, tmp_path, compression):
    """Plain h5py reads back, at every kept bin, 10 log10(p / max) in steps of
    1/128 dB (computed here), and NaN at the bins the gate removed (runs of kept
    bins with gaps, a chunk's worth of gated bins among them)."""
    from acousim.export import write_image_data

    rec = P.load_recording(recording_file, 0)
    rng = np.random.default_rng(3)
    step = 0.01
    kept = np.array([0, 1, 2, 5, 6, 13, 14, 15, 16, 17, 30])
    power = rng.uniform(1e-9, 2.0, (kept.size, 3, 4)) ** 3
    power[1, 0, 0] = 0.0  # no power: the floor, -300 dB
    image = P.Image(
        power=power,
        range_m=0.5 + step * kept,
        elevation_rad=np.deg2rad([-2.0, 0.0, 2.0]),
        azimuth_rad=np.deg2rad([-3.0, -1.0, 1.0, 3.0]),
        method="das",
        frequency_hz=40e3,
        bin_range_m=step,
    )
    path = write_image_data(tmp_path / "i.h5", [rec], [{"das": image}], compression=compression)
    want = np.full((31, 3, 4), np.nan, np.float32)
    with np.errstate(divide="ignore"):
        db = np.maximum(10 * np.log10(power / power.max()), -300.0)
    want[kept] = np.round(db * 128) / 128
    with h5py.File(path, "r") as f:
        d = f["recording_000000/das"]
        assert d.dtype == np.float32 and d.compression == compression
        np.testing.assert_array_equal(d[()], want)  # NaN where NaN
        np.testing.assert_allclose(f["recording_000000/range_m"][()], 0.5 + step * np.arange(31))


def test_label_maps_made_elsewhere_are_written_as_those_made_there(recording_file, tmp_path):
    """write_image_data with the label maps handed to it (as `acousim image` makes
    them, in a second process) writes the same label datasets as making them itself,
    and reports its progress by recording."""
    from acousim.export import write_image_data
    from acousim.export.images import Given, label_maps
    from acousim.imaging.run import ImagingOptions, image_recordings

    recs = [P.load_recording(recording_file, 0)]
    images = image_recordings(recs, ImagingOptions(methods=("das", "music-fbss"), step_deg=4.0))
    calls = []
    given = Given(labels=label_maps(recs, images), progress=lambda *a: calls.append(a))
    handed = write_image_data(tmp_path / "a.h5", recs, images, given=given)
    made = write_image_data(tmp_path / "b.h5", recs, images)
    assert calls == [(1, 1)]
    with h5py.File(handed, "r") as a, h5py.File(made, "r") as b:
        g, h = a["recording_000000"], b["recording_000000"]
        for name in ("das_object", "das_order", "music-fbss_object", "music-fbss_order"):
            np.testing.assert_array_equal(g[name][()], h[name][()])
            assert g[name].attrs["long_name"] == h[name].attrs["long_name"]
        assert (g["das_object"][()] >= 0).any()  # a labelled cell: the maps were written


def test_label_maps_ahead_hand_out_what_label_maps_makes(recording_file):
    """label_maps_ahead (images.h5's maps, the next made in a thread): every
    recording's maps, in order, equal to those label_maps makes."""
    from acousim.export.images import label_maps, label_maps_ahead
    from acousim.imaging.run import ImagingOptions, image_recordings

    recs = [P.load_recording(recording_file, 0)] * 3
    images = image_recordings(recs, ImagingOptions(methods=("das",), step_deg=4.0))
    out = list(label_maps_ahead(recs, images))
    want = list(label_maps(recs, images))
    assert len(out) == 3
    for got, ref in zip(out, want):
        assert list(got) == list(ref) and len(ref) == 1
        for res in ref:
            np.testing.assert_array_equal(got[res].object_index, ref[res].object_index)
            np.testing.assert_array_equal(got[res].order, ref[res].order)


@pytest.mark.parametrize("isal", [True, False])
@pytest.mark.parametrize("dtype", [np.int8, np.int16, np.float32])
def test_chunks_packed_by_hand_read_back_through_hdf5s_own_filters(tmp_path, dtype, isal):
    """images.h5's chunks are shuffled and deflated here (ISA-L or zlib) and written
    as they are: plain h5py, undoing them with HDF5's own shuffle and gzip filters,
    reads back the values given (an edge chunk past the last range bin included)."""
    from acousim.export import images

    if isal and images._isal_zlib is None:
        pytest.skip("the isal package is not installed")
    values = np.random.default_rng(1).integers(-1, 90, (37, 5, 7)).astype(dtype)
    values[:9] = -1  # runs of one value, as a label map's empty bins
    bins = 16
    with pytest.MonkeyPatch.context() as mp:
        if not isal:
            mp.setattr(images, "_isal_zlib", None)
        packed = images._packed_chunks(values, bins)
    with h5py.File(tmp_path / "c.h5", "w") as f:
        d = f.create_dataset(
            "x", shape=values.shape, dtype=dtype, chunks=(bins, 5, 7), compression="gzip",
            shuffle=True,
        )  # fmt: skip
        for offset, raw in packed:
            d.id.write_direct_chunk(offset, raw, 0)
    with h5py.File(tmp_path / "c.h5", "r") as f:
        np.testing.assert_array_equal(f["x"][()], values)
        assert f["x"].compression == "gzip" and f["x"].shuffle


def test_label_maps_read_back_as_made_whatever_the_compression(recording_file, tmp_path):
    """The label maps, written as packed chunks (gzip, shared by the methods of one
    resolution) or by h5py itself (no compression), read back as the label maps made
    (int16 objects, int8 orders) for every method."""
    from acousim.export import write_image_data
    from acousim.export.images import label_maps
    from acousim.imaging.run import ImagingOptions, image_recordings

    recs = [P.load_recording(recording_file, 0)]
    images = image_recordings(recs, ImagingOptions(methods=("das", "music-fbss"), step_deg=2.0))
    (made,) = list(label_maps(recs, images))
    (labels,) = made.values()  # one frequency: one resolution, one map for both
    assert labels.object_index.shape[0] > 16  # more than one chunk
    for compression in ("gzip", None):
        path = tmp_path / f"{compression}.h5"
        write_image_data(path, recs, images, compression=compression)
        with h5py.File(path, "r") as f:
            g = f["recording_000000"]
            for method in ("das", "music-fbss"):
                obj, order = g[f"{method}_object"], g[f"{method}_order"]
                assert obj.dtype == np.int16 and order.dtype == np.int8
                np.testing.assert_array_equal(obj[()], labels.object_index)
                np.testing.assert_array_equal(order[()], labels.order)
                assert obj.compression == compression


def test_peaks_csv_writes_numbers_in_full_and_no_value_as_an_empty_cell():
    """A peak without truth: truth_order and truth_behind (None) are empty cells, as
    NaN is; a number is the float64 itself (0.44641854 is not rounded to 0.446419)."""
    from acousim.export.images import peaks_csv_text

    matched = P.PeakRow(
        recording=3, method="das", range_m=0.44641854, azimuth_deg=-12.5, level_db=-4.70148312,
        x_m=1e-19, on_grid_edge=True, truth_kind="specular", truth_order=2, truth_behind=False,
    )  # fmt: skip
    unmatched = P.PeakRow(recording=3, method="das", range_m=1.0 / 3.0, truth_note="none")
    assert unmatched.truth_order is None and unmatched.truth_behind is None
    text = peaks_csv_text([{"das": P.PeakTable([matched, unmatched])}])
    a, b = csv.DictReader(io.StringIO(text))
    assert a["range_m"] == "0.44641854" and a["level_db"] == "-4.70148312"
    assert a["x_m"] == "1e-19" and a["azimuth_deg"] == "-12.5"
    assert (a["on_grid_edge"], a["truth_order"], a["truth_behind"]) == ("1", "2", "0")
    assert float(b["range_m"]) == 1.0 / 3.0 and b["range_m"] == "0.3333333333333333"
    assert (b["truth_order"], b["truth_behind"], b["elevation_deg"]) == ("", "", "")
    assert (b["recording"], b["truth_note"]) == ("3", "none")
