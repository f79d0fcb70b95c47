"""Regression tests of issue 25, one per class of fault, each fixed at its cause: bad
input always an InputError (never a ValueError/RuntimeError traceback), the memory
estimate before the matched filter, metadata checked when read, nothing written that
its reader refuses, and the check before any computation (no warning first)."""

from __future__ import annotations

import copy
import dataclasses
import json
import tracemalloc
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest

import processing as P
from acousim.cli import main
from acousim.dataset.spec import load_spec
from acousim.scene import load_scene
from processing.base.errors import InputError
from tests import REPO
from tests.oracles.scenes import PAPER_SENSOR_TOML

SCENES = REPO / "scenes"


def small_recording(array=None, **kw) -> P.Recording:
    """A 2 x 2 URA recording of noise, 1024 samples at 450 kHz, the 25-50 kHz call."""
    array = array or P.ura(2, 2, 4e-3)
    x = np.random.default_rng(5).standard_normal((array.n_mics, 1024))
    return P.Recording(x, 450e3, array, P.rtis_call("default_25_50"), **kw)


# --- 1. bad input is an InputError -----------------------------------------------------


@pytest.mark.parametrize(
    "grid", [[[0, 0], [0, 1], [1, 0], [-1, 1]], [[0, 0], [0, 1], [1, 0], [2**40, 1]]]
)
def test_grid_indices_outside_the_array_are_refused(grid):
    pos = P.ura(2, 2, 4e-3).positions_m
    with pytest.raises(InputError, match=r"grid indices must lie in \[0, 4\)"):
        P.Array("bad", pos, grid_index=grid, pitch_m=(4e-3, 4e-3))


def test_a_smoothed_method_on_an_irregular_array_is_an_input_error():
    from acousim.imaging.run import ImagingOptions, image_recordings

    irregular = P.from_coordinates(np.array([[0, 0], [3e-3, 1e-3], [1e-3, 5e-3], [6e-3, 4e-3]]))
    rec = small_recording(irregular)
    with pytest.raises(InputError, match="is not a URA, so music-fbss cannot be used"):
        image_recordings([rec], ImagingOptions(methods=("das", "music-fbss")))
    with pytest.raises(InputError, match="irregular"):
        irregular.require_ura("spatial smoothing")


def test_a_random_pose_region_without_a_free_pose_is_an_input_error(tmp_path):
    from acousim.dataset.generation import sample_parameters

    spec = tmp_path / "spec.toml"
    spec.write_text(
        f"""[dataset]
samples = 2
[[scenes]]
file = "{SCENES}/corridor.toml"
poses = "random"
region = {{ x = [100.0, 101.0], y = [0.0, 0.1], z = [0.3, 0.4] }}
"""
    )
    closed = r"scenes\[0\].region.*sample 0: no usable pose in 1000 draws.*1000 were outside"
    with pytest.raises(InputError, match=closed):
        sample_parameters(load_spec(spec), 0)


POINTS = (
    '[scene]\nname = "silent"\n'
    + PAPER_SENSOR_TOML
    + """[sensor.pose]
position_m = [0.0, 0.0, 0.0]
[simulation]
max_range_m = 1.5
absorption = false
[[points]]
position_m = [1.0, 0.2, 0.0]
velocity_m_s = [0.5, 0.0, 0.0]
"""
)
SILENT = """[[points]]
position_m = [0.8, -0.3, 0.1]
velocity_m_s = [0.0, 0.4, 0.0]
strength = 0.0
"""


def test_a_point_of_strength_zero_adds_nothing(tmp_path):
    """It used to fail the moving renderer ('need at least one array to stack'); the
    samples are now the same bytes as without it (an independent reference: the
    scene without that point)."""
    from acousim.simulator import Simulator

    (tmp_path / "a.toml").write_text(POINTS)
    (tmp_path / "b.toml").write_text(POINTS + SILENT)
    a = Simulator(load_scene(tmp_path / "a.toml")).run()[0]
    b = Simulator(load_scene(tmp_path / "b.toml")).run()[0]
    assert np.any(a.samples) and a.samples.tobytes() == b.samples.tobytes()
    (tmp_path / "c.toml").write_text(POINTS.split("[[points]]")[0] + SILENT)
    assert main(["simulate", str(tmp_path / "c.toml"), "--out", str(tmp_path / "c.h5")]) == 2


# --- 2. memory estimated before the matched filter -------------------------------------


@pytest.mark.parametrize("change", ["rate 1e12", "call 100 s"])
def test_the_matched_filter_is_estimated_before_allocating(change):
    rec = small_recording()
    if change == "rate 1e12":
        rec = dataclasses.replace(rec, sample_rate_hz=1e12)
    else:
        rec = dataclasses.replace(rec, waveform=dataclasses.replace(rec.waveform, duration_s=100.0))
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match="for the matched filter and snapshots alone"):
            P.acoustic_images(rec, ["das"])
        with pytest.raises(InputError, match="for the matched filter"):
            P.recording_snapshot(rec, P.ProcessingSettings())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6  # refused before anything large was allocated


def test_the_front_end_estimate_bounds_what_it_allocates():
    """Independent reference: the peak of the bytes numpy allocates (tracemalloc
    sees numpy's buffers) while the snapshot of a recording is made."""
    rec = small_recording(P.ura(4, 4, 4e-3))
    rec = rec.with_samples(np.random.default_rng(1).standard_normal((16, 20000)))
    settings = P.ProcessingSettings()
    tracemalloc.start()
    try:
        P.recording_snapshot(rec, settings)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    estimate = P.front_end_bytes(rec, settings)
    assert peak <= estimate <= 1.5 * peak


# --- 3. metadata read with checks ------------------------------------------------------


def _with_metadata(path: Path, meta) -> Path:
    with h5py.File(path, "r+") as f:
        g = f["recordings/000000"]
        del g["metadata"]
        g.create_dataset("metadata", data=json.dumps(meta))
    return path


@pytest.mark.parametrize(
    "meta,key",
    [
        ({"pose": {"yaw_deg": 3.0}}, "pose"),
        ({"pose": {"position_m": [0, 0], "yaw_deg": 3.0}}, "pose"),
        ({"pose": {"position_m": [0, 0, 0], "yaw_deg": "3"}}, "pose"),
        ({"pose": {"position_m": [0, 0, 1e300]}}, "pose"),
        ({"pose": {"position_m": [0, 0, 0], "time_s": None}}, "pose"),
        ({"motion": {"velocity_m_s": [1, 2]}}, "motion"),
        ({"motion": {"emission_pose": {"yaw_deg": 1}}}, "motion"),
        ({"scene_file": 3}, "scene_file"),
        ({"pose_index": -1}, "pose_index"),
        ({"pose_index": True}, "pose_index"),
        ({"max_range_m": "far"}, "max_range_m"),
        ({"simulated": "yes"}, "simulated"),
        ([1, 2], "metadata"),
    ],
)
def test_metadata_is_checked_key_by_key(tmp_path, meta, key):
    path = _with_metadata(P.save_recording(tmp_path / "r.h5", small_recording()), meta)
    with pytest.raises(P.RecordingFileError, match=key):
        P.load_recording(path)


def test_a_pose_without_its_angles_reads_as_zero_angles(tmp_path, capsys):
    """It ended in KeyError: 'yaw_deg' in the imaging; absent angles are 0, read in
    one place (Recording.provenance)."""
    from acousim.imaging.run import _pose

    meta = {"pose": {"position_m": [1.0, 2.0, 0.5]}}
    path = _with_metadata(P.save_recording(tmp_path / "r.h5", small_recording()), meta)
    rec = P.load_recording(path)
    pose = _pose(rec)
    assert pose.position_m.tolist() == [1.0, 2.0, 0.5]
    assert (pose.yaw_rad, pose.pitch_rad, pose.roll_rad, pose.time_s) == (0, 0, 0, 0)
    args = ["image", str(path), "--out", str(tmp_path / "o"), "--method", "das", "--no-3d"]
    assert main([*args, "--step", "10"]) == 0
    assert main(["info", str(path)]) == 0
    assert "yaw 0.0°" in capsys.readouterr().out


# --- 4. accepted, then unreadable ------------------------------------------------------


def test_two_microphones_at_one_place_are_refused_when_the_scene_is_read(tmp_path):
    (tmp_path / "mics.csv").write_text("0 0\n5 0\n0 5\n0 5\n")
    scene = (
        (SCENES / "points.toml")
        .read_text()
        .replace('array = "paper_8x8"', 'coordinates = "mics.csv"')
    )
    (tmp_path / "s.toml").write_text(scene)
    with pytest.raises(InputError, match="two microphones at the same position"):
        load_scene(tmp_path / "s.toml")


@pytest.mark.parametrize(
    "change",
    ["call above Nyquist", "pose without position", "motion of 2 numbers", "not JSON"],
)
def test_nothing_is_written_that_the_reader_refuses(tmp_path, change):
    rec = small_recording()
    if change == "call above Nyquist":
        high = dataclasses.replace(rec.waveform, f_end_hz=300e3)
        with pytest.raises(InputError, match="waveform: reaches 300000 Hz, above the Nyquist"):
            dataclasses.replace(rec, waveform=high)  # the constructor runs the same check
        rec = copy.copy(rec)
        object.__setattr__(rec, "waveform", high)  # changed in place after the check
    elif change == "pose without position":
        rec = dataclasses.replace(rec, metadata={"pose": {"yaw_deg": 1.0}})
    elif change == "motion of 2 numbers":
        rec = dataclasses.replace(rec, metadata={"motion": {"velocity_m_s": [1.0, 2.0]}})
    else:
        rec = dataclasses.replace(rec, metadata={"x": {1, 2}})
    with pytest.raises(InputError):
        P.save_recording(tmp_path / "r.h5", rec)
    assert list(tmp_path.iterdir()) == []


# --- 5. checked before computing: no warning before the error ---------------------------


@pytest.mark.parametrize(
    "old,new",
    [
        ("position_m = [1.0, 0.0, 0.0]", "position_m = [1e308, 0.0, 0.0]"),
        ("position_m = [0.0, 0.0, 0.0]\n", "position_m = [-1e300, 0.0, 0.0]\n"),
        ('array = "paper_8x8"', 'coordinates = "huge.csv"'),
    ],
)
def test_huge_coordinates_are_refused_without_a_warning(tmp_path, old, new):
    (tmp_path / "huge.csv").write_text("0 0\n1e305 0\n0 5\n5 5\n")
    text = (SCENES / "points.toml").read_text()
    assert old in text
    (tmp_path / "s.toml").write_text(text.replace(old, new, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning would fail the test
        with pytest.raises(InputError, match=r"1e\+06|10 m"):
            load_scene(tmp_path / "s.toml")


def test_a_mesh_placed_beyond_the_world_is_refused_without_a_warning(tmp_path):
    from acousim.simulator import Simulator

    text = (SCENES / "wall.toml").read_text().replace('"meshes/', f'"{SCENES}/meshes/')
    # units given: a mesh of no units that large is refused before, as drawn in mm
    big = '[[meshes]]\nscale = 1e9\nunits = "m"'
    (tmp_path / "s.toml").write_text(text.replace("[[meshes]]", big, 1))
    scene = load_scene(tmp_path / "s.toml")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match="mesh vertices reach beyond"):
            Simulator(scene).run()


def test_a_recording_shorter_than_the_stft_window_is_one_line(tmp_path, capsys):
    """It loads (a valid file) and imaging refuses it with a sentence (was a
    ValueError traceback)."""
    rec = small_recording()
    path = P.save_recording(tmp_path / "short.h5", rec.with_samples(rec.samples[:, :100]))
    assert main(["image", str(path), "--out", str(tmp_path / "o"), "--no-3d"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("acousim image: error: ") and err.count("\n") == 1, err
