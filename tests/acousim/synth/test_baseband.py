"""The Doppler renderer at complex baseband (``render_rate = "baseband"``,
:mod:`acousim.synth.baseband`) against independent references: the exact per-sample
echo (the analytic call at the solved emission time) and each path filtered by its
own response by FFT."""

from __future__ import annotations

import numpy as np
import pytest

import processing as P
from acousim.core.echoes import Echoes
from acousim.kinematics import SensorKinematics, arrivals
from acousim.kinematics.reference import render_doppler_reference
from acousim.scene import Pose
from acousim.scene.trajectory import Trajectory
from acousim.synth import baseband
from acousim.synth.doppler import render_doppler
from acousim.synth.options import RenderOptions
from acousim.synth.response import PathResponse
from acousim.trace.motion.following import MovingPaths
from tests.acousim.synth.references import echoes_ahead, filtered_per_path

C = 343.0
FS = 450e3
#: the baseband route itself (few paths, under 'auto', are summed in time instead)
BASEBAND = RenderOptions(rate="baseband", domain="frequency")


def _drive(n_paths: int):
    """Two microphones of the uRTIS on a sensor driving at 1 m/s and turning at
    90 deg/s; `n_paths` point reflectors at 1.5-3 m (seeded)."""
    arr = P.preset("urtis_v1")
    arr = P.Array("two", arr.positions_m[[3, 25]], np.array([0.0, 0, -0.012]))
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [1.0, 0.2, 0], [0, 0, np.deg2rad(90)])
    rng = np.random.default_rng(5)
    direction = rng.normal(size=(n_paths, 3)) * [0.3, 1, 0.3] + [1, 0, 0]
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    pts = direction * rng.uniform(1.5, 3.0, (n_paths, 1))
    paths = MovingPaths.points(
        pts, np.ones(n_paths), np.zeros((n_paths, 3)), pose.to_world(arr.emitter_m)
    )
    n = int(0.024 * FS)
    kin = SensorKinematics(traj, pose, arr, n / FS, 2.5e-4)
    a = arrivals(paths, kin, P.rtis_call("default_25_50").duration_s, C, np.array([1.0, 0, 0]))
    return arr, pose, traj, paths, n, a


def _db(a: np.ndarray, b: np.ndarray) -> float:
    return float(20 * np.log10(np.linalg.norm(a - b) / np.linalg.norm(b)))


def test_baseband_renderer_against_the_per_sample_reference():
    """Without a path response: within -58 dB of the exact echoes (the band at its
    default -60 dB floor: the call's energy outside it is -65 dB)."""
    arr, pose, traj, paths, n, a = _drive(5)
    wf = P.rtis_call("default_25_50")
    fast = render_doppler(a.echoes, a.rate, wf, FS, n, options=BASEBAND)
    exact = render_doppler_reference(
        paths, SensorKinematics.exact(traj, pose, arr), wf, FS, n, C, a.echoes.gain
    )
    assert _db(fast, exact) <= -58


def _filtered_drive(n_paths: int):
    """:func:`_drive`'s echoes with absorption and directivity: (echoes, response,
    each path's exact echo filtered by its own response (FFT, here), (arrivals,
    call, samples))."""
    arr, pose, traj, paths, n, a = _drive(n_paths)
    wf = P.rtis_call("default_25_50")
    length = np.broadcast_to(a.echoes.path_length_m.mean(axis=0), a.echoes.gain.shape)
    echoes = Echoes(a.echoes.delay_s, a.echoes.gain, length, a.echoes.order, a.echoes.angles())
    response = PathResponse(speed_of_sound_m_s=C, emitter_radius_m=0.005)
    nfft = 2 * n
    f = np.fft.rfftfreq(nfft, 1 / FS)
    exact = np.zeros((2, n))
    kin = SensorKinematics.exact(traj, pose, arr)
    for k in range(len(paths)):
        one = render_doppler_reference(paths.select([k]), kin, wf, FS, n, C, a.echoes.gain[:, [k]])
        H = response.matrix(f, length[0, [k]], echoes.angles()[[k]])[:, 0]
        exact += np.fft.irfft(np.fft.rfft(one, nfft) * H, nfft)[:, :n]
    return echoes, response, exact, (a, wf, n)


def test_baseband_renderer_with_absorption_and_directivity_against_exact_filtering():
    """Doppler, absorption and directivity: each path's exact echo filtered by its own
    response (FFT, here); the band floor sets the error (a wider band, a smaller one)."""
    echoes, response, exact, (a, wf, n) = _filtered_drive(4)
    errors = []
    for floor in (-40.0, -60.0):
        options = RenderOptions(rate="baseband", band_floor_db=floor, domain="frequency")
        fast = render_doppler(echoes, a.rate, wf, FS, n, response=response, options=options)
        errors.append(_db(fast, exact))
    assert errors[1] <= -58
    assert errors[0] > errors[1]


def test_kernel_transform_matches_a_direct_sum():
    """The kernel's Fourier transform (quadrature) against the sum of its samples
    over a fine grid (the Riemann sum of a smooth compact function)."""
    g = baseband.grid(4000, 500, 200, baseband.TAPS, baseband.OVERSAMPLING)
    x = np.linspace(-baseband.TAPS / 2, baseband.TAPS / 2, 200001)
    phi = baseband._phi(x, g.width, g.beta)
    for k in (0, 50, 200):
        direct = np.sum(phi * np.cos(2 * np.pi * k / g.nb * x)) * (x[1] - x[0])
        assert g.psi[k + g.half] == pytest.approx(direct, rel=1e-6)


def test_static_baseband_render_matches_exact_per_path_filtering():
    """A static scene's echoes (40 point reflectors, absorption and directivity) at
    complex baseband against each path filtered by its own response and delayed
    exactly in the frequency domain (written here): the band floor sets the error."""
    from acousim.synth.options import Capture
    from acousim.synth.render import render_baseband

    arr = P.ura(2, 2, 3.85e-3)
    wf = P.rtis_call("default_25_50")
    e = echoes_ahead(arr)
    resp = PathResponse(emitter_radius_m=0.004)
    ref = filtered_per_path(e, wf, resp, FS, 16384)
    capture = Capture(arr, wf, FS, 16384, C)
    errors = [
        _db(render_baseband(e, capture, BASEBAND, resp, floor), ref) for floor in (-40.0, -60.0)
    ]
    assert errors[1] <= -58
    assert errors[0] > errors[1]


def test_the_old_fast_point_still_imports_with_a_warning():
    """The deprecated fast point (one "fast" now: the quality preset) still names
    settings a scene accepts, with valid values, for one version."""
    from acousim.scene import fast
    from acousim.scene.model import Simulation

    with pytest.warns(DeprecationWarning, match='quality = "fast"'):
        settings = fast.FAST_SETTINGS
    sim = Simulation(**settings)
    assert sim.render_rate == "baseband"
    with pytest.raises(Exception, match="render_rate"):
        Simulation(render_rate="quarter")


def _impulses(n: int, M: int, N: int, S: int, seed: int):
    """Positions (M, N) over an n-point span, some within a sample of either end
    (their kernels wrap round the coarse grid), and gains (M, N, S) (seeded)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(1.0, n - 1.0, (M, N))
    q[:, :3] = [0.2, 0.7, n - 0.4]  # at the ends
    return q, rng.normal(size=(M, N, S))


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_band_spectra_against_the_direct_sums(dtype):
    """:func:`.baseband.render_band` with unit filters against the exact sums
    ``sum_n g exp(-2 pi i k q / n)`` at the band's bins (numpy, per bin): within the
    kernel's aliasing error (W = 4, 1.5x; largest at the band's edges, where its
    transform is smallest: -55 dB over the whole band at equal weights, -68 dB over
    its inner half), impulses at the span's ends included (their taps fold round the
    grid), zero outside the band."""
    n, c, half = 4000, 700, 96
    q, gains = _impulses(n, 3, 60, 4, 1)
    sets = np.array([0, 2, 3])
    g = baseband.grid(n, c, half, baseband.TAPS, baseband.OVERSAMPLING)
    filters = np.ones((sets.size, 2 * half + 1))
    out = baseband.render_band(q, gains, filters, g, dtype, sets)
    k = np.arange(c - half, c + half + 1)
    phase = np.exp(-2j * np.pi * q[..., None] * k / n)  # (M, N, K)
    exact = np.einsum("mnk,mnr->mk", phase, gains[:, :, sets])
    assert out.shape == (3, n // 2 + 1) and out.dtype == dtype
    assert _db(out[:, k], exact) < -53
    inner = slice(half // 2, -half // 2)
    assert _db(out[:, k][:, inner], exact[:, inner]) < -65
    assert not np.any(out[:, : k[0]]) and not np.any(out[:, k[-1] + 1 :])


@pytest.mark.parametrize("n", [4000, 3375])
def test_spectra_of_even_and_odd_lengths_against_the_direct_sums(n):
    """:func:`.baseband.spectra` (the band found from the filters, on an n-point real
    FFT of either parity: F = n // 2 + 1 bins) against the exact sums times the
    filters (numpy, per bin): a smooth filter over 600-900 bins, zero elsewhere."""
    q, gains = _impulses(n, 2, 50, 3, 5)
    F = n // 2 + 1
    k = np.arange(F)
    filters = np.zeros((3, F), complex)  # a filter per set of gains
    on = slice(600 * n // 4000, 900 * n // 4000)
    filters[:, on] = np.hanning(k[on].size) * np.array([[1.0], [3.0], [0.5j]])
    sets = np.array([0, 2])
    energy = np.sum(gains**2, axis=(0, 1))
    out = baseband.spectra(q, gains, filters, sets, energy, -60.0, complex, n)
    phase = np.exp(-2j * np.pi * q[..., None] * k[on] / n)  # (M, N, K)
    exact = np.einsum("mnk,mnr,rk->mk", phase, gains[:, :, sets], filters[sets, on])
    assert out.shape == (2, F)
    assert _db(out[:, on], exact) < -60
    assert np.linalg.norm(out[:, : on.start]) < 1e-3 * np.linalg.norm(exact)
    assert np.linalg.norm(out[:, on.stop :]) < 1e-3 * np.linalg.norm(exact)


def test_band_spectra_without_numba_are_the_compiled_ones(monkeypatch):
    """The numpy fallbacks of the accumulation and the products against the compiled
    kernels: the same sums (the turn evaluated directly instead of by its table and
    series, the sums in another order)."""
    pytest.importorskip("numba")
    n, c, half = 3000, 500, 64
    q, gains = _impulses(n, 2, 40, 3, 2)
    g = baseband.grid(n, c, half, baseband.TAPS, baseband.OVERSAMPLING)
    filters = np.random.default_rng(3).normal(size=(2, 2 * half + 1)) + 1j
    sets = np.array([2, 0])
    compiled = baseband.render_band(q, gains, filters, g, complex, sets).copy()
    monkeypatch.setattr(baseband, "optional_kernel", lambda *a: None)
    plain = baseband.render_band(q, gains, filters, g, complex, sets)
    assert np.any(compiled)
    assert _db(plain, compiled) < -120
    assert baseband.set_energy(gains) == pytest.approx(np.sum(gains**2, axis=(0, 1)), rel=1e-12)
    assert baseband.echo_sets(gains, np.zeros(40, bool)).all()


def test_echo_sets_are_those_the_direct_path_does_not_use():
    """Each set of one group: the direct path's are those with gains on its paths;
    the sets' energies the sums of squares (numpy, another order)."""
    gains = np.random.default_rng(4).normal(size=(2, 5, 4))
    direct = np.zeros(5, bool)
    direct[1] = True
    gains[:, 1, 2:] = 0  # the direct path's sets: 0 and 1
    gains[:, ~direct, :2] = 0
    assert baseband.echo_sets(gains, direct).tolist() == [False, False, True, True]
    energy = baseband.set_energy(gains)
    assert energy == pytest.approx(np.einsum("mnr,mnr->r", gains, gains), rel=1e-12)


def test_the_compressed_sets_have_unit_energy():
    """The moving render at baseband weighs the sets' filters alone when it finds
    the band: the compression's gains are orthonormal (``G E L^(-1/2) Y_r``), each
    set's sum of squares over microphones and paths one (numpy), its weight in its
    filter; the direct path's sets and the echoes' alike."""
    from acousim.synth.compress import compress
    from acousim.synth.doppler import plan_doppler

    arr, pose, traj, paths, n, a = _drive(6)
    e = a.echoes
    order = np.array([0, 1, 1, 1, 1, 1])
    echoes = Echoes(e.delay_s, e.gain * 10.0, e.path_length_m, order, e.angles())
    response = PathResponse(speed_of_sound_m_s=C, emitter_radius_m=0.005)
    wf = P.rtis_call("default_25_50")
    plan = plan_doppler(echoes, a.rate, wf, FS, n, response=response, options=BASEBAND)
    products = plan.products if plan.coarse_spectra is None else plan.folded_products
    gains, _ = compress(
        plan.terms,
        plan.responses,
        plan.templates,
        products,
        plan.response_spectra,
        plan.direct_paths,
        plan.direct_terms,
        plan.options.compress_tolerance,
    )
    assert gains.shape[2] >= 2
    assert np.sum(gains**2, axis=(0, 1)) == pytest.approx(1.0, rel=1e-9)
    assert baseband.echo_sets(gains, plan.direct_paths).sum() < gains.shape[2]


def test_grid_lengths_are_the_smallest_of_their_form():
    """The coarse grid's length: the least ``2**k f`` (f in 1, 3, 5, 9, 15) of at
    least the asked points, against a search upwards."""

    def of_form(x: int) -> bool:
        while x % 2 == 0:
            x //= 2
        return x in (1, 3, 5, 9, 15)

    for least in (1, 7, 100, 1665, 2498, 2561, 5000):
        nb = baseband._grid_length(least)
        assert nb == next(x for x in range(least, 4 * least + 8) if of_form(x))


def test_static_baseband_render_with_a_direct_path_matches_exact_filtering():
    """A direct path (order 0, 20 dB above the echoes) is summed in time, as the
    full-rate renderer sums it, onto the echoes at baseband: the recording within
    -55 dB of the echoes' energy of each path filtered exactly by its response."""
    from acousim.synth.options import Capture
    from acousim.synth.render import render_baseband

    arr = P.ura(2, 2, 3.85e-3)
    wf = P.rtis_call("default_25_50")
    e = echoes_ahead(arr, n=12)
    direct_delay = np.full((arr.n_mics, 1), 0.3e-3) + np.linspace(0, 5e-6, arr.n_mics)[:, None]
    peak = np.abs(e.gain).max()
    d = Echoes(
        np.hstack([direct_delay, e.delay_s]),
        np.hstack([np.full((arr.n_mics, 1), 10 * peak), e.gain]),
        np.hstack([np.full((arr.n_mics, 1), 0.1), e.path_length_m]),
        np.concatenate([[0], e.order]),
        np.concatenate([[0.0], e.angles()]),
    )
    resp = PathResponse(emitter_radius_m=0.004)
    ref = filtered_per_path(d, wf, resp, FS, 16384)
    echoes_only = filtered_per_path(e, wf, resp, FS, 16384)
    out = render_baseband(d, Capture(arr, wf, FS, 16384, C), BASEBAND, resp, -60.0)
    assert np.linalg.norm(ref - echoes_only) > 5 * np.linalg.norm(echoes_only)
    err = 20 * np.log10(np.linalg.norm(out - ref) / np.linalg.norm(echoes_only))
    assert err <= -55


def test_moving_baseband_render_with_a_direct_path_matches_the_full_rate_one():
    """A moving pose with a direct path (order 0, 20 dB above the echoes) and path
    responses: at baseband (the direct path summed in time onto the echoes' band)
    against the full-rate renderer, within -58 dB of the echoes' energy."""
    arr, pose, traj, paths, n, a = _drive(4)
    wf = P.rtis_call("default_25_50")
    e = a.echoes
    order = np.array([0, 1, 1, 1])
    gain = e.gain * np.array([10.0, 1, 1, 1])
    echoes = Echoes(e.delay_s, gain, e.path_length_m, order, e.angles())
    response = PathResponse(speed_of_sound_m_s=C, emitter_radius_m=0.005)

    def rendered(ech, rate, options):
        return render_doppler(ech, rate, wf, FS, n, response=response, options=options)

    full = rendered(echoes, a.rate, RenderOptions())
    base = rendered(echoes, a.rate, BASEBAND)
    keep = [1, 2, 3]
    sub = Echoes(
        e.delay_s[:, keep], e.gain[:, keep], e.path_length_m[:, keep], order[keep], e.angles()[keep]
    )
    only_echoes = rendered(sub, a.rate[:, keep], RenderOptions())
    assert np.linalg.norm(full - only_echoes) > 5 * np.linalg.norm(only_echoes)
    assert 20 * np.log10(np.linalg.norm(base - full) / np.linalg.norm(only_echoes)) <= -58


def test_few_paths_at_baseband_are_summed_in_time():
    """Under the 'auto' domain, echoes few enough for the sum in time (12 paths at
    4 microphones) are summed at the sample rate at either rate: the baseband
    render is the full-rate one, and both are within -65 dB of each path filtered
    exactly by its response (the responses' factorisation's error; the baseband
    route's, its band floor's, is larger)."""
    from acousim.synth.options import Capture
    from acousim.synth.render import render_baseband, render_with

    arr = P.ura(2, 2, 3.85e-3)
    wf = P.rtis_call("default_25_50")
    e = echoes_ahead(arr, n=12)
    resp = PathResponse(emitter_radius_m=0.004)
    capture = Capture(arr, wf, FS, 16384, C)
    ref = filtered_per_path(e, wf, resp, FS, 16384)
    auto = render_baseband(e, capture, RenderOptions(rate="baseband"), resp, -60.0)
    full = render_with(e, capture, RenderOptions(), resp)
    np.testing.assert_array_equal(auto, full)
    assert _db(auto, ref) <= -65
    assert _db(render_baseband(e, capture, BASEBAND, resp, -60.0), ref) > _db(auto, ref)


def test_few_moving_paths_at_baseband_are_summed_in_time():
    """The moving render likewise (with path responses: a single-precision render):
    4 paths at 2 microphones under 'auto' are the full-rate renderer's sum in time,
    within -58 dB of each path's exact echo filtered by its own response."""
    echoes, response, exact, (a, wf, n) = _filtered_drive(4)

    def rendered(options):
        return render_doppler(echoes, a.rate, wf, FS, n, response=response, options=options)

    auto = rendered(RenderOptions(rate="baseband"))
    np.testing.assert_array_equal(auto, rendered(RenderOptions()))
    assert _db(auto, exact) <= -58
