import h5py
import numpy as np
import pytest

import processing as P


def make(shape=(64, 100), k=None):
    rng = np.random.default_rng(3)
    s = rng.standard_normal(shape if k is None else (k, *shape))
    return P.Recording(
        s,
        500e3,
        P.paper_8x8(),
        P.paper_chirp(),
        343.2,
        7,
        {"seed": 3, "simulated": True, "pose": [1.0, 2.0, 0.0]},
    )


def test_hdf5_round_trip_is_exact(tmp_path):
    recs = [make(), make(k=3)]
    path = P.save_recordings(tmp_path / "r.h5", recs)
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
    assert back[1].n_measurements == 3


def test_time_axis_starts_at_emission():
    r = make()
    assert r.time_s()[7] == 0.0 and r.time_s()[8] == pytest.approx(2e-6)


def test_validation_errors_name_the_field(tmp_path):
    path = P.save_recording(tmp_path / "r.h5", make())
    with h5py.File(path, "a") as f:
        f["recordings/0000/array/positions"].attrs["units"] = "mm"
    with pytest.raises(P.RecordingFileError, match="array/positions.*units"):
        P.load_recording(path)
    with h5py.File(path, "a") as f:
        f["recordings/0000/array/positions"].attrs["units"] = "m"
        del f["recordings/0000/samples"]
        f["recordings/0000/samples"] = np.zeros((3, 100))
        f["recordings/0000/samples"].attrs["units"] = "1"
    with pytest.raises(P.RecordingFileError, match="3 channels.*64 microphones"):
        P.load_recording(path)
    (tmp_path / "x.h5").write_text("not hdf5")
    with pytest.raises(P.RecordingFileError, match="x.h5.*not an HDF5"):
        P.load_recording(tmp_path / "x.h5")
    with h5py.File(tmp_path / "y.h5", "w") as f:
        f.attrs["schema"] = "other"
    with pytest.raises(P.RecordingFileError, match="schema"):
        P.load_recording(tmp_path / "y.h5")


def test_failed_write_leaves_no_file(tmp_path):
    bad = make()
    object.__setattr__(bad, "metadata", {"x": object()})
    with pytest.raises(TypeError):
        P.save_recording(tmp_path / "r.h5", bad)
    assert list(tmp_path.iterdir()) == []


def test_recording_refuses_inconsistent_input():
    with pytest.raises(ValueError, match="3 channels"):
        P.Recording(np.zeros((3, 10)), 1e3, P.paper_8x8(), P.paper_chirp())
    with pytest.raises(ValueError, match="speed_of_sound"):
        P.Recording(np.zeros((64, 10)), 1e3, P.paper_8x8(), P.paper_chirp(), 3430.0)
