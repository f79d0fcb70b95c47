"""Simulated versus real: the real eRTIS sample against its scene, the emulated sensor
against the direct simulation, and recordings that cannot be compared."""

import numpy as np
import pytest

import processing as P
from acousim.cli import main
from acousim.compare.comparison import ComparisonError, check_comparable, compare
from acousim.scene import load_scene
from acousim.simulator import Simulator
from tests import REPO

SCENES = REPO / "scenes"


def test_real_sample_matches_its_scene(tmp_path, capsys):
    import json

    assert (
        main(
            [
                "compare",
                "rtisdev-sample",
                "--scene",
                str(SCENES / "ertis_sample.toml"),
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    report = json.loads((tmp_path / "comparison.json").read_text())
    das = report["images"]["das"]
    main_echo = max(das["matched"], key=lambda p: p["real"]["level_db"])
    assert main_echo["real"]["range_m"] == pytest.approx(3.21, abs=0.05)
    assert abs(main_echo["d_range_m"]) <= das["range_bin_m"] + 1e-9  # within one range bin
    assert abs(main_echo["d_azimuth_deg"]) <= 2.0
    # alignment and gain are reported
    assert abs(report["alignment"]["emission_shift_samples"]) < 50
    assert report["alignment"]["gain"] > 0
    # the one plate's echo spreads over the range bins of the STFT windows that overlap
    # it (256 samples at 450 kHz: 9.8 cm) and the sparse array puts lobes beside it:
    # those peaks, all within 3 cm of the echo, are its side lobes, not other echoes
    lobes = das["side_lobes_real"]
    assert len(lobes) >= 30
    assert all(abs(s["range_m"] - s["of"]["range_m"]) < 0.03 for s in lobes)
    assert all(s["level_db"] < s["of"]["level_db"] for s in lobes)
    assert len(das["only_real"]) <= 3
    # the range profiles do not climb at the far end (the envelope no longer wraps the
    # direct path around): over the last 0.5 m the simulation stays below the real
    # noise floor as everywhere past the echo (it climbed 40 dB to 20 dB above it)
    level = np.array(report["range_profile"]["level_difference_db"])
    assert np.min(level[-10:]) > 3  # 4.98 dB after the Cramer speed of sound; was -20 wrapped
    assert (tmp_path / "comparison.png").stat().st_size > 10_000
    out = capsys.readouterr().out
    assert "side lobe(s) in the real image" in out
    # the echo the scene was placed on is said to agree by construction; the side
    # lobes are predicted: their median level above the beam pattern, from the JSON
    assert "agrees on that echo by construction" in out
    excess = np.median(
        [s["level_db"] - s["of"]["level_db"] - s["array_response_db"] for s in lobes]
    )
    assert f"side lobes: {len(lobes)} real, median {excess:+.1f} dB re the array's beam" in out


def test_the_envelope_does_not_wrap():
    """A strong pulse at the start and silence after it: the padded envelope is
    (nearly) zero at the end, where the circular one carries the pulse's tail."""
    from scipy.signal import hilbert

    from acousim.compare.comparison import envelope

    t = np.arange(4000) / 450e3
    x = np.sin(2 * np.pi * 40e3 * t) * np.exp(-(((t - 2e-5) / 1e-5) ** 2))
    tail_wrapped = np.abs(hilbert(x))[-50:].max()
    assert tail_wrapped > 1e-4  # what the unpadded transform does
    assert envelope(x)[-50:].max() < 1e-3 * tail_wrapped
    # in the middle both are the same envelope: amplitude 1 at the peak
    assert envelope(x).max() == pytest.approx(1.0, abs=0.02)


def test_side_lobes_are_told_from_echoes():
    """Peaks within one window of a stronger peak are its side lobes, with the array's
    beam pattern (computed here independently) at their direction; a weaker peak
    further away in range is an echo of its own."""
    from acousim.compare.comparison import Peak, side_lobes

    arr = P.urtis_v1()
    f, c = 40e3, 343.0
    peaks = [
        Peak(2.00, 10.0, 0.0, 0.0),
        Peak(2.02, -30.0, 5.0, -6.0),
        Peak(2.60, -30.0, 5.0, -8.0),
    ]
    lobes, rest = side_lobes(peaks, [1, 2], 0.098, arr, f, c)
    assert rest == [2] and len(lobes) == 1 and lobes[0].of == peaks[0]
    k = 2 * np.pi * f / c

    def a(az, el):
        az, el = np.deg2rad(az), np.deg2rad(el)
        u = [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
        return np.exp(1j * k * arr.positions_m @ u)

    expect = 20 * np.log10(abs(np.sum(np.conj(a(-30, 5)) * a(10, 0))) / arr.n_mics)
    assert lobes[0].array_response_db == pytest.approx(expect, abs=1e-9)


def test_emulated_sensor_against_the_direct_simulation():
    from hardware import DeviceSettings, Recorder, RtisDevice
    from hardware.emulator import EmulatedSensor, EmulatorBackend, recording_source

    scene = load_scene(SCENES / "wall.toml")
    sim = Simulator(scene).simulate_pose(scene.sensor.poses[0], 0, n_samples=16384)
    source = recording_source([sim], sim.array.channels)
    backend = EmulatorBackend(EmulatedSensor(source))
    recorder = Recorder(
        lambda: RtisDevice(backend=backend),
        DeviceSettings(call=sim.waveform.sampled(450e3)),
        sim.array,
        sim.waveform,
        speed_of_sound_m_s=sim.speed_of_sound_m_s,
    )
    real = recorder.acquire(count=1)[0]
    report, _ = compare(real, sim, ("das",))
    assert abs(report.alignment.emission_shift_samples) < 0.5
    assert report.alignment.gain == pytest.approx(1 / source.full_scale, rel=0.05)
    assert report.mean_envelope_correlation > 0.9
    m = report.images["das"].matched[0]
    assert abs(m.d_range_m) < 1e-9 and abs(m.d_azimuth_deg) < 1e-9


def test_recordings_that_cannot_be_compared():
    a = P.Recording(np.zeros((64, 1000)), 500e3, P.paper_8x8(), P.paper_chirp())
    b = P.Recording(np.zeros((30, 900)), 450e3, P.urtis_v1(), P.rtis_call())
    with pytest.raises(ComparisonError, match="arrays .*sample rates .*calls"):
        check_comparable(a, b)


def test_compare_errors_exit_2(tmp_path, capsys):
    a = P.Recording(np.zeros((64, 1000)), 500e3, P.paper_8x8(), P.paper_chirp())
    b = P.Recording(np.zeros((64, 1000)), 450e3, P.paper_8x8(), P.paper_chirp())
    P.save_recording(tmp_path / "a.h5", a)
    P.save_recording(tmp_path / "b.h5", b)
    assert (
        main(
            [
                "compare",
                str(tmp_path / "a.h5"),
                "--sim",
                str(tmp_path / "b.h5"),
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 2
    )
    assert "sample rates (500000 vs 450000 Hz)" in capsys.readouterr().err
    assert main(["compare", str(tmp_path / "a.h5"), "--out", str(tmp_path / "o")]) == 2
    assert "exactly one of --scene" in capsys.readouterr().err
    for extra, message in (
        (["--sim", str(tmp_path / "b.h5"), "--index", "3"], "--index = 3: the real file holds 1"),
        (["--sim", str(tmp_path / "b.h5"), "--sim-index", "5"], "--sim-index = 5: the --sim"),
        (["--scene", str(SCENES / "points.toml"), "--pose", "4"], "--pose = 4: the scene has 1"),
    ):
        assert main(["compare", str(tmp_path / "a.h5"), *extra, "--out", str(tmp_path / "o")]) == 2
        assert message in capsys.readouterr().err
    # a negative index is refused by the parser (argparse's exit code 2)
    with pytest.raises(SystemExit) as exit_:
        main(
            [
                "compare",
                str(tmp_path / "a.h5"),
                "--sim",
                str(tmp_path / "b.h5"),
                "--sim-index",
                "-1",
            ]
        )
    assert exit_.value.code == 2
    assert "--sim-index: '-1': outside the allowed range" in capsys.readouterr().err


def test_trajectory_comparison_has_a_row_per_pose(tmp_path, capsys):
    import json

    scene = SCENES / "wall.toml"
    rec = tmp_path / "rec.h5"
    assert (
        main(
            ["record", "--emulate", str(scene), "--count", "2", "--rate", "100", "--out", str(rec)]
        )
        == 0
    )
    sim = tmp_path / "sim.h5"
    recs = P.load_recordings(rec)
    sc = load_scene(scene)
    s = Simulator(sc)
    P.save_recordings(
        sim, [s.simulate_pose(sc.sensor.poses[0], 0, n_samples=r.n_samples) for r in recs]
    )
    assert (
        main(["compare", str(rec), "--sim", str(sim), "--all", "--out", str(tmp_path / "cmp")]) == 0
    )
    table = json.loads((tmp_path / "cmp" / "summary.json").read_text())
    assert len(table["rows"]) == 2 and table["summary"]["poses"] == 2
    assert table["summary"]["median_abs_d_range_m"] < 0.01
    assert (tmp_path / "cmp" / "pose_0001" / "comparison.json").is_file()


def test_an_unreadable_mesh_is_a_one_line_error(tmp_path, capsys):
    """`compare --scene` and `record --emulate` report a broken mesh file as `simulate`
    does: exit 2, the file named, nothing written."""
    text = (SCENES / "wall.toml").read_text()
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "wall.stl").write_text("not a mesh\n")
    scene = tmp_path / "wall.toml"
    scene.write_text(text)
    rec = P.Recording(np.zeros((30, 2000)), 450e3, P.urtis_v1(), P.rtis_call())
    P.save_recording(tmp_path / "real.h5", rec)
    out = tmp_path / "o"
    assert (
        main(["compare", str(tmp_path / "real.h5"), "--scene", str(scene), "--out", str(out)]) == 2
    )
    assert "meshes/wall.stl" in capsys.readouterr().err
    assert (
        main(["record", "--emulate", str(scene), "--count", "1", "--out", str(out / "r.h5")]) == 2
    )
    assert "meshes/wall.stl" in capsys.readouterr().err
    assert not (out / "r.h5").exists() and not (out / "comparison.json").exists()
    # an array the 32-bit link cannot carry
    scene.write_text(
        text.replace('"urtis_v1"', '"paper_8x8"').replace("meshes/", str(SCENES / "meshes") + "/")
    )
    assert (
        main(["record", "--emulate", str(scene), "--count", "1", "--out", str(out / "r.h5")]) == 2
    )
    assert "'paper_8x8': the RTIS link carries at most 32 microphones" in capsys.readouterr().err


def test_the_names_comparison_held_still_import_from_it():
    """comparison.py was split into a module a step: every public name it held imports
    from it (and from the package) as the one object of its new module."""
    import importlib

    moved = {
        "alignment": ("Alignment", "DIRECT_WINDOW_S", "align", "envelope"),
        "comparable": ("CALL_RTOL", "ComparisonError", "check_comparable", "same_call"),
        "echoes": ("MIN_ECHO_ABOVE_FLOOR_DB", "MatchedEcho", "RejectedPair", "above_floor"),
        "echo_table": ("MethodComparison",),
        "figure": ("COMPARISON_RANGE_DB", "comparison_figure"),
        "lobes": ("SideLobe", "array_response_db", "side_lobes"),
        "peaks": ("MatchTolerance", "Peak", "match_peaks"),
        "report": ("Comparison", "ComparisonArrays"),
        "account": ("floor_start", "noise_floor"),
    }
    old = importlib.import_module("acousim.compare.comparison")
    package = importlib.import_module("acousim.compare")
    for module, names in moved.items():
        new = importlib.import_module(f"acousim.compare.{module}")
        for name in names:
            assert getattr(old, name) is getattr(new, name), name
            assert getattr(package, name) is getattr(new, name), name
    for name in old.__all__:
        assert getattr(package, name) is getattr(old, name)
