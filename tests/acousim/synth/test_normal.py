"""Standard normal draws (:mod:`acousim.synth.normal`): numpy's values bit for bit and
numpy's state after, through the compiled kernel and through numpy's own call (the
fallback); the ziggurat tables against their construction."""

from __future__ import annotations

import math

import numpy as np
import pytest

import acousim.synth.normal as normal
from acousim.synth.noise import add_noise
from acousim.synth.normal import standard_normal, ziggurat_tables
from processing.base.kernels import optional_kernel

R = 3.6541528853610088  # the ziggurat's r: beyond it, the base layer's tail


def _kernel_or_skip():
    if optional_kernel("acousim.synth._normal_kernel") is None:
        pytest.skip("numba not installed")


def _same_as_numpy(seed: int, shape, prepare=None) -> np.ndarray:
    """Asserts that standard_normal and numpy draw the same bits from `seed` (after
    `prepare(rng)`) and leave the same state (the next draws the same); numpy's draws."""
    ours, theirs = np.random.default_rng(seed), np.random.default_rng(seed)
    if prepare is not None:
        prepare(ours), prepare(theirs)
    a, b = standard_normal(ours, shape), theirs.standard_normal(shape)
    assert a.shape == b.shape and a.dtype == b.dtype == np.float64
    assert np.array_equal(a.view(np.uint64), b.view(np.uint64))
    assert ours.bit_generator.state == theirs.bit_generator.state
    assert np.array_equal(ours.standard_normal(7), theirs.standard_normal(7))
    assert np.array_equal(ours.random(3), theirs.random(3))
    return b


@pytest.mark.parametrize(
    "seed, shape", [(2, (30, 1800)), (3, (2, 3, 4)), (4, ()), (5, 0), (6, (1,)), (7, 777)]
)
def test_the_kernel_draws_numpy_s_values_and_leaves_numpy_s_state(seed, shape):
    _kernel_or_skip()
    _same_as_numpy(seed, shape)


def test_the_rare_paths_draw_numpy_s_values():
    """Seed 1's first 5000 draws take the tail 3 times (once rejecting a pair of
    uniforms) and reject 30 wedge attempts: counted by benchmarks.normal_draws' walk."""
    _kernel_or_skip()
    b = _same_as_numpy(1, (5000,))
    assert np.count_nonzero(np.abs(b) > R) == 3  # the tail's draws, beyond r


def test_a_generator_with_a_buffered_half_word_keeps_it():
    _kernel_or_skip()
    b = _same_as_numpy(8, (3, 100), lambda rng: rng.integers(0, 10, dtype=np.int32))
    assert b.size == 300


@pytest.mark.parametrize(
    "bits", [np.random.PCG64DXSM, np.random.Philox, np.random.MT19937, np.random.SFC64]
)
def test_other_bit_generators_draw_through_numpy(bits):
    ours, theirs = np.random.Generator(bits(9)), np.random.Generator(bits(9))
    assert np.array_equal(standard_normal(ours, (4, 50)), theirs.standard_normal((4, 50)))
    assert np.array_equal(ours.bit_generator.random_raw(9), theirs.bit_generator.random_raw(9))


@pytest.mark.parametrize("missing", ["kernel", "tables"])
def test_without_the_kernel_or_its_tables_numpy_draws(monkeypatch, missing):
    if missing == "kernel":
        monkeypatch.setattr(normal, "optional_kernel", lambda *a: None)
    else:
        monkeypatch.setattr(normal, "ziggurat_tables", lambda: None)
    _same_as_numpy(1, (5000,))


def test_the_tables_are_the_ziggurat_s_construction():
    """x_i = 2**52 w_i: x_255 = r; every layer above the base has the area
    v = r f(r) + int_r^inf f (f(x) = exp(-x^2 / 2)), as has the base layer x_0 f(r);
    k_i ~ 2**52 x_(i-1) / x_i; f_i = f(x_i)."""
    w, k, f = ziggurat_tables()
    x = w * 2.0**52
    assert x[255] == R and np.all(np.diff(x[1:]) > 0) and k[1] == 0
    v = R * math.exp(-R * R / 2) + math.sqrt(math.pi / 2) * math.erfc(R / math.sqrt(2))
    density = np.exp(-(np.concatenate([[0.0], x[1:]]) ** 2) / 2)  # f(0), f(x_1), ...
    areas = x[1:] * (density[:-1] - density[1:])  # layer i: x_i (f(x_(i-1)) - f(x_i))
    assert areas == pytest.approx(np.full(255, v), rel=1e-13)
    assert x[0] * math.exp(-R * R / 2) == pytest.approx(v, rel=1e-14)
    ratios = np.concatenate([[R / x[0]], x[1:-1] / x[2:]])
    assert k[np.r_[0, 2:256]] / 2.0**52 == pytest.approx(ratios, rel=1e-15, abs=0)
    assert f[0] == 1.0 and f[1:] == pytest.approx(np.exp(-(x[1:] ** 2) / 2), rel=1e-15)


def test_noise_is_sigma_times_numpy_s_draws_plus_the_signal():
    clean = np.random.default_rng(0).normal(size=(3, 400))
    out = add_noise(clean, 0.25, np.random.default_rng(12), 2)
    expected = np.random.default_rng(12).standard_normal((2, 3, 400)) * 0.25 + clean
    assert np.array_equal(out, expected)
