"""CHIRP files (processing.formats.chirp.write): written, then read three ways: by a small reader
written here from the format's documentation (chirppy's README: sensors under
/sensors, 4x4 `to_origin` transforms, signals (N, samples, channels) float32,
LiDAR points (N, max_points, 4) NaN-padded, odometry position + [x, y, z, w]
orientation), by chirppy itself (an optional test dependency) and by ours."""

import json
import shutil

import h5py
import numpy as np
import pytest

import processing as P
from acousim.bundled import resolve
from acousim.scene import load_scene
from acousim.simulator import Simulator
from processing.formats.chirp.write import ChirpFileError
from tests.oracles.analytic import echo_recording, rotation_zyx


@pytest.fixture(scope="module")
def corridor(tmp_path_factory):
    """Three corridor poses (a trajectory: poses, motion, ground truth) as our file."""
    scene = load_scene(resolve("scenes", "corridor"))
    recs = Simulator(scene).run([0, 1, 2])
    path = tmp_path_factory.mktemp("chirp") / "corridor.h5"
    P.save_recordings(path, recs)
    return P.load_recordings(path)  # float32, as a file holds them


@pytest.fixture(scope="module")
def exported(corridor, tmp_path_factory):
    path = tmp_path_factory.mktemp("chirp") / "corridor_chirp.h5"
    P.write_chirp(path, corridor)
    return path


def _quat_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def test_independent_reader(corridor, exported):
    """Every documented field read with h5py alone."""
    with h5py.File(exported, "r") as f:
        assert f.attrs["format"] == "chirp"
        assert f.attrs["n_reference_captures"] == 3
        ref = f.attrs["reference_sensor"]
        ac = f[f"sensors/{ref}"]
        assert ac.attrs["sensor_type"] == "acoustic_sensor"
        sig = ac["data/signals"]
        assert sig.dtype == np.float32 and sig.shape == (3, corridor[0].n_samples, 30)
        for k, rec in enumerate(corridor):
            np.testing.assert_array_equal(sig[k].T, rec.samples)
        np.testing.assert_array_equal(
            ac["calibration/receiver_relative_translations"][()], corridor[0].array.positions_m
        )
        assert ac.attrs["sample_rate_hz"] == 450e3
        t = ac["data/timestamps"][()]
        assert np.all(np.diff(t) > 0)
        np.testing.assert_allclose(np.diff(t), 0.1, atol=1e-12)  # the drive's 10 Hz
        tx = f["sensors/acoustic_transmitter_00"]
        np.testing.assert_allclose(tx["calibration/to_origin"][:3, 3], [0, 0, -0.012])
        call = tx["data/signals"][()]
        assert call.size == int(np.ceil(2.5e-3 * 450e3))  # the 2.5 ms RTIS call
        odo = f["sensors/odometry_00/data"]
        for k, rec in enumerate(corridor):
            p = rec.metadata["pose"]
            np.testing.assert_allclose(odo["position"][k], p["position_m"], atol=1e-12)
            R = rotation_zyx(*np.deg2rad([p["yaw_deg"], p["pitch_deg"], p["roll_deg"]]))
            np.testing.assert_allclose(_quat_matrix(odo["orientation"][k]), R, atol=1e-12)
            assert np.isclose(odo["yaw"][k], np.deg2rad(p["yaw_deg"]))
            v = rec.metadata["motion"]["velocity_m_s"]
            np.testing.assert_allclose(R @ odo["linear_velocity"][k], v, atol=1e-12)
        ground = f["transforms/ground_to_origin"][()]
        np.testing.assert_allclose(ground[:3, 3], [0, 0, -0.45])  # the robot's 0.45 m
        ours = f["acousim"]
        truth = ours["recordings/000001/truth"]
        np.testing.assert_array_equal(
            truth["position_world_m"][()], corridor[1].truth.position_world_m
        )
        meta = json.loads(ours["recordings/000002/metadata"][()])
        assert meta["pose_index"] == 2


def test_chirppy_reads_it(corridor, exported):
    chirppy = pytest.importorskip(
        "chirppy", reason="cosys-chirppy not installed (pip install cosys-chirppy)"
    )
    with chirppy.CHIRPDataset(exported) as ds:
        assert ds.format == "chirp" and len(ds) == 3
        ac = ds.get_acoustic_sensor(0)
        for k, rec in enumerate(corridor):
            x = ac[k]["signals"]
            assert x.dtype == np.float32
            assert np.abs(x.T - rec.samples).max() <= 1e-6 * np.abs(rec.samples).max()
        np.testing.assert_allclose(
            ac.get_receiver_relative_translations(), corridor[0].array.positions_m
        )
        assert np.all(np.diff(ds.reference_timestamps) > 0)
        # consistent transforms: the transmitter seen from the array and back
        T = ds.get_transform("acoustic_transmitter_00", "acoustic_sensor_00")
        np.testing.assert_allclose(T[:3, 3], corridor[0].array.emitter_m)
        np.testing.assert_allclose(
            T @ ds.get_transform("acoustic_sensor_00", "acoustic_transmitter_00"), np.eye(4)
        )
        up = ds.get_transform("acoustic_sensor_00", "ground")
        np.testing.assert_allclose(up[:3, 3], [0, 0, 0.45])
        odo = ds.get_odometry(0)
        for k, rec in enumerate(corridor):
            p = rec.metadata["pose"]
            np.testing.assert_allclose(odo.get_pose_matrix(k)[:3, 3], p["position_m"])
            R = rotation_zyx(np.deg2rad(p["yaw_deg"]), 0, 0)
            np.testing.assert_allclose(odo.get_pose_matrix(k)[:3, :3], R, atol=1e-12)
        tx = ds.get_acoustic_transmitter(0)
        assert tx.get_emitted_signal().size == 1125
        # every sensor's reader at a reference capture (what its data loader does)
        sample = ds[1]
        assert set(sample) == {"acoustic_sensor_00", "acoustic_transmitter_00", "odometry_00"}
        assert sample["odometry_00"]["timestamp"] == sample["acoustic_transmitter_00"]["timestamp"]


def test_ours_reads_it_back(corridor, exported):
    back = P.load_recordings(exported)
    assert P.count_recordings(exported) == 3 and len(back) == 3
    for a, b in zip(corridor, back):
        np.testing.assert_array_equal(a.samples, b.samples)
        assert a.waveform == b.waveform and a.metadata == b.metadata
        assert a.emission_index == b.emission_index
        assert a.speed_of_sound_m_s == b.speed_of_sound_m_s
        np.testing.assert_array_equal(a.truth.velocity_world_m_s, b.truth.velocity_world_m_s)
        np.testing.assert_array_equal(a.truth.kind, b.truth.kind)
    one = P.load_recording(exported, 2)
    np.testing.assert_array_equal(one.samples, corridor[2].samples)


def test_same_image(tmp_path):
    """A recording and its CHIRP copy give the same image (bit for bit: float32 both)."""
    rec = echo_recording(P.urtis_v1(), [(20, 5, 1.5, 1.0)], fs=450e3, n_samples=6000,
                         waveform=P.rtis_call(), emission_index=40)  # fmt: skip
    P.save_recording(tmp_path / "r.h5", rec)
    P.write_chirp(tmp_path / "c.h5", [P.load_recording(tmp_path / "r.h5")])
    a = P.acoustic_image(P.load_recording(tmp_path / "r.h5"))
    b = P.acoustic_image(P.load_recording(tmp_path / "c.h5"))
    np.testing.assert_array_equal(a.power, b.power)
    np.testing.assert_array_equal(a.range_m, b.range_m)


def test_foreign_file(tmp_path):
    """A CHIRP file without our group: call fitted to the transmitter's samples, the
    emission from the two timestamps, poses from odometry via base_link."""
    rec = echo_recording(P.urtis_v1(), [(-30, 0, 2.0, 1.0)], fs=450e3, n_samples=7000,
                         waveform=P.rtis_call("default_20_80"), emission_index=25)  # fmt: skip
    rec = P.Recording(rec.samples.astype(np.float32), rec.sample_rate_hz, rec.array, rec.waveform,
                      343.0, 25, {"pose": {"position_m": [1.0, 2.0, 0.3], "yaw_deg": 30.0,
                      "pitch_deg": 0.0, "roll_deg": 0.0, "time_s": 5.0}})  # fmt: skip
    path = tmp_path / "f.h5"
    P.write_chirp(path, [rec], start_time_s=1.7e9)
    with h5py.File(path, "a") as f:
        del f["acousim"]
        # a robot whose base_link is 0.2 m behind the array: the odometry moves with it
        link = np.eye(4)
        link[0, 3] = -0.2  # base_link origin in the array frame
        f["transforms/base_link_to_origin"][...] = link
        odo = f["sensors/odometry_00/data/position"]
        yaw = np.deg2rad(30)
        odo[0] = np.array([1.0, 2.0, 0.3]) - 0.2 * np.array([np.cos(yaw), np.sin(yaw), 0])
    back = P.load_recording(path)
    wf = back.waveform
    assert wf.kind == "hyperbolic"
    assert abs(wf.f_start_hz - 80e3) < 80 and abs(wf.f_end_hz - 20e3) < 20
    assert abs(wf.duration_s - 2.5e-3) < 1 / 450e3 and wf.taper == 0.1
    assert back.emission_index == 25
    assert back.metadata["timestamp"] == pytest.approx(1.7e9 + 5.0, abs=1e-6)
    np.testing.assert_allclose(back.metadata["pose"]["position_m"], [1.0, 2.0, 0.3], atol=1e-9)
    assert back.metadata["pose"]["yaw_deg"] == pytest.approx(30.0)
    a, b = P.acoustic_image(rec), P.acoustic_image(back)
    assert np.unravel_index(a.power.argmax(), a.power.shape) == np.unravel_index(
        b.power.argmax(), b.power.shape
    )
    # a transmitter signal stored with 10 leading zeros: the call starts 10 samples
    # after the transmitter's timestamp
    with h5py.File(path, "a") as f:
        d = f["sensors/acoustic_transmitter_00/data/signals"]
        x = np.concatenate([np.zeros(10, np.float32), d[()]])
        del f["sensors/acoustic_transmitter_00/data/signals"]
        f["sensors/acoustic_transmitter_00/data/signals"] = x
        f["sensors/acoustic_transmitter_00/data/timestamps"][0] -= 10 / 450e3
    assert P.load_recording(path).emission_index == 25


def test_what_it_lacks(tmp_path, corridor, exported):
    path = tmp_path / "bare.h5"
    shutil.copy(exported, path)
    with h5py.File(path, "a") as f:
        del f["acousim"], f["sensors/acoustic_transmitter_00"]
    with pytest.raises(ChirpFileError, match="--call"):
        P.load_recording(path)
    rec = P.load_recording(path, call=P.rtis_call())
    assert rec.waveform == P.rtis_call() and rec.metadata["emitter_assumed_at_origin"]
    with h5py.File(path, "a") as f:
        f["sensors/acoustic_sensor_00"].attrs.pop("sample_rate_hz")
    with pytest.raises(ChirpFileError, match="sample_rate_hz"):
        P.load_recording(path, call=P.rtis_call())
    with h5py.File(path, "a") as f:
        noise = np.random.default_rng(0).standard_normal(500).astype(np.float32)
        f.create_dataset("sensors/acoustic_transmitter_00/data/signals", data=noise)
        f["sensors/acoustic_sensor_00"].attrs["sample_rate_hz"] = 450e3
    with pytest.raises(ChirpFileError, match="not a linear or hyperbolic sweep"):
        P.load_recording(path)
    assert P.load_recording(path, call=P.paper_chirp()).waveform == P.paper_chirp()


def test_refuses_mixed_recordings(tmp_path, corridor):
    short = corridor[0].with_samples(corridor[0].samples[:, :1000])
    with pytest.raises(ChirpFileError, match="length"):
        P.write_chirp(tmp_path / "x.h5", [corridor[0], short])
    assert not (tmp_path / "x.h5").exists()


def test_measurements_and_synthetic_times(tmp_path):
    """A (K, M, T) recording becomes K captures and comes back whole; recordings
    without times get evenly spaced ones."""
    rec = echo_recording(P.urtis_v1(), [(0, 0, 1.0, 1.0)], fs=450e3, n_samples=3000,
                         waveform=P.rtis_call())  # fmt: skip
    x = np.stack([rec.samples, 2 * rec.samples, 3 * rec.samples]).astype(np.float32)
    rec3 = rec.with_samples(x)
    path = tmp_path / "k.h5"
    P.write_chirp(path, [rec3, rec.with_samples(x[0])], period_s=0.05)
    with h5py.File(path, "r") as f:
        assert f["sensors/acoustic_sensor_00/data/signals"].shape == (4, 3000, 30)
        np.testing.assert_allclose(
            f["sensors/acoustic_transmitter_00/data/timestamps"][()], [0, 0.05, 0.1, 0.15]
        )
        assert f["acousim"].attrs["timestamps_synthetic"]
        assert "sensors/odometry_00" not in f  # no poses
    back = P.load_recordings(path)
    np.testing.assert_array_equal(back[0].samples, x)
    np.testing.assert_array_equal(back[1].samples, x[0])


def test_damaged_capture(tmp_path, exported):
    path = tmp_path / "d.h5"
    shutil.copy(exported, path)
    with h5py.File(path, "a") as f:
        f["sensors/acoustic_sensor_00/data/signals"][1, 100, 3] += 1.0
    P.load_recording(path, 0)  # the others are intact
    with pytest.raises(ChirpFileError, match="checksum"):
        P.load_recording(path, 1)


def _signals_2d(f):
    x = f["sensors/acoustic_sensor_00/data/signals"][0]
    del f["sensors/acoustic_sensor_00/data/signals"]
    f["sensors/acoustic_sensor_00/data/signals"] = x


def _mics_short(f):
    g = f["sensors/acoustic_sensor_00/calibration"]
    x = g["receiver_relative_translations"][:-1]
    del g["receiver_relative_translations"]
    g["receiver_relative_translations"] = x


def _mics_twice(f):
    d = f["sensors/acoustic_sensor_00/calibration/receiver_relative_translations"]
    d[1] = d[0]


def _no_calibration(f):
    del f["sensors/acoustic_sensor_00/calibration"]


def _bad_transform(f):
    f["sensors/acoustic_transmitter_00/calibration/to_origin"][0, 0] = 2.0


def _nan_sample(f):
    f["sensors/acoustic_sensor_00/data/signals"][0, 5, 5] = np.nan


@pytest.mark.parametrize(
    "damage, key, words",
    [
        (_signals_2d, "data/signals", "expected 3 dimensions"),
        (_mics_short, "receiver_relative_translations", "must be finite (30, 3) metres"),
        (_mics_twice, "receiver_relative_translations", "two microphones at the same position"),
        (_no_calibration, "receiver_relative_translations", "missing"),
        (_bad_transform, "to_origin", "rigid 4x4 transform"),
        (_nan_sample, "data/signals", "NaN or infinite"),
    ],
)
def test_refusals_name_the_field(tmp_path, exported, damage, key, words):
    path = tmp_path / "bad.h5"
    shutil.copy(exported, path)
    with h5py.File(path, "a") as f:
        del f["acousim"]  # a file not of ours: every field read from CHIRP's own
        damage(f)
    with pytest.raises(ChirpFileError) as err:
        P.load_recording(path)
    assert str(path) in str(err.value) and key in str(err.value) and words in str(err.value)


def test_array_calibration_travels(tmp_path):
    """A calibration carried to be applied on loading (processing.sensor.calibration) is
    applied when the CHIRP copy is loaded, as for a recording file."""
    rec = echo_recording(P.urtis_v1(), [(0, 0, 1.0, 1.0)], fs=450e3, n_samples=3000,
                         waveform=P.rtis_call())  # fmt: skip
    cal = P.ArrayCalibration(gain_db=np.linspace(-3, 3, 30), phase_rad=np.zeros(30))
    carried = P.attach_calibration(rec.with_samples(rec.samples.astype(np.float32)), cal)
    P.save_recording(tmp_path / "r.h5", carried)
    P.write_chirp(tmp_path / "c.h5", [carried])
    a, b = P.load_recording(tmp_path / "r.h5"), P.load_recording(tmp_path / "c.h5")
    assert b.metadata["array_calibration"]["applied"] is True
    assert not np.allclose(b.samples, carried.samples)  # corrected on loading
    np.testing.assert_allclose(a.samples, b.samples, atol=1e-6 * np.abs(a.samples).max())


@pytest.mark.parametrize(
    "call, tol",
    [
        (P.rtis_call("default_25_50"), 1e-6),
        (P.linear_chirp(30e3, 90e3, 2e-3, 0.2), 1e-6),
        (P.paper_chirp(), 5e-4),  # untapered: the analytic signal rings at the edges
    ],
)
def test_fit_sweep(call, tol):
    """A call known only as samples (padded with zeros, its phase turned by 40 degrees,
    as another device may store it) is recognised: kind, band, duration, taper."""
    from scipy.signal import hilbert

    from processing.sensor.calls import fit_sweep

    z = hilbert(call.sampled(450e3))
    x = np.concatenate([np.zeros(37), np.real(z * np.exp(1j * np.deg2rad(40))), np.zeros(11)])
    fit, corr, start = fit_sweep(x, 450e3)
    assert start == 37
    assert fit.kind == call.kind and fit.taper == call.taper and corr > 0.999
    assert abs(fit.f_start_hz / call.f_start_hz - 1) < tol
    assert abs(fit.f_end_hz / call.f_end_hz - 1) < tol
    assert abs(fit.duration_s - call.duration_s) <= 1 / 450e3
