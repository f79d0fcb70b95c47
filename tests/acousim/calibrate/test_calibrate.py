"""Scene and array calibration: closed loops on simulated recordings, the truth
written here, never read from the code under test."""

from __future__ import annotations

import dataclasses
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import hilbert

import processing as P
from acousim.calibrate import CalibrationSettings, calibrate, write_scene
from acousim.calibrate.features import Directions, FeatureSpace
from acousim.scene.load import load_scene
from acousim.synth.options import Noise
from acousim.synth.point_reflectors import PointReflectors
from acousim.synth.signal_model import simulate_points
from processing.base.errors import InputError
from tests import REPO
from tests.oracles import corridor_cabinet

ROOT = REPO
POSES = [0, 12, 24, 36, 48]
# the truth the fit never sees
PLASTER = (0.70, 0.35)
METAL = (0.90, 0.05)
TABLE_KHZ = (25.0, 37.5, 50.0)
TABLE_R = (0.85, 0.70, 0.50)


def _truth(tmp: Path, name: str, plaster: str, extra: str = "") -> list[P.Recording]:
    metal = f"reflection = {METAL[0]}\ndiffuse = {METAL[1]}"
    return corridor_cabinet.simulate_truth(
        tmp / name, POSES, plaster=plaster, metal=metal, extra=extra
    )


@pytest.fixture(scope="module")
def corridor(tmp_path_factory):
    tmp = corridor_cabinet.folder(tmp_path_factory.mktemp("corridor"))
    recs = _truth(tmp, "truth.toml", f"reflection = {PLASTER[0]}\ndiffuse = {PLASTER[1]}")
    return tmp, recs


def test_materials_recovered_from_five_noisy_poses(corridor):
    """The plaster (every echo) is pinned; the cabinet is not: from these poses it
    returns no specular echo (only its diffuse tail, 30-41 dB under each pose's echo
    energy, and its edges' diffraction), so its reflection is known to its sigma and
    its diffuse fraction (0.05, under the 30 dB noise) not at all.  Measured over
    truth seeds 1-4, diffraction on and off: plaster within 0.009 / 0.007, metal
    reflection within 0.083 (0.046 here), metal diffuse 0 or 0.045."""
    tmp, recs = corridor
    start = load_scene(tmp / "start.toml")
    cal = calibrate(start, recs, POSES)
    got = cal.materials
    assert abs(got["plaster"].reflection - PLASTER[0]) < 0.015
    assert abs(got["plaster"].diffuse - PLASTER[1]) < 0.015
    assert abs(got["metal"].reflection - METAL[0]) < 0.05
    assert abs(got["metal"].reflection - METAL[0]) < 3 * cal.material_sigma["metal"][0]
    assert 0.0 <= got["metal"].diffuse < 0.10  # not identifiable from these poses
    assert cal.rms_db_after < cal.rms_db_before
    # the report: every parameter, the residual per range bin
    assert [p.name for p in cal.parameters] == [
        "plaster.reflection",
        "plaster.diffuse",
        "metal.reflection",
        "metal.diffuse",
    ]
    assert cal.residual_db_after.shape == cal.range_m.shape
    assert cal.lag_samples == pytest.approx([0.0] * 5, abs=0.05)

    # the fitted scene: the input's text but the fitted values, each with its sigma
    out = write_scene(tmp / "start.toml", tmp / "fitted.toml", cal)
    before = (tmp / "start.toml").read_text().splitlines()
    lines = out.read_text().splitlines()
    # the warnings head the file (the metal's diffuse fraction, 0.05 under the noise,
    # lands on its bound 0), one comment line each
    notes = [x for x in lines if x.startswith("# acousim calibrate warning: ")]
    assert len(notes) == len(cal.warnings)
    assert any("metal.diffuse" in x and "lower bound 0" in x for x in notes)
    after = lines[len(notes) :]
    changed = [a for a, b in zip(before, after) if a != b]
    assert len(before) == len(after)
    assert all(line.split("=")[0].strip() in ("reflection", "diffuse") for line in changed)
    assert len(changed) == 4
    assert all("+-" in b and "acousim calibrate" in b for a, b in zip(before, after) if a != b)
    assert "# a guess" in out.read_text()  # comments kept
    fitted = load_scene(out)
    for name in ("plaster", "metal"):
        assert fitted.materials[name].reflection == pytest.approx(got[name].reflection, rel=1e-3)
    # only reflection and diffuse: a parameter list that names one
    one = calibrate(
        start, recs[:1], POSES[:1], CalibrationSettings(parameters=("plaster.reflection",))
    )
    assert [p.name for p in one.parameters] == ["plaster.reflection"]


def test_scene_lacking_an_echo_reports_it(tmp_path):
    """A post the scene lacks: the fit holds, the report names its range."""
    tmp = corridor_cabinet.folder(tmp_path)
    post = "\n[[points]]\nposition_m = [3.0, -0.5, 0.45]\nstrength = 0.3\n"
    plaster = f"reflection = {PLASTER[0]}\ndiffuse = {PLASTER[1]}"
    recs = _truth(tmp, "truth.toml", plaster, post)[:3]
    cal = calibrate(load_scene(tmp / "start.toml"), recs, POSES[:3])
    assert abs(cal.materials["plaster"].reflection - PLASTER[0]) < 0.05
    assert abs(cal.materials["plaster"].diffuse - PLASTER[1]) < 0.10
    # the post's range from pose k: |(3, -0.5, 0.45) - sensor position|
    rows = np.loadtxt(ROOT / "scenes/corridor_drive.csv", delimiter=",", comments="#")
    for k, i in enumerate(POSES[:3]):
        r = np.linalg.norm(np.array([3.0, -0.5, 0.45]) - rows[i, :3])
        hits = [u for u in cal.unexplained if u.recording == k and abs(u.range_m - r) < 0.15]
        assert hits, (k, r, cal.unexplained)
        assert hits[0].azimuth_deg < 0  # to the right


def test_material_table_within_1_db(tmp_path):
    tmp = corridor_cabinet.folder(tmp_path)
    table = (
        f"frequencies_khz = {list(TABLE_KHZ)}\nreflection = {list(TABLE_R)}\ndiffuse = {PLASTER[1]}"
    )
    recs = _truth(tmp, "truth_table.toml", table)
    settings = CalibrationSettings(tables={"plaster": TABLE_KHZ})
    cal = calibrate(load_scene(tmp / "start.toml"), recs, POSES, settings)
    got = cal.materials["plaster"]
    assert got.frequencies_khz == TABLE_KHZ
    err_db = 20 * np.log10(np.array(got.reflection) / np.array(TABLE_R))
    assert np.all(np.abs(err_db) < 1.0), err_db
    out = write_scene(tmp / "start.toml", tmp / "fitted.toml", cal)
    plaster = next(m for m in tomllib.loads(out.read_text())["materials"] if m["name"] == "plaster")
    assert plaster["frequencies_khz"] == list(TABLE_KHZ)
    assert len(plaster["reflection"]) == 3


def test_noise_energy_per_bin_matches_its_closed_form():
    """White noise of variance s^2: mean energy per bin = s^2 * noise_unit."""
    arr, wf = P.urtis_v1(), P.rtis_call("default_25_50")
    rng = np.random.default_rng(7)
    x = rng.normal(0, 2.0, (arr.n_mics, 8192))
    rec = P.Recording(x, 450e3, arr, wf)
    space = FeatureSpace(rec, bands=2, directions=Directions((-30.0, 0.0, 30.0), (0.0,)))
    E = space.energies(space.envelopes(x))  # (B, D, R)
    ratio = E / (4.0 * space.noise_unit[:, None, :])
    assert np.mean(ratio) == pytest.approx(1.0, abs=0.05)


def test_bad_parameter_is_named(corridor):
    tmp, recs = corridor
    with pytest.raises(InputError, match="parameters"):
        calibrate(
            load_scene(tmp / "start.toml"),
            recs[:1],
            POSES[:1],
            CalibrationSettings(parameters=("brick",)),
        )


def _mismatch(x, gain_db, phase_rad, delay_s, fs):
    """Each channel's analytic signal times g e^{i phi}, real part, then delayed
    (written here, apart from processing.sensor.calibration)."""
    T = x.shape[-1]
    a = hilbert(x, N=4 * T, axis=-1)
    y = (10 ** (gain_db / 20))[:, None] * np.real(np.exp(1j * phase_rad)[:, None] * a)
    f = np.fft.rfftfreq(4 * T, 1 / fs)
    return np.fft.irfft(np.fft.rfft(y, axis=-1) * np.exp(-2j * np.pi * f * delay_s), axis=-1)[:, :T]


def _relative(gain_db, phase_rad):
    u = np.exp(1j * phase_rad)
    p = np.angle(u * np.conj(u.sum()))
    return gain_db - gain_db.mean(), p - p.mean()


@pytest.mark.parametrize("array", ["urtis_v1", "ertis_v3d1"])
def test_microphone_gains_and_phases(array):
    arr, wf, fs = P.preset(array), P.rtis_call("default_25_50"), 450e3
    where = np.array([2.2, -0.4, 0.3])
    rec = simulate_points(
        PointReflectors(where[None], np.array([1.0])), arr, wf, fs, 8192, noise=Noise(20.0, 11)
    )
    rng = np.random.default_rng(2027)
    g = rng.uniform(-2, 2, arr.n_mics)
    ph = np.deg2rad(rng.uniform(-20, 20, arr.n_mics))
    bad = rec.with_samples(_mismatch(rec.samples, g, ph, 31e-6, fs))
    fit = P.fit_array_calibration(bad, where)
    cal = fit.calibration
    tg, tp = _relative(g, ph)
    assert np.max(np.abs(np.array(cal.gain_db) - tg)) < 0.2
    assert np.rad2deg(np.max(np.abs(np.array(cal.phase_rad) - tp))) < 2.0
    assert cal.delay_s == pytest.approx(31e-6, abs=0.5e-6)
    # corrected, the channels match the clean simulation up to one common gain/phase
    fixed = P.apply_calibration(bad, cal).samples
    c = np.vdot(hilbert(rec.samples), hilbert(fixed)) / np.vdot(
        hilbert(rec.samples), hilbert(rec.samples)
    )
    err = np.linalg.norm(fixed - np.real(c * hilbert(rec.samples))) / np.linalg.norm(fixed)
    assert err < 0.2  # the noise (20 dB) dominates what is left


def test_calibration_in_the_file_is_applied_once(tmp_path):
    arr, wf = P.urtis_v1(), P.rtis_call("default_25_50")
    rng = np.random.default_rng(3)
    rec = P.Recording(rng.normal(size=(arr.n_mics, 4096)).astype(np.float32), 450e3, arr, wf)
    cal = P.ArrayCalibration(
        tuple(rng.uniform(-1, 1, arr.n_mics)), tuple(rng.uniform(-0.3, 0.3, arr.n_mics)), 5e-6
    )
    path = P.save_recording(tmp_path / "raw.h5", P.attach_calibration(rec, cal))
    loaded = P.load_recording(path)
    expected = P.apply_calibration(rec, cal)
    assert np.allclose(loaded.samples, expected.samples, atol=1e-5)
    assert loaded.metadata["array_calibration"]["applied"] is True
    again = P.load_recording(P.save_recording(tmp_path / "again.h5", loaded))
    assert np.array_equal(again.samples, loaded.samples)  # not applied twice
    restored = P.ArrayCalibration.from_dict(loaded.metadata["array_calibration"])
    assert np.allclose(restored.phase_rad, cal.phase_rad)
    broken = dataclasses.replace(rec, metadata={"array_calibration": {"gain_db": [0.0]}})
    bad = P.save_recording(tmp_path / "bad.h5", broken)
    with pytest.raises(InputError, match="bad.h5"):
        P.load_recording(bad)


def test_command_line(corridor, capsys):
    from acousim.cli import main

    tmp, recs = corridor
    P.save_recordings(tmp / "truth.h5", recs[:2])
    code = main(
        [
            "calibrate",
            str(tmp / "truth.h5"),
            "--scene",
            str(tmp / "start.toml"),
            "--out",
            str(tmp / "cli.toml"),
            "--poses",
            "0,12",
            "--param",
            "plaster",
            "--report",
            str(tmp / "cli.json"),
        ]
    )
    assert code == 0
    said = capsys.readouterr()
    text = said.out
    assert "plaster.reflection" in text and "metal" not in text.split("range_m")[0]
    # not a terminal: one line on stderr when the two poses are traced and rendered
    assert re.fullmatch(r"calibrate: 2/2 poses in [\d.]+ s \(.*\)\n", said.err), said.err
    fitted = load_scene(tmp / "cli.toml")
    assert abs(fitted.materials["plaster"].reflection - PLASTER[0]) < 0.05
    assert fitted.materials["metal"].reflection == 0.99  # not fitted: as it was
    import json

    report = json.loads((tmp / "cli.json").read_text())
    assert report["rms_db_after"] < report["rms_db_before"]


def test_jacobian_is_the_derivative(corridor):
    """The analytic Jacobian against central differences of the residuals."""
    from acousim.calibrate.fit import Problem
    from acousim.calibrate.groups import GroupModel
    from acousim.calibrate.parameters import MaterialFit, ParameterSet
    from acousim.calibrate.run import _observe

    tmp, recs = corridor
    scene = load_scene(tmp / "start.toml")
    fits = (
        MaterialFit.start(scene.materials["plaster"], (25.0, 50.0)),
        MaterialFit.start(scene.materials["metal"]),
    )
    space = FeatureSpace(recs[0], bands=3, directions=Directions((-20.0, 20.0), (0.0,)))
    params = ParameterSet(fits, space.band_hz)
    model = GroupModel(scene, fits)
    groups, measured, _ = _observe(model, params, space, recs[:2], POSES[:2], True)
    problem = Problem(params, space, tuple(groups), tuple(measured), model.log_reference, True)
    x = problem.start() + np.array([-0.2, -0.1, 0.1, 0.15, -0.05, 0.05, 0.3, -0.2, 0.1])
    J = problem.jacobian(x)
    for k in range(x.size):
        h = 1e-4 * max(1.0, abs(x[k]))
        e = np.zeros_like(x)
        e[k] = h
        fd = (problem.residuals(x + e) - problem.residuals(x - e)) / (2 * h)
        err = np.max(np.abs(fd - J[:, k])) / np.max(np.abs(fd))
        assert err < 5e-3, k  # the envelopes are single precision: ~1e-3 measured


def test_find_echo_finds_the_reflector():
    arr, wf, fs = P.urtis_v1(), P.rtis_call("default_25_50"), 450e3
    where = np.array([2.0, 0.35, -0.2])
    rec = simulate_points(
        PointReflectors(where[None], np.array([1.0])), arr, wf, fs, 8192, noise=Noise(30.0, 4)
    )
    found = P.find_echo(rec, 1.0, 3.0)
    assert np.linalg.norm(found) == pytest.approx(np.linalg.norm(where), abs=0.03)
    cos = found @ where / np.linalg.norm(found) / np.linalg.norm(where)
    assert np.rad2deg(np.arccos(min(cos, 1.0))) < 2.0  # the image's 2 degree grid


def test_time_offset_is_found_and_removed(corridor):
    """Recordings that start 7.3 samples late: the lag is found, the fit holds."""
    tmp, recs = corridor
    late = []
    for r in recs[:3]:
        n = 2 * r.n_samples
        f = np.fft.rfftfreq(n)
        x = np.fft.irfft(np.fft.rfft(r.samples, n) * np.exp(-2j * np.pi * f * 7.3), n)
        late.append(r.with_samples(x[:, : r.n_samples]))
    cal = calibrate(load_scene(tmp / "start.toml"), late, POSES[:3])
    assert cal.lag_samples == pytest.approx([7.3] * 3, abs=0.1)
    assert abs(cal.materials["plaster"].reflection - PLASTER[0]) < 0.05
    assert abs(cal.materials["plaster"].diffuse - PLASTER[1]) < 0.10


def test_a_bundled_scenes_repeated_measurements_fit_into_a_file_anywhere(tmp_path, capsys):
    """Three recordings of the bundled wall scene's one pose, saying no pose (as the
    sensor or its emulator records them): fitted from the bundled scene as it is
    (every recording at its one pose, no --poses needed), the fitted scene written
    to another folder loads there (its mesh found through a path from that folder)
    and holds the fitted reflection, 0.6 as simulated, of the material the file left
    implicit (a ``default`` block added)."""
    from acousim.bundled import find_scene
    from acousim.cli import main
    from acousim.simulator import Simulator

    wall = load_scene(find_scene("wall"))
    (mesh,) = wall.meshes
    truth = dataclasses.replace(mesh, material=dataclasses.replace(mesh.material, reflection=0.6))
    recs = []
    for seed in (1, 2, 3):  # with noise, as measured
        sim = dataclasses.replace(wall.simulation, snr_db=30.0, seed=seed)
        (rec,) = Simulator(dataclasses.replace(wall, meshes=(truth,), simulation=sim)).run()
        meta = {k: v for k, v in rec.metadata.items() if k != "pose_index"}
        recs.append(dataclasses.replace(rec, metadata=meta))
    P.save_recordings(tmp_path / "r.h5", recs)
    out = tmp_path / "elsewhere" / "fitted.toml"
    out.parent.mkdir()
    args = ["calibrate", str(tmp_path / "r.h5"), "--scene", "wall", "--out", str(out)]
    assert main(args) == 0, capsys.readouterr().err
    said = capsys.readouterr().out
    (line,) = [x for x in said.splitlines() if x.startswith("default.reflection")]
    fitted_value = float(line.split()[2])
    assert fitted_value == pytest.approx(0.6, abs=0.03)  # the wall's, as simulated
    fitted = load_scene(out)
    assert fitted.meshes[0].material.reflection == pytest.approx(fitted_value, abs=1e-3)
    assert Path(fitted.meshes[0].mesh).samefile(mesh.mesh)  # the bundled mesh file
    assert not (out.parent / "meshes").exists()  # pointed to, not copied


def test_a_scene_without_a_mesh_is_refused_in_one_line(tmp_path, capsys):
    """The bundled points scene (point reflectors alone) has no material to fit:
    one line naming the scene file, exit code 2 (it was a traceback)."""
    from acousim.bundled import find_scene
    from acousim.cli import main
    from acousim.simulator import Simulator

    (rec,) = Simulator(load_scene(find_scene("points"))).run()
    P.save_recordings(tmp_path / "p.h5", [rec])
    args = ["calibrate", str(tmp_path / "p.h5"), "--scene", "points"]
    assert main([*args, "--out", str(tmp_path / "f.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "points.toml" in err, err
    assert "no material to fit" in err and not (tmp_path / "f.toml").exists()
