"""A rig's recordings in files and tools: one CHIRP file with an acoustic group per
sonar (read back with h5py alone, by ours and, when installed, by chirppy).
References: the mounts, firing times and sample rates the test declares, the
rotation written out in tests.oracles.analytic."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
import trimesh

import processing as P
from acousim.rig import RigSimulator
from acousim.scene import parse_scene
from tests.oracles.analytic import rotation_zyx

#: the sonars: name, mount position (m), rotation (roll, pitch, yaw; degrees),
#: sample rate (Hz) and first firing (s); each fires twice at 20 Hz
SONARS = (
    ("front", [0.2, 0.1, 0.05], [0.0, 0.0, 0.0], 450e3, 0.0),
    ("side", [0.0, -0.15, 0.1], [0.0, 5.0, -40.0], 500e3, 0.02),
)
BODY_Z, SPEED, TURN_DEG_S = 0.3, 0.5, 10.0
#: the LiDARs: mount position (m) and rotation (roll, pitch, yaw; degrees)
LIDARS = (([0.0, 0.0, 0.4], [0.0, 0.0, 0.0]), ([0.3, 0.0, 0.2], [0.0, 0.0, 90.0]))


def mount(position, rotation_deg) -> np.ndarray:
    """A mount (sensor -> body, 4x4) from its declared numbers."""
    T = np.eye(4)
    roll, pitch, yaw = np.deg2rad(rotation_deg)
    T[:3, :3] = rotation_zyx(yaw, pitch, roll)
    T[:3, 3] = position
    return T


@pytest.fixture(scope="module")
def rig_recordings(tmp_path_factory):
    """Two sonars on a driving, turning body, a wall 2 m ahead, two VLP-16: their
    four firings as a recording file holds them (float32)."""
    tmp = tmp_path_factory.mktemp("rigfiles")
    wall = trimesh.creation.box(extents=(0.1, 6.0, 3.0))
    wall.apply_translation([2.05, 0, 1.0])
    wall.export(tmp / "wall.obj")
    sensors = [
        {
            "name": name,
            "array": "urtis_v1",
            "sample_rate_hz": fs,
            "mount": {"position_m": pos, "rotation_deg": rot},
            "firing": {"rate_hz": 20, "offset_s": t0, "count": 2},
        }
        for name, pos, rot, fs, t0 in SONARS
    ]
    scene = parse_scene(
        {
            "body": {
                "pose": {
                    "position_m": [0, 0, BODY_Z],
                    "velocity_m_s": [SPEED, 0, 0],
                    "angular_rate_deg_s": [0, 0, TURN_DEG_S],
                }
            },
            "sensors": sensors,
            "lidars": [
                {"preset": "vlp16", "position_m": pos, "rotation_deg": rot} for pos, rot in LIDARS
            ],
            "simulation": {"max_range_m": 2.5, "diffraction": {"enabled": False}},
            "materials": [{"name": "m", "reflection": 1.0, "diffuse": 0.0}],
            "meshes": [{"file": "wall.obj", "material": "m"}],
        },
        base_dir=tmp,
    )
    recs = RigSimulator(scene).run().recordings
    P.save_recordings(tmp / "rig.h5", list(recs))
    return tmp, P.load_recordings(tmp / "rig.h5")


@pytest.fixture(scope="module")
def rig_chirp(rig_recordings):
    tmp, recs = rig_recordings
    return P.write_chirp(tmp / "rig_chirp.h5", recs), recs


def test_a_rig_in_one_chirp_file_has_a_group_per_sonar(rig_chirp):
    """Read with h5py alone: each sonar's group, its mount (through base_link), its
    firings' samples and times."""
    path, recs = rig_chirp
    assert [r.metadata["sensor"] for r in recs] == ["front", "side", "front", "side"]
    with h5py.File(path, "r") as f:
        assert f.attrs["reference_sensor"] == "acoustic_sensor_00"
        assert f.attrs["n_reference_captures"] == 2  # the reference sonar's firings
        body_to_origin = f["transforms/base_link_to_origin"][()]
        for n, (name, pos, rot, fs, t0) in enumerate(SONARS):
            g = f[f"sensors/acoustic_sensor_{n:02d}"]
            assert g.attrs["name"] == name and g.attrs["sample_rate_hz"] == fs
            assert g.attrs["sync_mode"] == ("reference_capture" if n == 0 else "full_capture")
            to_origin = g["calibration/to_origin"][()]
            np.testing.assert_allclose(
                np.linalg.inv(body_to_origin) @ to_origin, mount(pos, rot), atol=1e-12
            )
            mine = [r for r in recs if r.metadata["sensor"] == name]
            sig = g["data/signals"]
            assert sig.shape == (2, mine[0].n_samples, 30)
            for k, rec in enumerate(mine):
                np.testing.assert_array_equal(sig[k].T, rec.samples)
            fired = t0 + np.array([0.0, 0.05])  # the declared schedule
            tx = f[f"sensors/acoustic_transmitter_{n:02d}"]
            np.testing.assert_allclose(tx["data/timestamps"][()], fired, atol=1e-12)
            lead = np.array([r.emission_index for r in mine]) / fs
            np.testing.assert_allclose(g["data/timestamps"][()], fired - lead, atol=1e-12)
            emitter = np.linalg.inv(to_origin) @ tx["calibration/to_origin"][()]
            np.testing.assert_allclose(emitter[:3, 3], mine[0].array.emitter_m, atol=1e-12)
            if n:  # the reference captures at 0 and 50 ms: its firing nearest each (20, 70 ms)
                np.testing.assert_array_equal(g["data/sync_to_reference_index"][()], [0, 1])
        # the body's odometry, one row per firing: driving 0.5 m/s, turning 10 deg/s
        odo = f["sensors/odometry_00/data"]
        t = np.array([0.0, 0.02, 0.05, 0.07])
        np.testing.assert_allclose(odo["timestamps"][()], t, atol=1e-12)
        np.testing.assert_allclose(odo["yaw"][()], np.deg2rad(TURN_DEG_S) * t, atol=1e-12)
        np.testing.assert_allclose(odo["position"][:, 0], SPEED * t, atol=1e-12)
        np.testing.assert_allclose(odo["position"][:, 2], BODY_Z, atol=1e-12)
        yaw = np.deg2rad(TURN_DEG_S) * t  # the world's velocity (+x) in the turned body
        v = np.stack([SPEED * np.cos(yaw), -SPEED * np.sin(yaw), 0 * t], axis=1)
        np.testing.assert_allclose(odo["linear_velocity"][()], v, atol=1e-12)
        w = np.deg2rad(TURN_DEG_S)
        np.testing.assert_allclose(odo["angular_velocity"][()], [[0, 0, w]] * 4, atol=1e-12)
        # the LiDARs beside them, at their mounts on the body, a scan per firing
        for n, (pos, rot) in enumerate(LIDARS):
            g = f[f"sensors/lidar_{n:02d}"]
            lidar = np.linalg.inv(body_to_origin) @ g["calibration/to_origin"][()]
            np.testing.assert_allclose(lidar, mount(pos, rot), atol=1e-12)
            assert g["data/points"].shape[0] == 4
            # the reference sonar's captures are rows 0 and 2 (one row per firing)
            np.testing.assert_array_equal(g["data/sync_to_reference_index"][()], [0, 2])


def test_our_reader_gives_back_each_sonars_recordings(rig_chirp):
    path, recs = rig_chirp
    back = P.load_recordings(path)
    assert P.count_recordings(path) == 4
    for a, b in zip(recs, back, strict=True):
        assert b.metadata == a.metadata and b.sample_rate_hz == a.sample_rate_hz
        np.testing.assert_array_equal(b.samples, a.samples)
        np.testing.assert_array_equal(b.array.positions_m, a.array.positions_m)
        np.testing.assert_allclose(b.array.emitter_m, a.array.emitter_m, atol=1e-12)
        assert len(a.lidars) == len(b.lidars) == 2
        for sa, sb in zip(a.lidars, b.lidars):
            np.testing.assert_allclose(sb.to_sensor, sa.to_sensor, atol=1e-12)
            np.testing.assert_array_equal(sb.points_m, sa.points_m)
            np.testing.assert_array_equal(sb.ring, sa.ring)
        np.testing.assert_array_equal(b.truth.emitter, a.truth.emitter)
    one = P.load_recording(path, 3)
    assert one.metadata["sensor"] == "side" and one.sample_rate_hz == 500e3


def test_chirppy_reads_the_rig(rig_chirp):
    chirppy = pytest.importorskip(
        "chirppy", reason="cosys-chirppy not installed (pip install cosys-chirppy)"
    )
    path, recs = rig_chirp
    with chirppy.CHIRPDataset(path) as ds:
        assert len(ds) == 2
        for n, (_, pos, rot, _, _) in enumerate(SONARS):
            T = ds.get_transform(f"acoustic_sensor_{n:02d}", "base_link")
            np.testing.assert_allclose(T, mount(pos, rot), atol=1e-12)
            up = ds.get_transform(f"acoustic_sensor_{n:02d}", "ground")
            assert up[2, 3] == pytest.approx(BODY_Z + pos[2], abs=1e-12)
        side = ds.get_acoustic_sensor(1)
        assert len(side) == 2 and side.num_reference_captures == 2
        capture = side.at_reference_capture(1)  # at 50 ms: side's firing at 70 ms
        mine = [r for r in recs if r.metadata["sensor"] == "side"]
        np.testing.assert_array_equal(capture["signals"].T, mine[1].samples)
        assert capture["timestamp"] == pytest.approx(0.07 - mine[1].emission_index / 500e3)


def test_info_lists_the_sonars_of_a_rig_file(rig_chirp, capsys):
    from acousim.cli import main

    path, _ = rig_chirp
    for f in (path, path.with_name("rig.h5")):  # CHIRP, and our recording file
        assert main(["info", str(f)]) == 0
        out = capsys.readouterr().out
        assert (
            "a rig of 2 sonar(s): 'front' 2 firing(s), mount [0.2, 0.1, 0.05] m, "
            "roll/pitch/yaw [0.0, 0.0, 0.0]°; 'side' 2 firing(s), mount [0.0, -0.15, 0.1] m, "
            "roll/pitch/yaw [0.0, 5.0, -40.0]°"
        ) in out
        chirp_header = "2 capture(s) of the reference sonar 'front'"
        assert (chirp_header in out) == (f == path)


def test_image_draws_one_animation_per_sonar(rig_recordings, tmp_path):
    """A rig's file: drive_<sonar>.gif for each sonar, of its own firings only (20 Hz:
    50 ms a frame), no drive.gif; one sonar's (--sensor): drive.gif.  An earlier
    run's per-sonar GIFs are ours (removed when not written again); a user's file
    that only looks like one stays."""
    from PIL import Image

    from acousim.cli import main

    folder, recs = rig_recordings
    base = ["image", str(folder / "rig.h5"), "--no-3d", "--method", "das", "--out"]
    assert main([*base, str(tmp_path / "all")]) == 0
    gifs = sorted(p.name for p in (tmp_path / "all").glob("*.gif"))
    assert gifs == ["drive_front.gif", "drive_side.gif"]
    for name in ("front", "side"):
        with Image.open(tmp_path / "all" / f"drive_{name}.gif") as gif:
            assert gif.n_frames == sum(r.metadata["sensor"] == name for r in recs) == 2
            assert gif.info["duration"] == 50
    (tmp_path / "all" / "drive_my notes.gif").write_bytes(b"GIF89a")  # the user's
    assert main([*base, str(tmp_path / "all"), "--sensor", "front"]) == 0
    gifs = sorted(p.name for p in (tmp_path / "all").glob("*.gif"))
    assert gifs == ["drive.gif", "drive_my notes.gif"]


WALL_X = 2.0
RIG_TOML = """
[body]
pose = {{ position_m = [0, 0, 0.5] }}
[rig]
rate_hz = 20
crosstalk = false
[[sensors]]
name = "a"
array = "urtis_v1"
direct_path = {direct}
mount = {{ position_m = [0.1, 0.2, 0.0] }}
[[sensors]]
name = "b"
array = "urtis_v1"
direct_path = {direct}
mount = {{ position_m = [{bx}, -0.2, 0.0], rotation_deg = [0, 0, -20] }}
firing = {{ rate_hz = 20, offset_s = 0.025, count = 2 }}
"""
#: the wall before the rig (reflection and diffuse: its material's)
WALL_TOML = """
[simulation]
max_range_m = 3.0
absorption = false
diffraction = {{ enabled = false }}
[[materials]]
name = "wall"
reflection = {reflection}
diffuse = {diffuse}
[[meshes]]
file = "wall.obj"
material = "wall"
"""


def rig_files(tmp, *, reflection=0.7, diffuse=0.0, bx=0.3, direct="true", simulate=True):
    """A rig scene file (sonar b `bx` m ahead of the body's origin, turned 20° right,
    2 firings; a wall at x = 2 m) and its recordings (crosstalk off); start.toml: the
    same with a wall of reflection 0.4."""
    wall = trimesh.creation.box(extents=(0.1, 8.0, 4.0))
    wall.apply_translation([WALL_X + 0.05, 0, 0.5])
    wall.export(tmp / "wall.obj")
    kw = {"diffuse": diffuse, "bx": bx, "direct": direct}
    (tmp / "rig.toml").write_text((RIG_TOML + WALL_TOML).format(reflection=reflection, **kw))
    (tmp / "start.toml").write_text((RIG_TOML + WALL_TOML).format(reflection=0.4, **kw))
    from acousim.scene import load_scene

    if not simulate:
        return None
    recs = RigSimulator(load_scene(tmp / "rig.toml")).run().recordings
    P.save_recordings(tmp / "rig_recs.h5", list(recs))
    return tmp / "rig_recs.h5"


def test_compare_takes_a_rigs_sonar(tmp_path, capsys):
    """Sonar b's second firing against the rig scene's b alone: its wall echo where
    b's mount puts it (the wall 2 m ahead, b 0.3 m ahead of the body and turned 20°
    right: the wall's normal 1.7 m away, 20° to b's left)."""
    from acousim.cli import main

    recs = rig_files(tmp_path)
    args = ["compare", str(recs), "--scene", str(tmp_path / "rig.toml"), "--method", "das"]
    assert main(args) != 0  # a rig: which sonar?
    assert "--sensor" in (err := capsys.readouterr().err) and "(a, b)" in err
    out = tmp_path / "cmp"
    assert main([*args, "--sensor", "b", "--index", "1", "--pose", "1", "--out", str(out)]) == 0
    import json

    report = json.loads((out / "comparison.json").read_text())
    (echo,) = report["images"]["das"]["matched"]
    bin_m = report["images"]["das"]["range_bin_m"]
    assert echo["sim"]["range_m"] == pytest.approx(WALL_X - 0.3, abs=bin_m)
    assert echo["sim"]["azimuth_deg"] == pytest.approx(20, abs=2)  # the imaging step
    assert abs(echo["d_range_m"]) < 1e-9 and abs(echo["d_level_db"]) < 0.01  # b's own
    # a rig's file against a rig's file: b's firings paired with b's
    sim = ["compare", str(recs), "--sim", str(recs), "--all", "--method", "das"]
    assert main([*sim, "--sensor", "b"]) == 0
    assert "2 poses: mean envelope correlation 1.00" in capsys.readouterr().out
    assert main([*sim, "--sensor", "c"]) != 0 and "(a, b)" in capsys.readouterr().err


def test_calibrate_fits_a_rigs_sonar_with_its_mount_fixed(tmp_path, capsys):
    """Sonar b's two firings of a wall of reflection 0.7 (diffuse 0.35: a purely
    specular wall leaves the fit too little to hold on to), fitted from a start of
    0.4: the wall's reflection back, b's mount as declared in the fitted file."""
    from acousim.cli import main
    from acousim.scene import load_scene

    recs = rig_files(tmp_path, reflection=0.7, diffuse=0.35)
    args = ["calibrate", str(recs), "--scene", str(tmp_path / "start.toml")]
    args += ["--out", str(tmp_path / "fitted.toml"), "--param", "wall.reflection"]
    assert main(args) != 0 and "--sensor" in capsys.readouterr().err
    assert main([*args, "--sensor", "b"]) == 0
    assert "2/2 poses" in capsys.readouterr().err  # b's two firings, not the rig's four
    fitted = load_scene(tmp_path / "fitted.toml")
    assert fitted.materials["wall"].reflection == pytest.approx(0.7, abs=0.02)
    b = fitted.rig.sonars[1].mount
    np.testing.assert_allclose(b.position_m, [0.3, -0.2, 0.0], atol=1e-12)
    assert np.rad2deg(b.yaw_rad) == pytest.approx(-20, abs=1e-12)


SPEC = """
[dataset]
samples = 4
shard_size = 4
seed = 5
[[scenes]]
file = "rig.toml"
sensor = "b"
mount = { x = [0.0, 0.6], yaw_deg = [-10.0, 10.0] }
[store]
raw = true
snapshot = false
images = []
depth_map = false
"""


def _arrival(signal, call, fs, after):
    """The delay (s) of the strongest copy of `call` in `signal` arriving `after` s or
    later (matched filter envelope peak, parabolic interpolation)."""
    import scipy.signal

    mf = scipy.signal.correlate(signal, call, mode="full")[call.size - 1 :]
    env = np.abs(scipy.signal.hilbert(mf, 2 * mf.size))[: mf.size]  # padded: not circular
    skip = int(after * fs)
    i = skip + int(np.argmax(env[skip:]))
    a, b, c = env[i - 1], env[i], env[i + 1]
    return (i + 0.5 * (a - c) / (a - 2 * b + c)) / fs


def test_a_dataset_samples_a_rigs_mount(tmp_path):
    """Sonar b's mount drawn per sample (x in [0, 0.6] m, yaw in [-10, 10]°): in the
    sample's parameters, and its wall echo where that mount puts it (the
    mirror-image path from b's emitter to each microphone, the wall at x = 2 m)."""
    from acousim.dataset import DatasetReader, generate

    rig_files(tmp_path, reflection=1.0, direct="false")  # the wall's echo alone
    (tmp_path / "spec.toml").write_text(SPEC)
    generate(tmp_path / "spec.toml", tmp_path / "data")
    data = DatasetReader(tmp_path / "data")
    from acousim.scene import load_scene

    sensor = load_scene(tmp_path / "rig.toml").rig.sonars[1].sensor
    array, call = P.preset("urtis_v1"), sensor.call
    xs = []
    for i in range(4):
        sample = data[i]
        assert sample["raw"].shape[0] == 30
        p = sample["params"]
        x, y, z = p["mount"]["position_m"]
        roll, pitch, yaw = p["mount"]["rotation_deg"]
        assert p["sensor"] == "b" and 0 <= x <= 0.6 and -10 <= yaw <= 10
        assert (y, z, roll, pitch) == (-0.2, 0.0, 0.0, 0.0)  # as the rig declares them
        # crosstalk off: every path carries b's own call (b: the rig's second sonar)
        assert p["emitters"] == ["a", "b"] and set(sample["labels/emitter"].tolist()) == {1}
        xs.append(x)
        body = np.array([0.0, 0.0, 0.5])
        np.testing.assert_allclose(p["pose"]["position_m"], body + [x, y, z], atol=1e-12)
        assert p["pose"]["yaw_deg"] == pytest.approx(yaw, abs=1e-9)
        R = rotation_zyx(np.deg2rad(yaw))
        emitter = body + [x, y, z] + R @ array.emitter_m
        image = emitter * [-1, 1, 1] + [2 * WALL_X, 0, 0]  # mirrored in the wall
        fs, c = 450e3, p["speed_of_sound_m_s"]
        for m in range(0, 30, 3):
            mic = body + [x, y, z] + R @ array.positions_m[m]
            expected = np.linalg.norm(image - mic) / c
            got = _arrival(sample["raw"][m], call.sampled(fs), fs, after=0.0)
            assert got == pytest.approx(expected, abs=0.01e-6), (i, m)
    assert np.ptp(xs) > 0.1  # the mount moved between samples


@pytest.mark.parametrize(
    "scene_keys, key, words",
    [
        ("", "scenes[0].sensor", "rig of 2 sonar(s) (a, b)"),
        ('sensor = "c"', "scenes[0].sensor", "rig of 2 sonar(s) (a, b)"),
        ('sensor = "b"\nmount = { x = [0.5, 0.1] }', "scenes[0].mount.x", "low is above high"),
        ('sensor = "b"\nmount = { heading = [0, 1] }', "scenes[0].mount", "heading"),
    ],
)
def test_a_dataset_spec_of_a_rig_names_its_key(tmp_path, scene_keys, key, words):
    from acousim.dataset import load_spec
    from acousim.dataset.spec import SpecError

    rig_files(tmp_path, simulate=False)
    (tmp_path / "spec.toml").write_text(f'[[scenes]]\nfile = "rig.toml"\n{scene_keys}\n')
    with pytest.raises(SpecError) as err:
        load_spec(tmp_path / "spec.toml")
    assert err.value.key.startswith(key) and words in str(err.value)


def test_sensor_and_mount_are_only_for_a_rigs_scene(tmp_path):
    from acousim.dataset import load_spec
    from acousim.dataset.spec import SpecError

    (tmp_path / "one.toml").write_text("[sensor]\n[[points]]\nposition_m = [1, 0, 0]\n")
    (tmp_path / "spec.toml").write_text('[[scenes]]\nfile = "one.toml"\nsensor = "b"\n')
    with pytest.raises(SpecError, match=r"scenes\[0\].sensor: only for a rig's scene"):
        load_spec(tmp_path / "spec.toml")


def test_every_lidar_of_the_rig_scans_from_its_mount(rig_recordings):
    """Each firing carries both LiDARs' scans (through the recording file), each
    mounted where the rig declares it, and each sees the wall at its own distance:
    the nearest return of the LiDAR 0.3 m further forward is 0.3 m closer (the
    wall's face at x = 2 m, the body driving 0.5 m/s: the nearest points of a scan
    lie within the 0.05 m it drives in one 0.1 s rotation)."""
    _, recs = rig_recordings
    for rec, (name, pos, rot, _, _) in zip(recs, SONARS * 2):
        assert rec.metadata["sensor"] == name and len(rec.lidars) == 2
        for scan, (lpos, lrot) in zip(rec.lidars, LIDARS):
            # LiDAR -> sonar, carried to the body by the sonar's mount
            np.testing.assert_allclose(
                mount(pos, rot) @ scan.to_sensor, mount(lpos, lrot), atol=1e-9
            )
        nearest = [np.linalg.norm(s.points_m, axis=1).min() for s in rec.lidars]
        assert nearest[0] - nearest[1] == pytest.approx(0.3, abs=0.06)
        x_body = SPEED * rec.metadata["emission_time_s"]
        assert 2.0 - x_body - 0.06 < nearest[0] < 2.0 - x_body + 0.01
    # the two LiDARs' range noise is drawn apart (their own seeds)
    assert not np.array_equal(recs[0].lidars[0].points_m[:50], recs[0].lidars[1].points_m[:50])


def test_the_bag_has_a_topic_per_lidar(rig_recordings, tmp_path):
    """The ROS 2 bag of the rig's file: each LiDAR's scan on its own topic, in the
    frame of the sonar whose firing it started at, its points moved by the mounts."""
    pytest.importorskip("rosbags", reason="rosbags not installed (pip install 'acousim[ros]')")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from acousim.cli import main

    tmp, recs = rig_recordings
    bag = tmp_path / "bag"
    assert main(["export", str(tmp / "rig.h5"), "--out", str(bag), "--method", "das"]) == 0
    seen: dict[str, list] = {"/acousim/lidar": [], "/acousim/lidar_01": []}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for conn, _, raw in reader.messages():
            if conn.topic in seen:
                seen[conn.topic].append(reader.deserialize(raw, conn.msgtype))
    for n, msgs in enumerate(seen.values()):
        assert len(msgs) == len(recs)
        for msg, rec in zip(msgs, recs):
            assert msg.header.frame_id == rec.metadata["sensor"]
            raw = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.width, msg.point_step)
            xyz = raw[:, :12].copy().view("<f4").reshape(-1, 3)
            scan = rec.lidars[n]  # LiDAR frame -> the sonar's, by hand
            want = scan.points_m @ scan.to_sensor[:3, :3].T + scan.to_sensor[:3, 3]
            np.testing.assert_allclose(xyz, want, atol=1e-5)


XT_TOML = """
[body]
pose = {{ position_m = [0, 0, 0.5] }}
[rig]
crosstalk = {crosstalk}
[[sensors]]
name = "a"
array = "urtis_v1"
mount = {{ position_m = [0.1, 0.2, 0.0] }}
firing = {{ rate_hz = 20, offset_s = 0.005, count = 2 }}
[[sensors]]
name = "b"
array = "urtis_v1"
mount = {{ position_m = [0.3, -0.2, 0.0], rotation_deg = [0, 0, -20] }}
firing = {{ rate_hz = 20, offset_s = 0.0, count = 2 }}
"""


def test_compare_simulates_a_rigs_sonar_with_the_others_calls(tmp_path, capsys):
    """compare --sensor b of a rig with crosstalk (b firing at 0 and 50 ms, a 5 ms
    after each, a wall 2 m ahead): b's simulated firings hold a's call, its direct
    path at 5 ms + |e_a - m_b| / c at each of b's microphones (the mounts written out
    here); the same firings simulated without crosstalk do not match recordings that
    have it (its echo unmatched, the gain fitted to a's call)."""
    from acousim.cli import main
    from acousim.compare.inputs import pair_with_rig
    from acousim.scene import load_scene

    rig_files(tmp_path, simulate=False)  # the wall
    for on in ("true", "false"):
        toml = (XT_TOML + WALL_TOML).format(crosstalk=on, reflection=0.7, diffuse=0.0)
        (tmp_path / f"xt_{on}.toml").write_text(toml)
    scene = load_scene(tmp_path / "xt_true.toml")
    reals = RigSimulator(scene).run().of("b")
    P.save_recordings(tmp_path / "b.h5", reals)
    ((_, sim),) = pair_with_rig(reals, scene, "b", pose=1)
    assert list(sim.truth.emitter).count("a") == 2  # a's direct path and wall echo
    c, fs = scene.environment.speed_of_sound_m_s, sim.sample_rate_hz
    emitter_a = np.array([0.1, 0.2, 0.0]) + P.preset("urtis_v1").emitter_m  # a: no turn
    mics_b = sim.array.positions_m @ rotation_zyx(np.deg2rad(-20), 0, 0).T + [0.3, -0.2, 0]
    want = 0.005 + np.linalg.norm(mics_b - emitter_a, axis=1) / c  # s after b's emission
    env = np.abs(P.matched_filter(sim.samples, sim.waveform.sampled(fs)))
    lo, hi = sim.emission_index + int(0.004 * fs), sim.emission_index + int(0.008 * fs)
    got = (lo + np.argmax(env[:, lo:hi], axis=1) - sim.emission_index) / fs
    np.testing.assert_allclose(got, want, atol=1.5 / fs)
    # the command line: b's firings simulated with a's calls, as the recordings hold them
    args = ["compare", str(tmp_path / "b.h5"), "--sensor", "b", "--all", "--method", "das"]
    out = ["--out", str(tmp_path / "cmp")]
    import json

    rows = {}
    for on in ("true", "false"):
        assert main([*args, "--scene", str(tmp_path / f"xt_{on}.toml"), *out]) == 0
        rows[on] = json.loads((tmp_path / "cmp" / "summary.json").read_text())["rows"]
    # with the crosstalk: no gain to fit, the one echo matched; without it the real
    # recordings' stronger signal (a's call) is fitted as gain and the echo missed
    assert [r["gain"] for r in rows["true"]] == pytest.approx([1.0, 1.0], abs=1e-6)
    assert [r["das_matched"] for r in rows["true"]] == [1, 1]
    assert all(r["gain"] > 1.2 and r["das_only_real"] == 1 for r in rows["false"])


def test_a_dataset_sample_of_a_rig_hears_the_other_sonars(tmp_path):
    """A rig with crosstalk (XT_TOML: a fires 5 ms after b), sonar b's mount drawn
    per sample: each sample holds a's call, its direct path at 5 ms + |e_a - m_b| / c
    at b's microphones on the mount drawn (written out here)."""
    from acousim.dataset import DatasetReader, generate

    rig_files(tmp_path, simulate=False)  # the wall
    toml = (XT_TOML + WALL_TOML).format(crosstalk="true", reflection=0.7, diffuse=0.0)
    (tmp_path / "rig.toml").write_text(toml)
    (tmp_path / "spec.toml").write_text(SPEC.replace("samples = 4", "samples = 2"))
    generate(tmp_path / "spec.toml", tmp_path / "data")
    data = DatasetReader(tmp_path / "data")
    array, call = P.preset("urtis_v1"), P.rtis_call("default_25_50")
    body = np.array([0.0, 0.0, 0.5])
    emitter_a = body + [0.1, 0.2, 0.0] + array.emitter_m
    for i in range(2):
        sample = data[i]
        p = sample["params"]
        (x, y, z), yaw = p["mount"]["position_m"], p["mount"]["rotation_deg"][2]
        R = rotation_zyx(np.deg2rad(yaw))
        fs, c = 450e3, p["speed_of_sound_m_s"]
        for m in range(0, 30, 5):
            mic = body + [x, y, z] + R @ array.positions_m[m]
            expected = 0.005 + np.linalg.norm(emitter_a - mic) / c
            got = _arrival(sample["raw"][m], call.sampled(fs), fs, after=0.004)
            # b's own direct path (its emitter millimetres from its microphones, 5
            # orders stronger) leaves a floor 13 dB under a's call at -72 dB of
            # itself: the envelope peak within 1.5 samples
            assert got == pytest.approx(expected, abs=1.5 / fs), (i, m)
        # whose call each path carries: an index into the rig's sonars (XT_TOML's
        # order); the direct paths: b's own at |e_b - centre_b| / c, a's 5 ms later at
        # |e_a - centre_b| / c (centre: the array's centroid, on b's mount)
        assert p["emitters"] == ["a", "b"]
        emitter, order = sample["labels/emitter"], sample["labels/order"]
        assert set(emitter.tolist()) == {0, 1}
        centre_b = body + [x, y, z] + R @ array.positions_m.mean(axis=0)
        emitter_b = body + [x, y, z] + R @ array.emitter_m
        for k, want in (
            (0, 0.005 + np.linalg.norm(emitter_a - centre_b) / c),
            (1, np.linalg.norm(emitter_b - centre_b) / c),
        ):
            direct = sample["labels/delay_s"][(emitter == k) & (order == 0)]
            assert direct == pytest.approx([want], abs=1e-7), (i, k)
