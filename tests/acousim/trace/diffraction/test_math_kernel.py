"""The compiled edge-to-edge integral's branch-free log, log1p, exp, expm1, atan and
cos (:mod:`acousim.trace.diffraction.math_kernel`) against numpy's (the C library's)
over the ranges the integral uses, and at their ends."""

from __future__ import annotations

import numpy as np
import pytest

numba = pytest.importorskip("numba")

from acousim.trace.diffraction import math_kernel as mk  # noqa: E402
from acousim.trace.diffraction.pair_kernel import _atan2  # noqa: E402

ULPS = 4 * np.finfo(float).eps  # a few ulp, relative


@numba.njit
def _apply(f, x, out):  # pragma: no cover - compiled
    for i in range(x.size):
        out[i] = f(x[i])


def apply(f, x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    _apply(f, np.ascontiguousarray(x, float), out)
    return out


def relative(got: np.ndarray, ref: np.ndarray) -> float:
    scale = np.where(ref == 0, 1.0, np.abs(ref))
    return float(np.max(np.abs(got - ref) / scale))


RNG = np.random.default_rng(11)


def test_log_over_the_doubles():
    x = np.concatenate(
        [
            np.exp(RNG.uniform(-700, 700, 20000)),
            np.exp(RNG.uniform(-2, 2, 20000)),
            1 + RNG.uniform(-1e-6, 1e-6, 2000),
            [1.0, 2.0, 0.5, np.sqrt(0.5), np.sqrt(2.0), 1e-300, 1e300, 2e300],
        ]
    )
    ref = np.log(x)
    assert relative(apply(mk.log_pos, x), ref) < ULPS
    assert np.max(np.abs(apply(mk.log_pos, x) - ref)) < 2 * np.finfo(float).eps
    assert apply(mk.log_pos, np.array([1.0]))[0] == 0.0


def test_log1p_keeps_small_arguments_exact():
    s = np.concatenate(
        [
            np.exp(RNG.uniform(-40, 40, 20000)),
            RNG.uniform(0, 3, 20000),
            [0.0, 1e-300, 1e-17, 2.0**-53, 1.0, np.sqrt(2.0) - 1],
        ]
    )
    got = apply(mk.log1p_pos, s)
    assert relative(got, np.log1p(s)) < ULPS
    assert got[-6] == 0.0 and got[-5] == 1e-300  # below an ulp of 1: s itself


def test_exp_and_expm1():
    x = np.concatenate(
        [RNG.uniform(0, 700, 20000), np.exp(RNG.uniform(-40, 0, 20000)), [0.0, 40.0, 700.0]]
    )
    assert relative(apply(mk.exp_pos, x), np.exp(x)) < ULPS
    assert relative(apply(mk.expm1_pos, x), np.expm1(x)) < ULPS
    assert apply(mk.expm1_pos, np.array([1e-300]))[0] == 1e-300


def test_atan_everywhere():
    z = np.concatenate(
        [
            np.tan(RNG.uniform(-1.5707, 1.5707, 20000)),
            np.exp(RNG.uniform(-300, 300, 20000)) * RNG.choice([-1.0, 1.0], 20000),
            [0.0, 1.0, -1.0, 1e-300, np.inf, -np.inf],
        ]
    )
    got = apply(mk.atan_any, z)
    assert relative(got, np.arctan(z)) < ULPS
    assert np.isnan(apply(mk.atan_any, np.array([np.nan]))[0])
    assert np.signbit(apply(mk.atan_any, np.array([-0.0]))[0])


def test_cos_quarter_and_the_taper():
    t = np.concatenate([RNG.uniform(0, 1, 20000), [0.0, 0.5, 1.0]])
    got = apply(mk.cos_quarter, t)
    assert np.max(np.abs(got - np.cos(0.5 * np.pi * t))) < 2 * np.finfo(float).eps
    # the taper 0.5 (1 + cos(pi t)) as cos(pi t / 2)^2
    assert np.max(np.abs(got**2 - 0.5 * (1 + np.cos(np.pi * t)))) < 4 * np.finfo(float).eps


@numba.njit(error_model="numpy")
def _atan2_all(y, x, out):  # pragma: no cover - compiled
    for i in range(x.size):
        out[i] = _atan2(y[i], x[i])


def test_pair_kernels_atan2_as_the_library_s():
    import math

    specials = [0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, np.inf, -np.inf]
    y = np.concatenate([RNG.normal(size=20000) * 10.0 ** RNG.uniform(-5, 5, 20000)] + [
        np.repeat(specials, len(specials))])  # fmt: skip
    x = np.concatenate([RNG.normal(size=20000) * 10.0 ** RNG.uniform(-5, 5, 20000)] + [
        np.tile(specials, len(specials))])  # fmt: skip
    finite = np.isfinite(x) | np.isfinite(y)  # atan2(+-inf, +-inf): not used
    y, x = y[finite], x[finite]
    got = np.empty_like(x)
    _atan2_all(y, x, got)
    ref = np.array([math.atan2(a, b) for a, b in zip(y, x)])
    assert relative(got, ref) < ULPS
    assert np.array_equal(np.signbit(got), np.signbit(ref))
