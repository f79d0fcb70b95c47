import logging

import numpy as np
import pytest

import processing as P
from acousim.synth import (
    Capture,
    Noise,
    PointReflectors,
    RenderOptions,
    direct_path_echoes,
    point_echoes,
    render,
    signal_power,
    simulate,
    simulate_points,
)
from tests.acousim.synth.references import echoes_ahead, filtered_per_path

FS, C = 500e3, 343.0


def one_mic():
    return P.ura(1, 1, 1e-3)


def test_echo_delay_and_spherical_spreading():
    refl = PointReflectors.spherical(np.deg2rad(30), np.deg2rad(30), 1.0, strength=2.0)
    arr = P.paper_8x8()
    e = point_echoes(refl, arr, C, "spherical")
    r_m = np.linalg.norm(refl.positions_m - arr.positions_m, axis=1)
    np.testing.assert_allclose(e.delay_s[:, 0], (1.0 + r_m) / C)
    np.testing.assert_allclose(e.gain[:, 0], 2.0 / (1.0 * r_m))
    paper = point_echoes(refl, arr, C, "paper")
    np.testing.assert_allclose(paper.gain[:, 0], 2.0 / (2 * r_m))
    with pytest.raises(ValueError, match="spreading"):
        point_echoes(refl, arr, C, "cylindrical")


@pytest.mark.parametrize("interpolator,bound_db", [("sinc", -60), ("lagrange", -55), ("fft", -60)])
def test_fast_fractional_delays_against_the_band_limited_reference(interpolator, bound_db):
    rng = np.random.default_rng(0)
    refl = PointReflectors(rng.uniform([0.3, -0.5, -0.5], [1.5, 0.5, 0.5], (3, 3)), 1.0)
    arr = P.ura(2, 2, 5e-3)
    e = point_echoes(refl, arr, C)
    wf = P.paper_chirp()
    ref = render(e, wf, FS, 6000, interpolator="reference")
    y = render(e, wf, FS, 6000, interpolator=interpolator)
    err = 10 * np.log10(np.sum((y - ref) ** 2) / np.sum(ref**2))
    assert err < bound_db


def test_no_global_delay_echo_peaks_at_its_delay():
    e = point_echoes(PointReflectors([[1.3, 0, 0]], 1.0), one_mic(), C)
    for interpolator in ["sinc", "lagrange", "exact", "fft"]:
        y = render(e, P.paper_chirp(), FS, 8000, interpolator=interpolator, emission_index=50)
        mf = P.matched_filter(y, P.paper_chirp().sampled(FS))
        assert abs(np.argmax(mf[0]) - (50 + 2.6 / C * FS)) <= 0.5


def test_snr_definition_matches_eq2():
    wf = P.paper_chirp()
    rec = simulate_points(
        PointReflectors([[1.0, 0, 0]], 1.0),
        one_mic(),
        wf,
        FS,
        20000,
        noise=Noise(snr_db=10.0, seed=1, n_measurements=40),
    )
    clean = simulate_points(PointReflectors([[1.0, 0, 0]], 1.0), one_mic(), wf, FS, 20000)
    noise = rec.samples - clean.samples[None]
    p_s = signal_power(clean.samples, int(wf.duration_s * FS))
    assert 10 * np.log10(p_s / noise.var()) == pytest.approx(10.0, abs=0.05)
    # for one echo, P_s is the echo's own mean power: amplitude^2 / 2 for a chirp
    amp = 1 / (1.0 * 1.0)
    assert p_s == pytest.approx(amp**2 / 2, rel=0.03)


def test_seeded_noise_is_reproducible_and_measurements_independent():
    args = (PointReflectors([[1.0, 0.1, 0]], 1.0), P.paper_8x8(), P.paper_chirp(), FS, 4096)
    a = simulate_points(*args, noise=Noise(snr_db=0, seed=7, n_measurements=3))
    b = simulate_points(*args, noise=Noise(snr_db=0, seed=7, n_measurements=3))
    c = simulate_points(*args, noise=Noise(snr_db=0, seed=8, n_measurements=3))
    assert a.samples.tobytes() == b.samples.tobytes()
    assert not np.array_equal(a.samples, c.samples)
    assert a.samples.shape == (3, 64, 4096)
    assert not np.allclose(a.samples[0], a.samples[1])


def test_infinite_snr_generates_no_noise_and_far_reflectors_are_skipped(caplog):
    refl = PointReflectors([[1.0, 0, 0], [50.0, 0, 0]], 1.0)
    with caplog.at_level(logging.DEBUG, logger="acousim.synth.signal_model"):
        rec = simulate_points(refl, one_mic(), P.paper_chirp(), FS, 4096)
    assert rec.metadata["n_paths"] == 1
    assert "skipped 1 of 2 paths" in caplog.text and "no noise" in caplog.text
    assert np.all(rec.samples[0, :2000] == 0)  # nothing before the echo (after 2.9 ms)


def test_direct_path_arrives_first():
    arr = P.urtis_v1()
    e = direct_path_echoes(arr, C)
    r = np.linalg.norm(arr.positions_m, axis=1)
    np.testing.assert_allclose(e.delay_s[:, 0], r / C)
    assert e.order.tolist() == [0]


def test_empty_echoes_render_silence():
    from acousim.synth import Echoes

    e = Echoes.concatenate([Echoes.empty(1), Echoes.empty(1)])
    rec = simulate(e, Capture(one_mic(), P.paper_chirp(), FS, 100))
    assert np.all(rec.samples == 0)
    with pytest.raises(ValueError, match="no echo reaches"):
        simulate(e, Capture(one_mic(), P.paper_chirp(), FS, 100), noise=Noise(snr_db=10))


def test_path_responses_match_exact_per_path_filtering():
    """Absorption and piston directivity through the low-rank factorisation against
    filtering each path and microphone separately: -81 dB here, in float32 as in
    float64 (the factorisation sets it, not the single-precision FFTs)."""
    from acousim.synth import PathResponse

    arr = P.ura(2, 2, 3.85e-3)
    wf = P.rtis_call()
    fs = 450e3
    e = echoes_ahead(arr)
    resp = PathResponse(emitter_radius_m=0.004)
    y = render(e, wf, fs, 16384, response=resp)
    ref = filtered_per_path(e, wf, resp, fs, 16384)
    assert 10 * np.log10(np.sum((y - ref) ** 2) / np.sum(ref**2)) < -75
    # and the response does something: about 5 dB of absorption and directivity here
    y0 = render(e, wf, fs, 16384)
    assert 10 * np.log10(np.sum(y**2) / np.sum(y0**2)) < -2


def test_an_echo_within_the_calls_padding_of_sample_zero_keeps_its_delay():
    """The direct path arrives a few samples after the emission, earlier than the
    band-limited call's pre-ringing pad: it must not be moved."""
    from acousim.synth import Echoes

    wf = P.rtis_call()
    fs = 450e3
    for delay_samples in (3.0, 40.0, 700.0):
        e = Echoes(
            np.array([[delay_samples / fs]]), np.ones((1, 1)), np.ones((1, 1)), np.zeros(1, int)
        )
        y = render(e, wf, fs, 8000)
        ref = render(e, wf, fs, 8000, interpolator="exact")
        mf = np.abs(P.matched_filter(np.vstack([y, ref]), wf.sampled(fs)))
        assert abs(np.argmax(mf[0]) - np.argmax(mf[1])) <= 1
        assert 10 * np.log10(np.sum((y - ref) ** 2) / np.sum(ref**2)) < -35


def test_an_unknown_or_unfit_interpolator_is_an_input_error_naming_it():
    from acousim.synth import PathResponse
    from processing.base.errors import InputError

    e = point_echoes(PointReflectors([[1.0, 0, 0]], 1.0), one_mic(), C)
    with pytest.raises(InputError, match="interpolator = 'cubic'"):
        render(e, P.paper_chirp(), FS, 4000, interpolator="cubic")
    with pytest.raises(InputError, match="interpolator = 'fft': a path response"):
        render(e, P.paper_chirp(), FS, 4000, interpolator="fft", response=PathResponse())


@pytest.mark.parametrize("interpolator", ["sinc", "lagrange", "nearest"])
def test_compiled_and_sparse_impulse_sums_give_the_same_bits(interpolator, monkeypatch):
    """The numba accumulation adds every term in the sparse product's order: the same
    bytes with and without numba (with a path response: several gain sets)."""
    pytest.importorskip("numba")
    import importlib

    from acousim.synth import PathResponse

    render_mod = importlib.import_module("acousim.synth.render")  # the module
    arr = P.ura(2, 3, 3.85e-3)
    e = echoes_ahead(arr, n=60, seed=5, near_m=0.3)
    wf, fs = P.rtis_call(), 450e3
    resp = PathResponse(emitter_radius_m=0.004)
    capture = Capture(arr, wf, fs, 16384)
    opts = RenderOptions(interpolator=interpolator, domain="frequency")  # the impulses
    compiled = render_mod.render_with(e, capture, opts, resp)
    monkeypatch.setattr(render_mod, "_compiled", lambda: None)
    sparse = render_mod.render_with(e, capture, opts, resp)
    assert np.any(compiled)
    assert compiled.tobytes() == sparse.tobytes()


@pytest.mark.parametrize("method", ["sinc", "nearest"])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_impulse_sums_are_a_plain_loops_sums_in_their_precision(method, dtype):
    """The impulses' sums, compiled or sparse, into a reused buffer full of garbage:
    the bytes of a plain loop that puts each path's tabulated taps at its delay and
    adds them, path by path, in the output's precision (a zero gain adds nothing)."""
    import importlib

    render_mod = importlib.import_module("acousim.synth.render")
    rng = np.random.default_rng(3)
    M, N, Q, taps, n_span, width = 3, 40, 4, 6, 300, 330
    d = rng.uniform(-10, n_span + 10, (M, N))  # some taps beyond the span's margins
    g = rng.standard_normal((M, N, Q))
    g[:, ::5, 1:] = 0.0  # a set without some paths (the direct path's group)
    pad = taps + 1
    # the reference: where each path's first tap goes and which weights it takes
    if method == "nearest":
        first = np.clip(np.rint(d).astype(int), -pad, n_span + pad - 1) + pad
        weights = np.ones((M, N, 1))
    else:
        n0 = np.floor(d)
        first = np.clip(n0.astype(int), -1, n_span) + pad + 1 - taps
        rows = np.rint((d - n0) * render_mod.TABLE_PHASES).astype(int)
        weights = render_mod._kernel_table(method, taps)[rows]
    want = np.zeros((Q, M, width), dtype)
    for m in range(M):
        for n in range(N):
            for q in range(Q):
                if g[m, n, q] != 0.0:
                    taps_mn = weights[m, n].astype(dtype) * dtype(g[m, n, q])
                    for j, w in enumerate(taps_mn):  # one add per tap, in path order
                        want[q, m, first[m, n] + j] += w
    for compiled in (True, False):
        if compiled and render_mod._compiled() is None:
            continue
        kernel = render_mod._compiled
        try:
            if not compiled:
                render_mod._compiled = lambda: None
            out = np.full((Q, M, width), np.nan, dtype)
            h, at = render_mod._impulses(d, g, n_span, (method, taps), width, dtype, out=out)
        finally:
            render_mod._compiled = kernel
        assert h is out and at == pad
        assert h.tobytes() == want.tobytes(), f"compiled={compiled}"


def test_noise_drawn_in_advance_is_the_noise_drawn_after():
    from acousim.synth.noise import NoiseDraw, add_noise

    clean = np.linspace(-1, 1, 3 * 500).reshape(3, 500)
    later = add_noise(clean, 0.3, np.random.default_rng(11), 2)
    rng = np.random.default_rng(11)
    early = add_noise(clean, 0.3, rng, 2, NoiseDraw(rng, (2, 3, 500)))
    assert early.tobytes() == later.tobytes()
    rng = np.random.default_rng(11)
    with pytest.raises(ValueError, match="shape"):
        add_noise(clean, 0.3, rng, None, NoiseDraw(rng, (2, 3, 500)))
