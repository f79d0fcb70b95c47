import numpy as np
import pytest

import processing as P
from tests.oracles.analytic import echo_recording


@pytest.mark.parametrize("emission_index", [0, 123])
@pytest.mark.parametrize("r", [0.5, 1.0, 2.37])
def test_reflector_peaks_at_two_r_over_c_within_one_sample(r, emission_index):
    arr = P.ura(1, 1, 1e-3)  # one microphone at the emitter
    fs, c = 500e3, 343.0
    rec = echo_recording(
        arr, [(0, 0, r, 1.0)], fs=fs, c=c, n_samples=8192, emission_index=emission_index
    )
    mf = P.matched_filter(rec.samples, rec.waveform.sampled(fs))
    expected = emission_index + 2 * r / c * fs
    assert abs(np.argmax(mf[0]) - expected) <= 1.0


def test_matched_filter_is_correlation_and_keeps_shape():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((2, 3, 300))
    h = rng.standard_normal(17)
    y = P.matched_filter(x, h)
    assert y.shape == x.shape
    ref = np.array(
        [[np.correlate(ch, h, "full")[h.size - 1 : h.size - 1 + 300] for ch in k] for k in x]
    )
    np.testing.assert_allclose(y, ref, atol=1e-10)


def test_compressed_pulse_width_matches_bandwidth():
    # the paper: the echo's (Rayleigh) width shrinks from ~20 cm to ~6 mm.  For a
    # 65 kHz sweep the -3 dB envelope width is 0.886 / B and null to null 2 / B.
    from scipy.signal import hilbert

    fs, c, B = 4e6, 343.0, 65e3
    rec = echo_recording(P.ura(1, 1, 1e-3), [(0, 0, 1.0, 1.0)], fs=fs, c=c, n_samples=40000)
    env = np.abs(hilbert(P.matched_filter(rec.samples[0], rec.waveform.sampled(fs))))
    above = np.flatnonzero(env >= env.max() * 10 ** (-3 / 20))
    width_m = (above[-1] - above[0]) / fs * c / 2
    assert width_m == pytest.approx(0.886 / B * c / 2, rel=0.15)
    assert 2 / B * c / 2 == pytest.approx(5.3e-3, abs=0.1e-3)


def test_non_finite_input_is_refused_naming_channel_and_sample():
    """One NaN would spread over its whole channel (an FFT): refused, as a Recording
    refuses it, with the argument, the channel and the sample."""
    x = np.zeros((2, 3, 50))
    x[1, 2, 17] = np.nan
    with pytest.raises(
        P.InputError,
        match=r"^x = nan: 1 non-finite sample\(s\); first at channel 2, sample 17, measurement 1$",
    ):
        P.matched_filter(x, np.ones(4))
    with pytest.raises(P.InputError, match=r"^x = inf: .*first at channel 0, sample 1$"):
        P.matched_filter(np.array([[1.0, np.inf, 2.0]]), np.ones(2))
    with pytest.raises(P.InputError, match=r"^template = nan: .*first at sample 1$"):
        P.matched_filter(np.ones((1, 5)), np.array([1.0, np.nan]))
    with pytest.raises(P.InputError, match=r"^template = \(2, 2\): must be a non-empty 1-D"):
        P.matched_filter(np.ones((1, 5)), np.ones((2, 2)))
