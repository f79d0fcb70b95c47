import numpy as np
import pytest
from scipy.signal import hilbert

import processing as P


def inst_freq(x, fs):
    phase = np.unwrap(np.angle(hilbert(x)))
    return np.diff(phase) * fs / (2 * np.pi)


def test_paper_chirp_sweeps_20_to_85_khz():
    fs = 2e6
    x = P.paper_chirp().sampled(fs)
    assert x.size == 2000
    f = inst_freq(x, fs)
    assert np.median(f[100:200]) == pytest.approx(20e3 + 65e6 * 150 / fs, rel=0.02)
    assert np.median(f[-200:-100]) == pytest.approx(20e3 + 65e6 * 1850 / fs, rel=0.02)


def test_hyperbolic_period_grows_linearly_and_is_tapered():
    fs = 4.5e6
    wf = P.rtis_call("default_25_50")
    x = wf.sampled(fs)
    f = inst_freq(x, fs)
    n = x.size
    mid = slice(int(0.2 * n), int(0.8 * n))
    t = np.arange(n - 1)[mid] / fs
    period = 1 / f[mid]
    slope, intercept = np.polyfit(t, period, 1)
    assert intercept == pytest.approx(1 / 50e3, rel=0.01)
    assert slope * wf.duration_s == pytest.approx(1 / 25e3 - 1 / 50e3, rel=0.02)
    env = np.abs(hilbert(x))
    assert env[0] < 0.01 and env[n // 2] == pytest.approx(1, abs=0.02)
    assert env[int(0.05 * n)] == pytest.approx(0.5, abs=0.05)  # half-way up the ramp


def test_waveform_at_is_zero_outside_and_matches_sampled():
    wf = P.paper_chirp()
    fs = 500e3
    np.testing.assert_array_equal(wf.at(np.array([-1e-6, 1e-3, 2e-3])), 0.0)
    np.testing.assert_allclose(wf.at(np.arange(500) / fs), wf.sampled(fs))


def test_bad_waveforms_are_refused():
    with pytest.raises(ValueError, match="kind"):
        P.Waveform("square", 1, 2, 1)
    with pytest.raises(ValueError, match="duration"):
        P.linear_chirp(duration_s=0)


@pytest.mark.parametrize("kind", ["linear", "hyperbolic"])
@pytest.mark.parametrize("f0, f1, T", [(20e3, 85e3, 1e-3), (85e3, 20e3, 2e-3), (40e3, 40e3, 1e-3)])
def test_a_sweep_is_scipys_chirp_to_the_bit(kind, f0, f1, T):
    """The calls' phase is written out (scipy.signal takes a second to import): the
    samples are scipy.signal.chirp's, sine-phased, bit for bit."""
    from scipy.signal import chirp

    fs = 450e3
    t = np.arange(int(np.ceil(T * fs))) / fs
    w = P.Waveform(kind, f0, f1, T, taper=0.0)
    assert np.array_equal(w.at(t), chirp(t, f0, T, f1, method=kind, phi=-90))
    assert np.array_equal(w.sampled(fs), chirp(t, f0, T, f1, method=kind, phi=-90))
