"""Broadband energyscapes (DAS, DAS-CF, DMAS2-5(-CF)) and wideband Capon/MUSIC.

References are independent of processing.imaging.broadband.energyscape: exact analytic echoes
(tests.oracles.analytic.echo_recording), a brute-force elementary symmetric polynomial, and the
plain time-domain delay-and-sum written here at the full sample rate.
"""

from itertools import combinations
from math import comb

import numpy as np
import pytest
from scipy.signal import hilbert

import processing as P
from processing.imaging.broadband import energyscape as B
from processing.imaging.broadband import engines as E
from tests.oracles.analytic import echo_recording

WF = P.rtis_call("default_25_50")
FS = 450e3
URA = P.ura(8, 8, 0.0055)


def _peak(es):
    r, g = np.unravel_index(int(np.argmax(es.power)), es.power.shape)
    d = es.directions
    return np.rad2deg(d.azimuth_rad[g]), np.rad2deg(d.elevation_rad[g]), es.range_m[r]


@pytest.fixture(scope="module")
def ertis():
    try:
        return P.ertis_v3d1()
    except Exception as exc:  # the layout is fetched from the rtisdev wheel
        pytest.skip(f"eRTIS layout unavailable: {exc}")


@pytest.mark.parametrize("method", B.BROADBAND_METHODS)
@pytest.mark.parametrize("focus", ["far", "near"])
def test_every_method_peaks_at_the_reflector_ura(method, focus):
    rec = echo_recording(URA, [(-30, 0, 1.5, 1.0)], fs=FS, n_samples=8192, waveform=WF)
    settings = B.BroadbandSettings(range_limits_m=(0.5, 3.0), focus=focus)
    es = B.energyscape(rec, B.fan(n=61), method, settings)  # 3 degree steps
    az, el, r = _peak(es)
    assert az == pytest.approx(-30, abs=1e-9)
    assert r == pytest.approx(1.5, abs=es.bin_range_m)


@pytest.mark.parametrize("method", ["das-bb", "das-cf-bb", "dmas3-bb", "dmas5-cf-bb"])
def test_every_method_peaks_at_the_reflector_ertis_3d(method, ertis):
    rec = echo_recording(ertis, [(24, -12, 2.2, 1.0)], fs=FS, n_samples=8192, waveform=WF)
    grid = P.Grid.degrees((0, 40), (-24, 0), 4.0)
    es = B.energyscape(rec, grid, method, B.BroadbandSettings(range_limits_m=(1.0, 3.0)))
    az, el, r = _peak(es)
    assert (az, el) == pytest.approx((24, -12), abs=1e-9)
    assert r == pytest.approx(2.2, abs=es.bin_range_m)


def test_near_field_focus_beats_far_field_steering_close_by(ertis):
    # 0.3 m is well inside the aperture's Fraunhofer distance: far-field steering
    # smears the echo, focusing at each range restores it
    rec = echo_recording(ertis, [(10, 0, 0.3, 1.0)], fs=FS, n_samples=4096, waveform=WF)
    lim = (0.15, 0.6)
    near = B.energyscape(rec, B.fan(n=181), "das-bb", B.BroadbandSettings(lim, focus="near"))
    far = B.energyscape(rec, B.fan(n=181), "das-bb", B.BroadbandSettings(lim, focus="far"))
    assert _peak(near)[0] == pytest.approx(10, abs=1.0)
    assert near.power.max() > far.power.max()


def test_plain_time_domain_formula(ertis):
    """DAS against delay-and-sum at the full rate: matched filter by correlation,
    fractional delays by a phase ramp, Hilbert envelope, then the same block mean."""
    rec = echo_recording(
        ertis, [(-15, 0, 1.2, 1.0), (35, 0, 2.0, 0.5)], fs=FS, n_samples=8192, waveform=WF
    )
    settings = B.BroadbandSettings(range_limits_m=(0.8, 2.4), decimation=1)
    dirs = B.fan((-60, 60), 25)
    es = B.energyscape(rec, dirs, "das-bb", settings)
    x = rec.samples / np.abs(rec.samples).max()
    h = WF.sampled(FS)
    T = x.shape[1]
    mf = np.array(
        [np.correlate(np.concatenate([xm, np.zeros(h.size)]), h, "valid")[:T] for xm in x]
    )
    n = 4 * T
    f = np.fft.rfftfreq(n, 1 / FS)
    lo, hi = WF.band_hz
    spec = np.fft.rfft(mf, n) * ((f >= lo) & (f <= hi))
    u = dirs.unit()
    d = u @ (ertis.positions_m + ertis.emitter_m).T / rec.speed_of_sound_m_s  # (G, M)
    beams = np.fft.irfft((spec[None] * np.exp(-2j * np.pi * f * d[..., None])).sum(1), n)
    env = np.abs(hilbert(beams[:, :T], axis=-1)) ** 2  # (G, T)
    t = np.arange(T) / FS
    rng = rec.speed_of_sound_m_s * t / 2
    plain = np.array([np.interp(es.range_m, rng, e) for e in env]).T  # (R, G)
    # same peaks, same direction pattern at the peak range
    r, g = np.unravel_index(np.argmax(plain), plain.shape)
    assert np.unravel_index(np.argmax(es.power), es.power.shape)[1] == g
    cut_es = es.power[r] / es.power[r].max()
    cut_plain = plain[r] / plain[r].max()
    assert np.max(np.abs(cut_es - cut_plain)) < 0.05  # band tapers differ slightly
    prof_es, prof_plain = es.power.max(1), plain.max(1)
    assert abs(es.range_m[np.argmax(prof_es)] - es.range_m[np.argmax(prof_plain)]) <= 0.005


def test_newton_girard_dmas_equals_brute_force_products():
    rng = np.random.default_rng(3)
    s = rng.standard_normal((6, 5)) + 1j * rng.standard_normal((6, 5))  # M=6, N=5
    for order in (2, 3, 4, 5):
        root = s * np.abs(s) ** (1 / order - 1)
        brute = sum(np.prod(root[list(c)], axis=0) for c in combinations(range(6), order))
        want = np.abs(brute / comb(6, order)) ** 2
        np.testing.assert_allclose(B.combine(s, order, False), want, rtol=1e-10)
    cf = np.abs(s.sum(0)) ** 2 / (6 * (np.abs(s) ** 2).sum(0))
    np.testing.assert_allclose(B.combine(s, 1, True), np.abs(s.mean(0)) ** 2 * cf, rtol=1e-12)
    # coherent channels: every method gives the channel's power
    c = np.tile(2.0 * np.exp(0.3j), (8, 3))
    for order in (1, 2, 5):
        for cf in (False, True):
            np.testing.assert_allclose(B.combine(c, order, cf), 4.0, rtol=1e-12)


def test_dmas5_cf_dynamic_range_exceeds_das(ertis):
    rec = echo_recording(ertis, [(20, 0, 2.0, 1.0)], fs=FS, n_samples=16384, waveform=WF)
    dirs = B.fan()
    bb = B.baseband(rec, B.BroadbandSettings())
    az = np.rad2deg(dirs.azimuth_rad)

    def dr(method):
        es = B.energyscape(rec, dirs, method, bb=bb)
        p = es.power
        r, g = np.unravel_index(np.argmax(p), p.shape)
        away = (np.abs(es.range_m - es.range_m[r])[:, None] > 0.1) | (np.abs(az - az[g])[None] > 10)
        return 10 * np.log10(p.max() / np.percentile(p[away], 99))

    assert dr("dmas5-cf-bb") > dr("das-bb") + 30


def test_sphere_partition_is_equal_area_and_frontal():
    d = B.sphere_partition(1000)
    assert 950 <= d.size <= 1050
    u = d.unit()
    assert np.all(u[:, 0] > 0)
    assert d.solid_angle_sr.sum() == pytest.approx(2 * np.pi, rel=0.06)
    # fairly uniform: nearest-neighbour angles within a factor 2.5 of each other
    cos = np.clip(u @ u.T, -1, 1)
    np.fill_diagonal(cos, -1)
    nn = np.arccos(cos.max(1))
    assert nn.max() / nn.min() < 2.5
    full = B.sphere_partition(500, frontal=False)
    assert full.size == 500


def test_scale_free_inputs():
    rec = echo_recording(URA, [(10, 0, 1.0, 1.0)], fs=FS, n_samples=4096, waveform=WF)
    s = B.BroadbandSettings(range_limits_m=(0.5, 1.5))
    ref = B.energyscape(rec, B.fan(n=37), "dmas5-cf-bb", s).power
    for scale in (1e-160, 1e160):
        got = B.energyscape(rec.with_samples(rec.samples * scale), B.fan(n=37), "dmas5-cf-bb", s)
        np.testing.assert_allclose(got.power, ref, rtol=1e-5, atol=1e-7 * ref.max())


@pytest.mark.parametrize("method", ["das-bb", "dmas5-cf-bb", "capon-fbss-wb", "music-fbss-wb"])
def test_acoustic_images_give_the_same_image_face(method):
    rec = echo_recording(URA, [(-20, 10, 1.0, 1.0)], fs=FS, n_samples=4096, waveform=WF)
    settings = P.ProcessingSettings(grid=P.Grid.degrees((-40, 40), (-20, 20), 2.0))
    img = P.acoustic_images(rec, [method], settings)[method]
    assert isinstance(img, P.Image)
    pk = img.peaks(threshold_db=-3, max_peaks=1)
    assert np.rad2deg(pk.azimuth_rad[0]) == pytest.approx(-20, abs=2.01)
    assert np.rad2deg(pk.elevation_rad[0]) == pytest.approx(10, abs=2.01)
    assert pk.range_m[0] == pytest.approx(1.0, abs=0.03)
    assert P.angular_resolution(img) > 0


@pytest.mark.parametrize("method", ["capon-wb", "music-wb"])
def test_wideband_methods_on_the_irregular_array(method, ertis):
    rec = echo_recording(ertis, [(25, -5, 1.8, 1.0)], fs=FS, n_samples=8192, waveform=WF)
    settings = P.ProcessingSettings(grid=P.Grid.degrees((-60, 60), (-30, 30), 1.0))
    img = P.acoustic_images(rec, [method], settings)[method]
    pk = img.peaks(threshold_db=-3, max_peaks=1)
    assert np.rad2deg(pk.azimuth_rad[0]) == pytest.approx(25, abs=1.01)
    assert np.rad2deg(pk.elevation_rad[0]) == pytest.approx(-5, abs=1.01)
    assert pk.range_m[0] == pytest.approx(1.8, abs=0.03)


def test_memory_estimate_refuses_a_huge_grid():
    rec = echo_recording(URA, [(0, 0, 1.0, 1.0)], fs=FS, n_samples=4096, waveform=WF)
    grid = P.Grid.degrees(elevation=(-90, 90), step=0.01)
    with pytest.raises(P.InputError, match=r"GiB.*limit"):
        P.acoustic_images(rec, ["das"], P.ProcessingSettings(grid=grid))
    with pytest.raises(P.InputError, match=r"GiB.*limit"):
        P.acoustic_images(rec, ["das-bb"], P.ProcessingSettings(grid=grid))
    small = P.ProcessingSettings(
        grid=P.Grid.degrees(elevation=(-90, 90), step=10.0), memory_limit_bytes=1e3
    )
    with pytest.raises(P.InputError, match="limit of 0.0 GiB"):
        P.acoustic_images(rec, ["das"], small)


@pytest.mark.parametrize("focus", ["far", "near"])
@pytest.mark.parametrize("method", ["das-bb", "das-cf-bb", "dmas3-bb", "dmas5-cf-bb"])
def test_compiled_engine_matches_the_numpy_reference(method, focus):
    pytest.importorskip("numba")
    rec = echo_recording(
        URA, [(15, 0, 1.2, 1.0), (-50, 0, 1.6, 0.3)], fs=FS, n_samples=4096, waveform=WF, noise=0.01
    )
    s = dict(range_limits_m=(0.5, 2.0), focus=focus)
    ref = B.energyscape(rec, B.fan(n=61), method, B.BroadbandSettings(**s, engine="numpy")).power
    got = B.energyscape(rec, B.fan(n=61), method, B.BroadbandSettings(**s, engine="numba")).power
    # far field: cubic interpolation (U = 8) against exact phase ramps, about -50 dB
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-2 * ref.max())


@pytest.mark.parametrize("spectral_max", [0, 512])
def test_compiled_plain_das_both_paths_match_the_numpy_reference(spectral_max, monkeypatch):
    """Plain far-field DAS: the interpolating kernel (many directions) and the exact
    frequency-domain sum (few) against the numpy engine, two measurements."""
    pytest.importorskip("numba")
    monkeypatch.setattr(E, "_SPECTRAL_DAS_MAX", spectral_max)
    one = echo_recording(URA, [(15, 0, 1.2, 1.0)], fs=FS, n_samples=4096, waveform=WF, noise=0.01)
    two = np.stack([one.samples, 0.5 * one.samples])
    rec = P.Recording(two, FS, URA, WF, one.speed_of_sound_m_s, 0)
    s = dict(range_limits_m=(0.5, 2.0))
    ref = B.energyscape(rec, B.fan(n=61), "das-bb", B.BroadbandSettings(**s, engine="numpy")).power
    got = B.energyscape(rec, B.fan(n=61), "das-bb", B.BroadbandSettings(**s, engine="numba")).power
    tol = 1e-2 if spectral_max == 0 else 1e-5  # cubic interpolation, or float32 only
    np.testing.assert_allclose(got, ref, rtol=0, atol=tol * ref.max())


def test_real_ertis_sample_echo_stays_where_das_puts_it():
    """The real eRTIS measurement (rtisdev-sample): every broadband method finds the
    echo at 3.2 m where narrowband DAS does (same direction within a grid step)."""
    try:
        from hardware import decode_frame
        from processing.sensor.rtisdev import sample_recording

        raw = np.frombuffer(sample_recording().read_bytes(), "<u4")
        rec = decode_frame(raw, P.ertis_v3d1(), P.rtis_call("default_25_50"))
    except Exception as exc:  # the sample comes from the rtisdev wheel (network)
        pytest.skip(f"real eRTIS sample unavailable: {exc}")
    grid = P.Grid.degrees((-30, 14), (-10, 14), 2.0)
    settings = P.ProcessingSettings(grid=grid, range_limits_m=(0.5, 5.0))
    methods = ["das", "das-bb", "das-cf-bb", "dmas3-bb", "dmas5-cf-bb"]
    images = P.acoustic_images(rec, methods, settings)
    ref = images["das"].peaks(-3, max_peaks=1)
    assert ref.range_m[0] == pytest.approx(3.2, abs=0.03)
    for m in methods[1:]:
        pk = images[m].peaks(-3, max_peaks=1)
        assert pk.range_m[0] == pytest.approx(ref.range_m[0], abs=0.02), m
        assert abs(pk.azimuth_rad[0] - ref.azimuth_rad[0]) <= np.deg2rad(2.01), m
        assert abs(pk.elevation_rad[0] - ref.elevation_rad[0]) <= np.deg2rad(2.01), m


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_phat_weighting_and_repeated_measurements(engine):
    if engine == "numba":
        pytest.importorskip("numba")
    rec = echo_recording(URA, [(39, 0, 1.1, 1.0)], fs=FS, n_samples=4096, waveform=WF, noise=0.01)
    s = B.BroadbandSettings(range_limits_m=(0.5, 2.0), weighting="phat", engine=engine)
    es = B.energyscape(rec, B.fan(n=61), "das-cf-bb", s)
    az, _, r = _peak(es)
    assert az == pytest.approx(39, abs=1e-9)
    assert r == pytest.approx(1.1, abs=es.bin_range_m)
    # K identical measurements average to the single one
    twice = rec.with_samples(np.stack([rec.samples, rec.samples]))
    s = B.BroadbandSettings(range_limits_m=(0.5, 2.0), engine=engine)
    one = B.energyscape(rec, B.fan(n=61), "dmas3-bb", s).power
    two = B.energyscape(twice, B.fan(n=61), "dmas3-bb", s).power
    np.testing.assert_allclose(two, one, rtol=1e-5, atol=1e-7 * one.max())


def test_polyphase_upsampling_equals_zero_padded_fft():
    """The U phases of the compiled path's upsampled baseband, against the band-limited
    interpolation written out as a sum of complex exponentials in the test."""
    from processing.imaging.broadband.energyscape import Baseband
    from processing.imaging.broadband.engines import _polyphase

    N, U = 12, 4
    rng = np.random.default_rng(2)
    spec = rng.standard_normal((1, 2, N)) + 1j * rng.standard_normal((1, 2, N))
    spec[..., N // 2] = 0  # no Nyquist bin: its sign convention is then immaterial
    bb = Baseband(spec, np.zeros(N), 0.0, 1.0, 0.0)
    f = np.fft.fftfreq(N, 1 / N)
    t = np.arange(N * U) / U  # fine sample times in baseband samples
    want = (spec[..., None, :] * np.exp(2j * np.pi * f * t[:, None] / N)).sum(-1) / N
    got = _polyphase(bb, U)  # (K, M, U, N): [..., p, n] is fine sample n U + p
    np.testing.assert_allclose(got.transpose(0, 1, 3, 2).reshape(1, 2, -1), want, atol=1e-5)


def test_a_recording_too_short_for_the_range_limits_says_so():
    """100 samples after the emission at 450 kHz reach c * 100 / fs / 2 = 0.0381 m at
    343 m/s, short of the default minimum range 0.25 m: one error naming both."""
    rec = echo_recording(URA, [], fs=FS, n_samples=110, waveform=WF, emission_index=10)
    end = 343.0 * 100 / FS / 2
    want = (
        rf"^ProcessingSettings.range_limits_m = \(0.25, inf\): the recording is too short "
        rf"for the range limits: .* reach {end:.4g} m, not beyond the minimum range 0.25 m$"
    )
    for method in ["das-bb", "das", "capon"]:  # every family: no bin could be imaged
        with pytest.raises(P.InputError, match=want):
            P.acoustic_image(rec, method)
