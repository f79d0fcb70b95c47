"""A perfectly specular wall (diffuse fraction 0, the bundled ``wall`` scene's
implicit default material) recovered from repeated recordings of its one pose, at
any SNR up to noise-free; the truth is written here, never read from the code under
test.

The diffuse fraction is fitted through its amplitude ``u = sqrt(d)`` so that it
reaches 0: a floor on d (it was 1e-4) leaves a Lambert tail 40 dB under the echo
that stands above the noise of a clean recording, and the fit lowered the
reflection to hide it (0.485 at 30 dB SNR, 0.08 at 50 dB, 0.001 noise-free, for a
truth of 0.6)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from acousim.bundled import find_scene
from acousim.calibrate import calibrate
from acousim.calibrate.fit import group_factor_derivatives, group_factors
from acousim.calibrate.parameters import MaterialFit, ParameterSet
from acousim.scene.load import load_scene
from acousim.scene.model import Material
from acousim.simulator import Simulator

TRUE_REFLECTION = 0.6
SEEDS = (1, 2, 3)


def _wall():
    return load_scene(find_scene("wall"))


def _recordings(snr_db: float, diffuse: float = 0.0) -> list:
    """The wall at the true material, one recording per seed."""
    wall = _wall()
    (mesh,) = wall.meshes
    material = dataclasses.replace(mesh.material, reflection=TRUE_REFLECTION, diffuse=diffuse)
    truth = dataclasses.replace(mesh, material=material)
    recs = []
    for seed in SEEDS:
        sim = dataclasses.replace(wall.simulation, snr_db=snr_db, seed=seed)
        (rec,) = Simulator(dataclasses.replace(wall, meshes=(truth,), simulation=sim)).run()
        recs.append(rec)
    return recs


@pytest.mark.filterwarnings("error::RuntimeWarning")  # no overflow on the way
@pytest.mark.parametrize("snr_db", [30.0, 60.0, float("inf")])
def test_specular_wall_reflection_recovered(snr_db):
    """Started from the bundled 0.95 / 0: reflection within 0.03 of 0.6, the
    diffuse fraction at 0, and no bin the fitted wall leaves unexplained."""
    cal = calibrate(_wall(), _recordings(snr_db), [0, 0, 0])
    got = cal.materials["default"]
    assert got.reflection == pytest.approx(TRUE_REFLECTION, abs=0.03)
    assert got.diffuse < 1e-3
    assert cal.unexplained == ()
    assert cal.rms_db_after < cal.rms_db_before
    assert np.all(np.isfinite(cal.noise_db))


@pytest.mark.parametrize("snr_db", [60.0, float("inf")])
def test_a_little_diffuse_is_resolved(snr_db):
    """A wall with 1 % of its energy diffuse: the fraction found within 0.003."""
    cal = calibrate(_wall(), _recordings(snr_db, diffuse=0.01), [0, 0, 0])
    got = cal.materials["default"]
    assert got.reflection == pytest.approx(TRUE_REFLECTION, abs=0.03)
    assert got.diffuse == pytest.approx(0.01, abs=0.003)


def _parameter_set() -> ParameterSet:
    """Two materials: a single number (R, d) and a table over 25 / 50 kHz, seen in
    three bands (one below, one between, one above the table's points)."""
    one = MaterialFit.start(Material("a", 0.8, 0.0))
    table = MaterialFit.start(Material("b", (0.9, 0.5), (0.3, 0.0), 5.0, (25.0, 50.0)))
    return ParameterSet((one, table), np.array([20e3, 40e3, 60e3]))


def test_gains_are_the_materials_coefficients():
    """a = R sqrt(1 - d), b = R sqrt(d), d = u^2 at the table points and linear in
    frequency between them (written here); a diffuse fraction of 0 gives b = 0."""
    params = _parameter_set()
    # R_a, u_a, R_b(25), R_b(50), u_b(25), u_b(50)
    theta = np.array([0.7, 0.0, 0.9, 0.5, 0.4, 0.0])
    g, _ = params.gains(theta)
    R_b = np.array([0.9, 0.9 - 0.4 * 15 / 25, 0.5])
    d_b = np.array([0.16, 0.16 * (1 - 15 / 25), 0.0])
    assert g[:, 0] == pytest.approx([0.7] * 3)
    assert g[:, 1] == pytest.approx([0.0] * 3, abs=0)
    assert g[:, 2] == pytest.approx(R_b * np.sqrt(1 - d_b))
    assert g[:, 3] == pytest.approx(R_b * np.sqrt(d_b))


@pytest.mark.parametrize("u_b50", [0.0, 0.2])
def test_gain_derivatives_are_finite_and_exact_at_zero_diffuse(u_b50):
    """The derivatives of the gains and of the groups' factors against one-sided
    differences (the amplitudes start on their bound 0), where d = 0 makes the
    derivative of sqrt(d) infinite."""
    params = _parameter_set()
    theta = np.array([0.7, 0.0, 0.9, 0.5, 0.4, u_b50])
    counts = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 1, 0], [0, 1, 0, 1], [0, 0, 2, 1]])
    g, dg = params.gains(theta)
    w, dw = group_factors(counts, g), group_factor_derivatives(counts, g, dg)
    assert np.all(np.isfinite(dg)) and np.all(np.isfinite(dw))
    # a factor is the product of the gains to the counts' powers
    assert w == pytest.approx(np.prod(g[None] ** counts[:, None, :], axis=-1))
    assert w[1] == pytest.approx([0.0] * 3, abs=0)  # met a perfectly specular one diffusely
    h = 1e-7
    for p in range(theta.size):
        e = np.zeros(theta.size)
        e[p] = h
        g1, _ = params.gains(theta + e)
        fd = (group_factors(counts, g1) - w) / h
        assert dw[..., p] == pytest.approx(fd, abs=1e-5), p
        assert dg[..., p] == pytest.approx((g1 - g) / h, abs=1e-5), p


def test_diffuse_sigma_is_the_spread_of_a_squared_normal():
    """d = u^2 with u ~ N(u0, s): the reported sigma against a seeded Monte Carlo."""
    params = _parameter_set()
    rng = np.random.default_rng(5)
    for u0, s in ((0.0, 0.05), (0.3, 0.05)):
        theta = np.array([0.7, u0, 0.9, 0.5, 0.4, 0.0])
        sigma = np.array([0.01, s, 0.0, 0.0, 0.0, 0.0])
        value, spread = params.public(theta, sigma)
        draws = rng.normal(u0, s, 400_000) ** 2
        assert value[1] == pytest.approx(u0**2)
        assert spread[1] == pytest.approx(np.std(draws), rel=0.01)
        assert spread[0] == 0.01  # a reflection's as it is
