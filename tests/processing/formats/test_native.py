"""The recording file: round trips, float32 error bound, ground truth as datasets,
order past 9,999, lazy reading, schema 1 files, and a corrupted-file test per field."""

import dataclasses
import json
import re

import h5py
import numpy as np
import pytest

import processing as P
from processing.base.errors import InputError


def make(shape=(64, 100), k=None, truth=None):
    rng = np.random.default_rng(3)
    s = rng.standard_normal(shape if k is None else (k, *shape))
    return P.Recording(
        s,
        500e3,
        P.paper_8x8(),
        P.paper_chirp(),
        343.2,
        7,
        {"seed": 3, "simulated": True, "pose": {"position_m": [1.0, 2.0, 0.0], "yaw_deg": 10.0}},
        truth,
    )


def truth(n=5):
    rng = np.random.default_rng(1)
    pw = rng.uniform(-3, 3, (n, 3))
    return P.GroundTruth(
        pw, pw - 1.0, rng.uniform(0, 1, n), np.arange(n) % 3, ["direct"] + ["specular"] * (n - 1)
    )


def test_hdf5_round_trip_is_exact_in_float64(tmp_path):
    recs = [make(truth=truth()), make(k=3)]
    path = P.save_recordings(tmp_path / "r.h5", recs, dtype=np.float64, compression="gzip")
    back = P.load_recordings(path)
    assert len(back) == 2
    for a, b in zip(recs, back):
        np.testing.assert_array_equal(a.samples, b.samples)
        assert a.samples.dtype == b.samples.dtype
        np.testing.assert_array_equal(a.array.positions_m, b.array.positions_m)
        np.testing.assert_array_equal(a.array.grid_index, b.array.grid_index)
        assert a.array.pitch_m == b.array.pitch_m and a.array.name == b.array.name
        assert a.waveform == b.waveform
        assert (a.sample_rate_hz, a.speed_of_sound_m_s, a.emission_index) == (
            b.sample_rate_hz,
            b.speed_of_sound_m_s,
            b.emission_index,
        )
        assert a.metadata == b.metadata
    assert back[1].n_measurements == 3 and back[1].truth is None
    t, u = recs[0].truth, back[0].truth
    for name in ("position_world_m", "position_sensor_m", "amplitude", "order", "kind"):
        np.testing.assert_array_equal(getattr(t, name), getattr(u, name))


def test_float32_by_default_within_its_rounding_bound(tmp_path):
    rec = make()
    back = P.load_recording(P.save_recording(tmp_path / "r.h5", rec))
    assert back.samples.dtype == np.float32
    rel = np.abs(back.samples - rec.samples) / np.abs(rec.samples)
    assert rel.max() <= 2.0**-24  # round to nearest: half an ulp of a 24-bit significand
    with h5py.File(tmp_path / "r.h5") as f:
        d = f["recordings/000000/samples"]
        assert d.chunks == (1, 100) and d.fletcher32


def test_ground_truth_is_plain_datasets(tmp_path):
    """Another tool (here bare h5py) reads the truth without our code or JSON."""
    P.save_recording(tmp_path / "r.h5", make(truth=truth(4)))
    with h5py.File(tmp_path / "r.h5") as f:
        g = f["recordings/000000/truth"]
        assert g["position_world_m"].shape == (4, 3) and g["position_world_m"].attrs["units"] == "m"
        assert [k.decode() for k in g["kind"][()]] == ["direct", "specular", "specular", "specular"]
        assert g["order"][()].tolist() == [0, 1, 2, 0]
        assert "truth" not in json.loads(f["recordings/000000/metadata"][()])


@pytest.mark.slow
def test_order_past_9999_and_lazy_single_read(tmp_path):
    arr = P.Array("two", np.array([[0, 0, 0], [0, 0.01, 0]], float))
    w = P.paper_chirp()
    recs = [P.Recording(np.full((2, 4), float(i)), 500e3, arr, w) for i in range(10_002)]
    path = P.save_recordings(tmp_path / "many.h5", recs, checksum=False)
    assert P.count_recordings(path) == 10_002
    assert P.load_recording(path, 10_001).samples[0, 0] == 10_001
    assert P.load_recording(path, -3).samples[0, 0] == 9_999
    got = [P.load_recording(path, i).samples[0, 0] for i in range(9_997, 10_002)]
    assert got == [9_997, 9_998, 9_999, 10_000, 10_001]
    with h5py.File(path) as f:  # plain string order is the recordings' order, too
        names = sorted(f["recordings"])
    assert names[9_999:] == ["009999", "010000", "010001"]


def test_one_recording_loads_without_reading_the_others(tmp_path):
    path = P.save_recordings(tmp_path / "r.h5", [make(), make()], dtype=np.float64)
    with h5py.File(path, "a") as f:
        f["recordings/000000/samples"][0, 0] = np.nan
    assert P.load_recording(path, 1).n_samples == 100
    with pytest.raises(P.RecordingFileError, match="000000/samples.*NaN"):
        P.load_recording(path, 0)


def test_schema_1_files_still_load(tmp_path):
    """A version-1 file written here with bare h5py, as version 1 wrote it: float64,
    groups %04d, the ground truth as JSON inside the metadata."""
    path = tmp_path / "v1.h5"
    arr = P.paper_8x8()
    samples = np.random.default_rng(0).standard_normal((64, 50))
    meta = {
        "pose": {"position_m": [1, 2, 0.5], "yaw_deg": 90.0, "pitch_deg": 0, "roll_deg": 0},
        "truth": {
            "position_world_m": [[1, 2, 3]],
            "position_sensor_m": [[0.5, 0, 0]],
            "amplitude": [0.25],
            "order": [1],
            "kind": ["specular"],
        },
    }
    with h5py.File(path, "w") as f:
        f.attrs["schema"] = "acousim.recordings"
        f.attrs["schema_version"] = 1
        g = f.create_group("recordings/0000")
        g.create_dataset("samples", data=samples).attrs["units"] = "1"
        g.create_dataset("array/positions", data=arr.positions_m).attrs["units"] = "m"
        g.create_dataset("array/emitter", data=arr.emitter_m).attrs["units"] = "m"
        g.create_dataset("array/channels", data=arr.channels)
        g.create_dataset("array/grid_index", data=arr.grid_index).attrs["pitch_m"] = [5e-3, 5e-3]
        g.attrs.update(
            array_name="paper_8x8",
            sample_rate_hz=450e3,
            speed_of_sound_m_s=343.0,
            emission_index=0,
            waveform=json.dumps(
                {"kind": "linear", "f_start_hz": 20e3, "f_end_hz": 80e3, "duration_s": 1e-3}
            ),
        )
        g.create_dataset("metadata", data=json.dumps(meta))
    rec = P.load_recording(path)
    np.testing.assert_array_equal(rec.samples, samples)
    assert rec.truth.amplitude.tolist() == [0.25] and rec.truth.kind.tolist() == ["specular"]
    assert rec.metadata["pose"]["yaw_deg"] == 90.0 and "truth" not in rec.metadata


# what to break in a fresh file, and the message expected
CASES = {
    "nan samples": (
        lambda f, g: g["samples"].__setitem__((3, 5), np.inf),
        r"000000/samples.*NaN or infinite",
    ),
    "nan pitch": (
        lambda f, g: g["array/grid_index"].attrs.__setitem__("pitch_m", [np.nan, np.nan]),
        r"grid_index.pitch_m = \[nan, nan\]: must be two positive",
    ),
    "zero pitch": (
        lambda f, g: g["array/grid_index"].attrs.__setitem__("pitch_m", [0.0, 0.0]),
        r"grid_index.pitch_m.*positive",
    ),
    "deleted pitch": (
        lambda f, g: g["array/grid_index"].attrs.__delitem__("pitch_m"),
        r"grid_index.pitch_m: missing",
    ),
    "above nyquist": (
        lambda f, g: g.attrs.__setitem__("sample_rate_hz", 100e3),
        r"waveform: reaches 85000 Hz, above the Nyquist frequency 50000",
    ),
    "same mic positions": (
        lambda f, g: g["array/positions"].__setitem__(1, g["array/positions"][0]),
        r"array/positions: two microphones at the same position",
    ),
    "schema_version one": (
        lambda f, g: f.attrs.__setitem__("schema_version", "one"),
        r"schema_version = 'one': unsupported",
    ),
    "array schema": (
        lambda f, g: f.attrs.__setitem__("schema", np.array([1, 2])),
        r"schema = .*not a recording file",
    ),
    "pose": (
        lambda f, g: _set_meta(g, pose={"position_m": [1, "a"]}),
        r"metadata: pose = .*position_m",
    ),
    "truth kind": (
        lambda f, g: g["truth/kind"].__setitem__(0, b"ghost"),
        r"truth: truth kind 'ghost'",
    ),
    "truth kind not ASCII": (
        lambda f, g: g["truth/kind"].__setitem__(0, b"sp\xffcular"),
        "truth: truth kind 'sp\ufffdcular'",
    ),
    "truth length": (
        lambda f, g: _replace(g["truth"], "amplitude", np.ones(2), units="1"),
        r"truth: truth amplitude has 2 entries",
    ),
    "metadata not json": (
        lambda f, g: _replace(g, "metadata", "{oops"),
        r"000000/metadata: not JSON",
    ),
    "sample rate text": (
        lambda f, g: g.attrs.__setitem__("sample_rate_hz", "fast"),
        r"sample_rate_hz = 'fast': must be a finite float",
    ),
    "count": (
        lambda f, g: f.attrs.__setitem__("count", 2),
        r"count = 2: the file holds 1 recording group",
    ),
    "waveform": (
        lambda f, g: g.attrs.__setitem__("waveform", "[]"),
        r"\.waveform: not a waveform",
    ),
}


def _replace(group, name, data, units=None):
    del group[name]
    d = group.create_dataset(name, data=data)
    if units:
        d.attrs["units"] = units


def _set_meta(g, **kw):
    meta = json.loads(g["metadata"][()])
    meta.update(kw)
    _replace(g, "metadata", json.dumps(meta))


@pytest.mark.parametrize("case", sorted(CASES))
def test_corrupted_files_name_the_file_and_field(tmp_path, case):
    path = P.save_recording(tmp_path / "r.h5", make(truth=truth()))
    change, pattern = CASES[case]
    with h5py.File(path, "a") as f:
        change(f, f["recordings/000000"])
    with pytest.raises(P.RecordingFileError, match=pattern) as info:
        P.load_recording(path)
    assert str(info.value).startswith(str(path)) and isinstance(info.value, InputError)


def test_huge_declared_shape_is_refused_before_reading(tmp_path):
    path = P.save_recording(tmp_path / "r.h5", make())
    with h5py.File(path, "a") as f:
        g = f["recordings/000000"]
        del g["samples"]
        # 15 TiB declared, nothing written: a file of a few kB
        d = g.create_dataset("samples", shape=(64, 2**35), dtype="f8", chunks=(1, 2**20))
        d.attrs["units"] = "1"
    assert path.stat().st_size < 100_000
    with pytest.raises(
        P.RecordingFileError, match=r"samples = \(64, 34359738368\).*16,384 GiB.*max_bytes"
    ):
        P.load_recording(path)


def test_unregistered_filter_is_named(tmp_path):
    path = P.save_recording(tmp_path / "r.h5", make())
    with h5py.File(path, "a") as f:
        g = f["recordings/000000"]
        del g["samples"]
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_chunk((64, 100))
        dcpl.set_filter(32123, h5py.h5z.FLAG_OPTIONAL)  # an id no library registers
        space = h5py.h5s.create_simple((64, 100))
        h5py.h5d.create(g.id, b"samples", h5py.h5t.IEEE_F64LE, space, dcpl=dcpl)
        g["samples"].attrs["units"] = "1"
    with pytest.raises(P.RecordingFileError, match=r"samples filter = '32123.*not available"):
        P.load_recording(path)


def test_flipped_bytes_fail_the_checksum(tmp_path):
    rec = make()
    path = P.save_recording(tmp_path / "r.h5", rec)
    with h5py.File(path) as f:
        offset = f["recordings/000000/samples"].id.get_chunk_info(0).byte_offset
    raw = bytearray(path.read_bytes())
    raw[offset + 40] ^= 0xFF
    path.write_bytes(bytes(raw))
    with pytest.raises(P.RecordingFileError, match=r"samples: cannot be read: corrupted"):
        P.load_recording(path)


def test_validation_errors_name_the_field(tmp_path):
    path = P.save_recording(tmp_path / "r.h5", make())
    with h5py.File(path, "a") as f:
        f["recordings/000000/array/positions"].attrs["units"] = "mm"
    with pytest.raises(P.RecordingFileError, match="array/positions.units = 'mm'"):
        P.load_recording(path)
    with h5py.File(path, "a") as f:
        f["recordings/000000/array/positions"].attrs["units"] = "m"
        del f["recordings/000000/samples"]
        f["recordings/000000/samples"] = np.zeros((3, 100))
        f["recordings/000000/samples"].attrs["units"] = "1"
    with pytest.raises(P.RecordingFileError, match="3 channels.*64 microphones"):
        P.load_recording(path)
    (tmp_path / "x.h5").write_text("not hdf5")
    with pytest.raises(P.RecordingFileError, match="x.h5.*not an HDF5"):
        P.load_recording(tmp_path / "x.h5")
    with h5py.File(tmp_path / "y.h5", "w") as f:
        f.attrs["schema"] = "other"
    with pytest.raises(P.RecordingFileError, match="schema"):
        P.load_recording(tmp_path / "y.h5")


def test_time_axis_starts_at_emission():
    r = make()
    assert r.time_s()[7] == 0.0 and r.time_s()[8] == pytest.approx(2e-6)


def test_failed_write_leaves_no_file(tmp_path):
    bad = make()
    object.__setattr__(bad, "metadata", {"x": object()})
    with pytest.raises(P.InputError, match="metadata: not JSON-serialisable"):
        P.save_recording(tmp_path / "r.h5", bad)  # refused before anything is written
    assert list(tmp_path.iterdir()) == []


def test_recording_refuses_inconsistent_input():
    with pytest.raises(ValueError, match="3 channels"):
        P.Recording(np.zeros((3, 10)), 1e3, P.paper_8x8(), P.paper_chirp())
    with pytest.raises(ValueError, match="speed_of_sound"):
        P.Recording(np.zeros((64, 10)), 1e3, P.paper_8x8(), P.paper_chirp(), 3430.0)


def test_a_recording_refuses_the_call_its_file_would_refuse(tmp_path):
    """One check in the constructor and the file: a 20-85 kHz call at 100 kHz (Nyquist
    50 kHz) and a call shorter than one sample, named as the writer names them."""
    x = np.zeros((64, 100))
    with pytest.raises(
        P.InputError,
        match=r"^waveform: reaches 85000 Hz, above the Nyquist "
        r"frequency 50000 Hz$",
    ):
        P.Recording(x, 100e3, P.paper_8x8(), P.linear_chirp(20e3, 85e3, 1e-3))
    with pytest.raises(P.InputError, match=r"^waveform: lasts 1e-06 s, less than one sample"):
        P.Recording(x, 500e3, P.paper_8x8(), P.linear_chirp(20e3, 85e3, 1e-6))
    ok = P.Recording(x, 170e3, P.paper_8x8(), P.linear_chirp(20e3, 85e3, 1e-3))  # at Nyquist
    assert ok.sample_rate_hz == 170e3


def test_a_rigs_lidar_scans_round_trip_in_order(tmp_path):
    """Three LiDAR scans (a rig's): lidar, lidar_01, lidar_02, read back in order;
    other scans without the first, or not a point cloud, are refused by name."""
    rng = np.random.default_rng(5)

    def cloud(n: int, dz: float) -> P.PointCloud:
        T = np.eye(4)
        T[2, 3] = dz
        return P.PointCloud(rng.normal(size=(n, 3)), rng.uniform(0, 1, n), T, name=f"L{n}")

    scans = (cloud(7, 0.1), cloud(9, 0.2), cloud(4, 0.3))
    rec = dataclasses.replace(make(), lidar=scans[0], other_lidars=scans[1:])
    assert rec.lidars == scans
    P.save_recordings(tmp_path / "r.h5", [rec, make()])
    with h5py.File(tmp_path / "r.h5") as f:
        assert sorted(k for k in f["recordings/000000"] if k.startswith("lidar")) == [
            "lidar", "lidar_01", "lidar_02"
        ]  # fmt: skip
    back, plain = P.load_recordings(tmp_path / "r.h5")
    assert plain.lidars == () and plain.other_lidars == ()
    for a, b in zip(scans, back.lidars, strict=True):
        assert b.name == a.name
        np.testing.assert_array_equal(b.to_sensor, a.to_sensor)
        np.testing.assert_allclose(b.points_m, a.points_m, rtol=1e-6)  # float32
    with pytest.raises(InputError, match="other_lidars.*needs the first"):
        dataclasses.replace(make(), other_lidars=scans[1:])
    with pytest.raises(InputError, match=r"other_lidars\[1\].*PointCloud"):
        dataclasses.replace(make(), lidar=scans[0], other_lidars=(scans[1], "scan"))


@pytest.mark.parametrize("case", ["nan samples", "deleted pitch", "pose", "truth kind"])
def test_command_line_reports_a_corrupted_file_in_one_line(tmp_path, capsys, case):
    from acousim.cli import main

    path = P.save_recording(tmp_path / "r.h5", make(truth=truth()))
    change, pattern = CASES[case]
    with h5py.File(path, "a") as f:
        change(f, f["recordings/000000"])
    for command in (["info", str(path)], ["image", str(path), "--out", str(tmp_path / "o")]):
        assert main(command) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and str(path) in err
        assert re.search(pattern, err), err


def test_a_scene_without_paths_round_trips_an_empty_truth(tmp_path):
    empty = P.GroundTruth([], [], [], [], [])
    rec = P.Recording(np.zeros((64, 50)), 500e3, P.paper_8x8(), P.paper_chirp(), truth=empty)
    back = P.load_recording(P.save_recording(tmp_path / "r.h5", rec))
    assert len(back.truth) == 0 and back.truth.position_world_m.shape == (0, 3)


def _data_ranges(path):
    """Byte ranges (start, stop) of the stored data of every dataset in the file."""
    ranges = []

    def visit(_, d):
        if not isinstance(d, h5py.Dataset) or not d.size:
            return
        if d.chunks is None:
            ranges.append((d.id.get_offset(), d.id.get_offset() + d.id.get_storage_size()))
        else:
            for i in range(d.id.get_num_chunks()):
                c = d.id.get_chunk_info(i)
                ranges.append((c.byte_offset, c.byte_offset + c.size))

    with h5py.File(path) as f:
        f.visititems(visit)
    return ranges


def test_damaged_data_gives_a_file_error_never_wrong_numbers(tmp_path):
    """150 files, each with 3 random bytes of stored data changed (seeded): a load
    either fails with RecordingFileError or returns the samples and truth written
    (checksums), never other numbers. Bytes of HDF5's own structures are left alone:
    some of those crash the HDF5 library itself (a segmentation fault in h5py's
    attribute reader was seen), which no loader can catch."""
    rec = make(truth=truth())
    path = P.save_recording(tmp_path / "r.h5", rec)
    raw = path.read_bytes()
    offsets = np.concatenate([np.arange(a, b) for a, b in _data_ranges(path)])
    rng = np.random.default_rng(0)
    failed = 0
    for _ in range(150):
        b = bytearray(raw)
        for o in rng.choice(offsets, 3, replace=False):
            b[int(o)] ^= int(rng.integers(1, 256))
        (tmp_path / "d.h5").write_bytes(bytes(b))
        try:
            back = P.load_recording(tmp_path / "d.h5")
        except P.RecordingFileError:
            failed += 1
            continue
        np.testing.assert_allclose(back.samples, rec.samples, rtol=2.0**-24)
        np.testing.assert_array_equal(back.truth.amplitude, rec.truth.amplitude)
    assert failed > 100


def test_a_chunk_that_cannot_be_found_is_not_read_as_zeros(tmp_path):
    """HDF5 reads a chunk missing from its index as the fill value (zeros), without
    error; the samples' sha256 catches it."""
    path = P.save_recording(tmp_path / "r.h5", make())
    with h5py.File(path, "a") as f:
        g = f["recordings/000000"]
        data, attrs = g["samples"][()], dict(g["samples"].attrs)
        del g["samples"]
        d = g.create_dataset("samples", shape=data.shape, dtype=data.dtype, chunks=(1, 100))
        d[:57] = data[:57]
        d[58:] = data[58:]  # row 57 never written
        d.attrs.update(attrs)
    with pytest.raises(P.RecordingFileError, match=r"samples.sha256: samples differ"):
        P.load_recording(path)


def test_provenance_reads_the_simulation_facts_typed(tmp_path):
    """The simulation's facts cross modules typed (Recording.provenance), read back
    from a file as they were written; a recording without them (real, or written
    before them) has None; a file of schema 1 (only ``simulated``) still says its kind."""
    facts = {
        "scene_file": "/scenes/corridor.toml",
        "max_range_m": 6.0,
        "n_paths": 4423,
        "pose_index": 12,
        "sample": {"temperature_c": 21.5, "snr_db": 30.0},
        "timestamp": 1.7e9,
        "motion": {"velocity_m_s": [0.5, 0.0, 0.0], "angular_velocity_deg_s": [0, 0, 90.0]},
    }
    rec = make()
    rec = P.Recording(
        rec.samples, 500e3, rec.array, rec.waveform, 343.2, 7, {**rec.metadata, **facts}
    )
    back = P.load_recording(P.save_recording(tmp_path / "r.h5", rec))
    p = back.provenance
    assert (p.kind, p.simulated, p.scene_file, p.max_range_m, p.n_paths, p.pose_index) == (
        "simulated",
        True,
        "/scenes/corridor.toml",
        6.0,
        4423,
        12,
    )
    assert p.sample == {"temperature_c": 21.5, "snr_db": 30.0} and p.timestamp_s == 1.7e9
    assert p.motion.velocity_m_s == (0.5, 0.0, 0.0)
    assert p.motion.angular_velocity_rad_s[2] == pytest.approx(np.pi / 2, rel=1e-15)
    # the pose's transform: yaw 10 degrees about z, written here by hand
    c, s = np.cos(np.pi / 18), np.sin(np.pi / 18)
    expected = np.array([[c, -s, 0, 1.0], [s, c, 0, 2.0], [0, 0, 1, 0.0], [0, 0, 0, 1]])
    np.testing.assert_allclose(p.pose.matrix(), expected, atol=1e-15)
    bare = P.Provenance.from_metadata({"simulated": False})
    assert bare.kind == "real"
    assert (bare.scene_file, bare.max_range_m, bare.n_paths, bare.sample) == (None,) * 4
    assert P.Provenance.from_metadata({"simulated": True}).kind == "simulated"


def test_a_recording_with_its_truth_is_the_replaced_one():
    """``with_truth`` (its samples not checked again) gives what
    ``dataclasses.replace`` gives, field for field, and refuses a LiDAR scan that
    is not a point cloud, by name."""
    rec = make()
    T = np.eye(4)
    scan = P.PointCloud(np.zeros((3, 3)), np.ones(3), T, name="L")
    want = dataclasses.replace(rec, truth=truth(), lidar=scan)
    got = rec.with_truth(want.truth, scan)
    for f in dataclasses.fields(P.Recording):
        assert getattr(got, f.name) is getattr(want, f.name) or f.name in ("samples", "metadata")
    assert got.samples is rec.samples and rec.truth is None
    with pytest.raises(InputError, match="lidar"):
        rec.with_truth(None, "a scan")
