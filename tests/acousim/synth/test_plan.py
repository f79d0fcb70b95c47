"""The Doppler render's plan and its gain-set compression: the compiled placement and
sums and the path responses' directivity series, against references written here
(plain loops and formulas, scipy's J1)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from scipy.special import j1

from acousim.synth.compress import ChebyshevGains, compress
from acousim.synth.response import PathResponse, piston_directivity, piston_series


def _loop_terms(gain, s, K):
    """t_p[m, n] = gain T_p(s) by the cosine form of the Chebyshev polynomials."""
    theta = np.arccos(np.clip(s, -1, 1))
    return np.stack([gain * np.cos(p * theta) for p in range(K)])  # (K, M, N)


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("K", [1, 2, 6])
def test_chebyshev_gains_sums_against_plain_loops(K, compiled, monkeypatch):
    """Per path the sum over microphones of t_j t_k (K, K, N), the terms path by path
    (N, K, M) and their product with per-path matrices (M, N, R): compiled and in
    numpy (as without numba) against loops over the microphones and paths here."""
    if not compiled:
        monkeypatch.setattr("acousim.synth.compress._kernel", lambda name: None)
    rng = np.random.default_rng(3)
    M, N, R = 7, 300, 3  # more paths than a compiled block: the blocks' seams too
    gain = rng.uniform(-1, 1, (M, N))
    s = rng.uniform(-1, 1, (M, N))
    terms = ChebyshevGains(gain, s if K > 1 else None, K)
    t = _loop_terms(gain, s, K)
    X = terms.gram()
    want = np.zeros((K, K, N))
    for n in range(N):
        for m in range(M):
            want[:, :, n] += np.outer(t[:, m, n], t[:, m, n])
    np.testing.assert_allclose(X, want, rtol=1e-12, atol=1e-12 * M)
    np.testing.assert_allclose(terms.terms(), t.transpose(2, 0, 1), rtol=1e-12, atol=1e-13)
    P = rng.standard_normal((N, K, R))
    got = terms.times(P)
    loop = np.zeros((M, N, R))
    for m in range(M):
        for n in range(N):
            loop[m, n] = t[:, m, n] @ P[n]
    np.testing.assert_allclose(got, loop, rtol=1e-12, atol=1e-12)


def test_compress_keeps_the_sum_of_the_sets():
    """The compressed sets' sum ``sum_r g_r b_r`` equals the uncompressed ``sum_jq
    t_j v_q W_j U_q`` formed here (all sets kept at a tight tolerance), for the
    factored terms and for the terms given as an array, the filters' products over
    the bins and folded onto the coarse grid U is interpolated from alike."""
    from acousim.synth.compress import coarse_products

    rng = np.random.default_rng(5)
    M, N, K, Q, F = 4, 40, 3, 2, 16
    gain = rng.uniform(0.1, 1, (M, N))
    s = rng.uniform(-1, 1, (M, N))
    V = rng.standard_normal((N, Q))
    W = rng.standard_normal((K, F)) + 1j * rng.standard_normal((K, F))
    fb, coarse = np.linspace(0, 1, F), np.array([0.1, 0.5, 0.9])
    Uc = rng.standard_normal((coarse.size, Q))
    U = np.stack([np.interp(fb, coarse, u) for u in Uc.T], axis=1)
    j, k = np.triu_indices(K)
    WW = (W.conj()[j] * W[k]).real
    no = np.zeros(N, bool), np.zeros(Q, bool)
    t = _loop_terms(gain, s, K)  # (K, M, N)
    want = np.einsum("kmn,nq,kf,fq->mnf", t, V, W, U)
    folded = (coarse_products(WW, fb, coarse), Uc)
    for terms, products in (
        (ChebyshevGains(gain, s, K), WW),
        (t.transpose(0, 2, 1), WW),
        (ChebyshevGains(gain, s, K), folded),
    ):
        g, filt = compress(terms, V, W, products, U, *no, 1e-9)
        got = np.einsum("mnr,fr->mnf", g, filt)
        assert np.abs(got - want).max() < 1e-9 * np.abs(want).max()


def test_piston_series_is_the_bessel_directivity():
    """The power series of 2 J1(x) / x (as a matrix product) against scipy's J1,
    across the series' range (x up to 6: the largest cancellation), behind the
    baffle too, with the weights: within 1e-14; beyond its range it says so."""
    th = np.linspace(0, np.pi, 4001)
    f = np.linspace(0, 80e3, 33)
    c, a = 343.0, 5.999 * 343.0 / (2 * np.pi * 80e3)  # x reaches 6 at 80 kHz
    x = 2 * np.pi * f[:, None] / c * a * np.sin(np.minimum(th, np.pi / 2))[None, :]
    safe = np.where(x == 0, 1.0, x)
    want = np.where(x == 0, 1.0, 2 * j1(safe) / safe) * np.clip(2 - 2 * th / np.pi, 0, 1)
    weight = np.linspace(0.5, 2, th.size)
    got = piston_series(f, th, a, c, weight)
    assert got is not None
    assert np.abs(got - want * weight).max() < 1e-14
    assert piston_series(f, th, 1.01 * a, c, weight) is None


def test_weighted_matrix_against_the_path_response():
    """PathResponse.weighted_matrix is the response matrix (absorption, directivity by
    scipy's J1) times the weights, with the series and beyond its range alike."""
    rng = np.random.default_rng(2)
    f = np.linspace(20e3, 60e3, 64)
    length = rng.uniform(0.5, 8, 50)
    theta = rng.uniform(0, np.pi, 50)
    weight = rng.uniform(0.1, 3, 50)
    for radius in (0.004, 0.02):  # within the series' range, beyond it
        r = PathResponse(emitter_radius_m=radius)
        alpha = r.matrix(f, length, None)  # absorption only
        want = alpha * piston_directivity(f[:, None], theta[None, :], radius, r.speed_of_sound_m_s)
        got = r.weighted_matrix(f, length, theta, None, weight)
        assert np.abs(got - want * weight).max() < 1e-14 * np.abs(want * weight).max()


@pytest.mark.parametrize("compiled", [True, False])
def test_placement_against_its_formula(compiled, monkeypatch):
    """Impulse positions ``((t0 + p (1 / a - 1)) fs + e) + s``, the factors mapped
    onto the nodes' interval and the positions' range, compiled and in numpy, for
    delays stored either way round, against the formulas evaluated here per element."""
    from acousim.synth import doppler

    if not compiled:
        monkeypatch.setattr(doppler, "optional_kernel", lambda *a: None)
    rng = np.random.default_rng(4)
    nodes = np.array([1.004, 1.0, 0.996])
    K = nodes.size
    x = np.cos((2 * np.arange(K) + 1) * np.pi / (2 * K))  # the nodes' Chebyshev points
    for order in ("C", "F"):
        delay = np.asarray(rng.uniform(1e-3, 2e-2, (5, 9)), order=order)
        rate = np.asarray(rng.uniform(0.996, 1.004, (5, 9)), order=order)
        d, s, span, advance, margin = doppler._placement(delay, rate, nodes, 1e-3, 450e3, (3, 1046))
        want = np.empty((5, 9))
        for m in range(5):
            for n in range(9):
                want[m, n] = (delay[m, n] + 5e-4 * (1 / rate[m, n] - 1)) * 450e3 + 3 + 1046
        np.testing.assert_allclose(d, want, rtol=1e-15)
        assert span == (d.min(), d.max())
        # s maps the nodes' interval onto [-1, 1]: the nodes themselves onto x
        half = (nodes[0] - nodes[-1]) / (x[0] - x[-1])
        np.testing.assert_allclose(s, (rate - (nodes[0] - half * x[0])) / half, rtol=1e-13)
        np.testing.assert_allclose(advance, 5e-4 * (1 / nodes - 1))
    _, s1, *_ = doppler._placement(delay, rate, nodes[:1], 1e-3, 450e3)
    assert s1 is None


def test_coarse_products_give_the_sums_over_the_interpolated_terms():
    """``sum_f WW_j(f) u(f) v(f)`` over bins reaching beyond the coarse grid, u and v
    np.interp's linear interpolation of random coarse values, against the folded
    products ``u_c^T MM_j v_c``."""
    from acousim.synth.compress import coarse_products

    rng = np.random.default_rng(8)
    coarse = np.linspace(20e3, 60e3, 9)
    fb = np.sort(rng.uniform(15e3, 65e3, 500))
    WW = rng.standard_normal((3, fb.size))
    MM = coarse_products(WW, fb, coarse)
    for _ in range(3):
        uc, vc = rng.standard_normal((2, coarse.size))
        u, v = np.interp(fb, coarse, uc), np.interp(fb, coarse, vc)
        np.testing.assert_allclose(MM @ vc @ uc, WW @ (u * v), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("spread_m", [0.03, 0.5])  # the series' range, and beyond it
def test_mic_gains_against_a_plain_loop(compiled, spread_m, monkeypatch):
    """The paths' mean lengths, the gains times the absorption of each microphone's
    difference from the mean and the paths' RMS gains (compiled: the exponential a
    series for small arguments; numpy), against the formulas per element here."""
    import math

    render_mod = importlib.import_module("acousim.synth.render")
    if not compiled:
        monkeypatch.setattr(render_mod, "optional_kernel", lambda *a: None)
    rng = np.random.default_rng(8)
    M, N, c = 6, 40, -0.15  # c: -alpha ln(10) / 20 per metre, alpha = 1.3 dB/m
    length = rng.uniform(1, 5, N)[None] + rng.uniform(-spread_m, spread_m, (M, N))
    gain = rng.uniform(0.1, 1, (M, N))
    mean, g, weight = render_mod._mic_gains(gain, length, c)
    for n in range(N):
        want_mean = math.fsum(length[:, n]) / M
        assert mean[n] == pytest.approx(want_mean, rel=1e-15)
        want = [gain[m, n] * math.exp(c * (length[m, n] - want_mean)) for m in range(M)]
        np.testing.assert_allclose(g[:, n], want, rtol=2e-15)
        rms = math.sqrt(math.fsum(w * w for w in want) / M)
        assert weight[n] == pytest.approx(rms, rel=1e-14)
