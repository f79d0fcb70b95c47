"""A calibration's report says what its numbers cannot be trusted for: values on a
bound, parameters the recordings do not determine, a level that is unknown (real or
emulated recordings) or confounded with a reflection (``--fit-level``).

The expectations are built here from the physics of the model, never read from the
code under test: an echo's energy is ``L R^2`` times the traced one (one bounce), so
d E / d log L and d E / d R are proportional columns (a correlation of exactly +1)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from acousim.bundled import find_scene
from acousim.calibrate import CalibrationSettings, calibrate
from acousim.calibrate.diagnose import diagnose
from acousim.calibrate.scenefile import WARNING_PREFIX, with_warnings
from acousim.scene.load import load_scene
from acousim.simulator import Simulator

NAMES = ["wall.reflection", "wall.diffuse"]
LO, HI = np.array([1e-3, 0.0]), np.array([1.0, 0.999])


def _toy_jacobian() -> np.ndarray:
    """d log E / d x of ``E(t) = R^2 f(t) + d g(t) + n`` at R = 0.5, d = 0.1,
    n = 1e-3 (f: a specular echo, g: a diffuse tail; independent shapes), columns
    R, d, log n: written out by hand."""
    t = np.linspace(0, 1, 400)
    f, g = np.exp(-((t - 0.3) ** 2) / 0.002), np.exp(-3 * t) * (t > 0.3)
    R, d, n = 0.5, 0.1, 1e-3
    E = R**2 * f + d * g + n
    cols = [2 * R * f / E, g / E, n / E]
    return np.stack(cols, axis=1)


def _diagnose(jac, value=(0.5, 0.1), sigma=(0.01, 0.01), **kw):
    return diagnose(
        names=NAMES,
        value=np.array(value),
        sigma=np.array(sigma),
        bounds=(LO, HI),
        jacobian=jac,
        all_names=[*NAMES, "noise[0]"],
        **kw,
    )


def test_a_determined_fit_warns_of_nothing():
    assert _diagnose(_toy_jacobian(), kinds=["simulated"]) == ()


def test_a_value_on_its_bound_is_named_with_its_value():
    (w,) = _diagnose(_toy_jacobian(), value=(1.0, 0.1))
    assert w.kind == "at_bound" and w.parameters == ("wall.reflection",)
    assert "wall.reflection = 1 is at its upper bound 1" in w.message
    assert "sigma is not meaningful" in w.message
    (w,) = _diagnose(_toy_jacobian(), value=(0.5, 0.005))  # within 1 % of 0..0.999
    assert "wall.diffuse = 0.005 is at its lower bound 0" in w.message


def test_a_sigma_wider_than_the_range_is_undetermined():
    (w,) = _diagnose(_toy_jacobian(), sigma=(0.01, 1.624))
    assert w.kind == "undetermined" and w.parameters == ("wall.diffuse",)
    assert "sigma 1.62 is larger than its whole range 0..0.999" in w.message


def test_a_level_and_a_reflection_of_one_bounce_are_confounded():
    """With the level fitted, R and L enter only as L R^2 in the echo: their columns
    are proportional (d E / d R = (2 / R) d E / d log L on the echo alone)."""
    t = np.linspace(0, 1, 400)
    f = np.exp(-((t - 0.3) ** 2) / 0.002)
    E = 0.25 * f + 1e-3
    jac = np.stack([2 * 0.5 * f / E, 1e-3 / E, 0.25 * f / E], axis=1)
    out = diagnose(
        names=["wall.reflection"],
        value=np.array([0.5]),
        sigma=np.array([0.004]),
        bounds=(LO[:1], HI[:1]),
        jacobian=jac,
        all_names=["wall.reflection", "noise[0]", "level"],
        kinds=["emulated"],
    )
    (w,) = [w for w in out if w.kind == "level_confounded"]
    assert w.parameters == ("level", "wall.reflection")
    assert "confounded with wall.reflection (correlation +1.000)" in w.message
    assert not [w for w in out if w.kind == "level_unknown"]


def test_recordings_not_simulated_ask_for_the_level():
    (w,) = _diagnose(_toy_jacobian(), kinds=["real", "real"])
    assert w.kind == "level_unknown"
    assert "the recordings are real, not simulated" in w.message and "--fit-level" in w.message


def test_warnings_head_the_file_and_replace_an_earlier_calibrations():
    text = "[scene]\nname = 'x'\n"
    once = with_warnings(text, ["a is at its bound"])
    assert once == f"{WARNING_PREFIX}a is at its bound\n{text}"
    assert with_warnings(once, ["b"]) == f"{WARNING_PREFIX}b\n{text}"


def _wall_recordings(kind: str) -> tuple:
    """The bundled wall (one pose, one bounce) at reflection 0.6, diffuse 0, 60 dB
    SNR, two seeds, marked as recorded by a sensor of `kind`."""
    wall = load_scene(find_scene("wall"))
    (mesh,) = wall.meshes
    truth = dataclasses.replace(
        mesh, material=dataclasses.replace(mesh.material, reflection=0.6, diffuse=0.0)
    )
    recs = []
    for seed in (1, 2):
        sim = dataclasses.replace(wall.simulation, snr_db=60.0, seed=seed)
        (rec,) = Simulator(dataclasses.replace(wall, meshes=(truth,), simulation=sim)).run()
        recs.append(dataclasses.replace(rec, metadata={**rec.metadata, "provenance": kind}))
    return wall, recs


def test_emulated_recordings_warn_of_the_level_and_fit_level_names_the_reflection():
    wall, recs = _wall_recordings("emulated")
    cal = calibrate(wall, recs, [0, 0])
    kinds = {w.kind: w for w in cal.warnings}
    assert "level_unknown" in kinds and "emulated" in kinds["level_unknown"].message
    # the truth's diffuse fraction, 0, is the bound: said so
    assert any(w.parameters == ("default.diffuse",) for w in cal.warnings if w.kind == "at_bound")
    assert "warning: the recordings are emulated" in cal.summary()
    assert cal.to_dict()["warnings"][0]["kind"] in kinds
    fl = calibrate(wall, recs, [0, 0], CalibrationSettings(fit_level=True))
    (w,) = [w for w in fl.warnings if w.kind == "level_confounded"]
    assert "default.reflection" in w.parameters
    assert not [w for w in fl.warnings if w.kind == "level_unknown"]


def test_simulated_recordings_do_not_ask_for_the_level():
    wall, recs = _wall_recordings("simulated")
    cal = calibrate(wall, recs, [0, 0])
    assert cal.materials["default"].reflection == pytest.approx(0.6, abs=0.03)
    assert not [w for w in cal.warnings if w.kind.startswith("level")]


def test_a_fit_stopped_at_its_cap_says_so(tmp_path):
    """One evaluation cannot reach the truth from 0.95: the report says the solver
    stopped at its cap of 1, naming the setting."""
    wall, recs = _wall_recordings("simulated")
    cal = calibrate(wall, recs, [0, 0], CalibrationSettings(max_evaluations=1))
    (w,) = [w for w in cal.warnings if w.kind == "not_converged"]
    assert "stopped at its cap of 1 evaluations (--max-evaluations" in w.message
    assert w.parameters == ("default.reflection", "default.diffuse")
