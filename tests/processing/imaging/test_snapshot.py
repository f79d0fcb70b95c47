import numpy as np
import pytest
from scipy.signal import ShortTimeFFT, get_window

import processing as P
from tests.oracles.analytic import echo_recording


def test_energy_gate_keeps_bins_around_the_echo():
    rec = echo_recording(P.paper_8x8(), [(0, 0, 1.0, 1.0)])
    mf = P.matched_filter(rec.samples, rec.waveform.sampled(rec.sample_rate_hz))
    snap = P.stft_snapshot(mf, rec.sample_rate_hz, frequency_hz=31250, gate=P.PAPER_GATE)
    assert snap.frequency_hz == 31250
    assert snap.data.shape == (64, snap.n_bins)
    assert np.all(np.abs(snap.range_m - 1.0) < 0.06)
    assert snap.energy.min() >= 0.5 * snap.energy.max()
    assert snap.bin_range_m == pytest.approx(343 * 16 / 500e3 / 2)


@pytest.mark.parametrize("searched", [False, True])
def test_same_transform_as_scipy_shorttimefft(searched):
    """The snapshots are scipy's STFT at the bin: given, or found by the band's search
    (whose products are then the snapshots), with range limits keeping some frames."""
    rng = np.random.default_rng(1)
    x = rng.standard_normal((3, 2048))
    x += np.sin(2 * np.pi * 31250 * np.arange(2048) / 500e3)  # the strongest bin: 16
    if searched:
        gate = P.BinGate(energy_fraction=0, range_limits_m=(0.1, 0.6))
        snap = P.stft_snapshot(x, 500e3, band_hz=(20e3, 45e3), gate=gate)
        assert snap.frequency_hz == 31250 and np.all((snap.range_m >= 0.1) & (snap.range_m <= 0.6))
    else:
        snap = P.stft_snapshot(x, 500e3, frequency_hz=31250, gate=P.BinGate(energy_fraction=0))
    sft = ShortTimeFFT(get_window("hann", 256), 16, 500e3)
    ref = sft.stft(x)  # (3, F, P), slices centred on p * hop
    col = ref[:, 16, :]
    # our bin p is scipy's slice centred at p * hop + 128, i.e. slice index p + 8
    t_ref = sft.t(2048)
    j = np.rint((snap.time_s - t_ref[0]) / (16 / 500e3)).astype(int)
    np.testing.assert_allclose(t_ref[j], snap.time_s)
    np.testing.assert_allclose(np.abs(snap.data), np.abs(col[:, j]), rtol=1e-10)
    # relative phase between channels is what DOA uses
    np.testing.assert_allclose(
        snap.data[1] * snap.data[0].conj(), col[1, j] * col[0, j].conj(), rtol=1e-9, atol=1e-9
    )


def test_the_gates_defaults_are_the_pipelines():
    """One declaration: stft_snapshot's gate is the one ProcessingSettings (and so the
    command line) uses by default; the paper's is PAPER_GATE."""
    s = P.ProcessingSettings()
    assert P.BinGate() == P.BinGate(s.energy_fraction, s.range_limits_m, s.max_bins)
    assert P.BinGate().energy_fraction == 1e-3 and P.BinGate().range_limits_m == (0.25, np.inf)
    assert P.PAPER_GATE == P.BinGate(energy_fraction=0.5, range_limits_m=None)
    # the default gate keeps a weak echo (-20 dB) beside a strong one; the paper's not
    rec = echo_recording(P.paper_8x8(), [(0, 0, 0.6, 1.0), (0, 0, 1.1, 0.1)])
    mf = P.matched_filter(rec.samples, rec.waveform.sampled(rec.sample_rate_hz))
    kept = P.stft_snapshot(mf, rec.sample_rate_hz, frequency_hz=31250).range_m
    assert np.any(np.abs(kept - 1.1) < 0.03) and kept.min() >= 0.25
    paper = P.stft_snapshot(mf, rec.sample_rate_hz, frequency_hz=31250, gate=P.PAPER_GATE)
    assert np.any(np.abs(paper.range_m - 0.6) < 0.03)
    assert not np.any(np.abs(paper.range_m - 1.1) < 0.03)


def test_multi_measurement_snapshots_and_band():
    rec = echo_recording(P.paper_8x8(), [(0, 0, 1.0, 1.0)], noise=0.01)
    mf = P.matched_filter(np.stack([rec.samples] * 3), rec.waveform.sampled(500e3))
    snap = P.stft_snapshot(mf, 500e3, band_hz=(20e3, 34e3))
    assert snap.data.ndim == 3 and snap.data.shape[2] == 3
    assert 20e3 <= snap.frequency_hz <= 34e3


def test_all_zero_recording_keeps_no_bins_and_range_limits():
    snap = P.stft_snapshot(np.zeros((4, 1024)), 500e3)
    assert snap.n_bins == 0 and snap.data.shape == (4, 0)
    rec = echo_recording(P.paper_8x8(), [(0, 0, 1.0, 1.0), (0, 0, 0.5, 4.0)])
    mf = P.matched_filter(rec.samples, rec.waveform.sampled(500e3))
    snap = P.stft_snapshot(
        mf, 500e3, frequency_hz=31250, gate=P.BinGate(0.5, range_limits_m=(0.8, 2.0))
    )
    assert snap.n_bins > 0 and np.all(snap.range_m > 0.9)


def test_bad_stft_parameters():
    with pytest.raises(ValueError, match="overlap"):
        P.stft_snapshot(np.zeros((2, 1000)), 1e3, stft=P.Stft(window=64, overlap=64))
    with pytest.raises(ValueError, match="fewer than the window"):
        P.stft_snapshot(np.zeros((2, 10)), 1e3)


def _strongest_by_full_fft(x, fs, band, limits, c=343.0, window=256, hop=16):
    """Independent reference: every whole frame's full rfft (hann), the power summed
    over channels and the frames whose centre's range lies within `limits`, the
    strongest bin inside `band`."""
    win = get_window("hann", window)
    starts = np.arange(0, x.shape[-1] - window + 1, hop)
    ranges = c * (starts + window // 2) / fs / 2
    starts = starts[(ranges >= limits[0]) & (ranges <= limits[1])]
    power = sum(
        (np.abs(np.fft.rfft(x[:, s : s + window] * win, axis=-1)) ** 2).sum(axis=0) for s in starts
    )
    freqs = np.fft.rfftfreq(window, 1 / fs)
    inband = np.flatnonzero((freqs >= band[0]) & (freqs <= band[1]))
    order = np.argsort(power[inband])[::-1]
    margin = (power[inband][order[0]] - power[inband][order[1]]) / power[inband][order[0]]
    return freqs[inband[order[0]]], margin


@pytest.mark.parametrize("seed", range(6))
def test_strongest_bin_is_the_full_ffts(seed):
    """The band's bins alone (not the full FFT) give the same strongest bin."""
    rng = np.random.default_rng(seed)
    fs = 450e3
    t = np.arange(4096) / fs
    # noise plus a few tones of random levels inside and beside the band
    x = rng.standard_normal((5, t.size))
    for f in rng.uniform(15e3, 90e3, 4):
        x += rng.uniform(0.05, 0.5) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6, (5, 1)))
    band, limits = (25e3, 70e3), (0.3, 1.2)
    f_ref, margin = _strongest_by_full_fft(x, fs, band, limits)
    assert margin > 1e-9  # a real winner, not a tie decided by rounding
    gate = P.BinGate(energy_fraction=0, range_limits_m=limits)
    snap = P.stft_snapshot(x, fs, band_hz=band, gate=gate)
    assert snap.frequency_hz == f_ref
    # the same with the frames gathered at fixed ranges (tapered before the search)
    snap = P.stft_snapshot(
        x, fs, band_hz=band, gate=gate, stft=P.Stft(range_step_m=343 * 16 / fs / 2)
    )
    assert snap.frequency_hz == f_ref


@pytest.mark.parametrize("n", [1, 2, 3, 64, 240, 241, 1000])
def test_the_hann_window_is_scipys_to_the_bit(n):
    """The STFT's Hann window, made without importing scipy.signal, is the one
    scipy.signal.get_window gives (periodic), bit for bit; other names are scipy's."""
    from scipy.signal import get_window

    from processing.imaging.snapshot import stft_window

    np.testing.assert_array_equal(stft_window("hann", n), get_window("hann", n))
    np.testing.assert_array_equal(stft_window("hamming", n), get_window("hamming", n))


def test_imaging_does_not_import_scipy_signal():
    """An image made with the default window leaves scipy.signal unimported (its
    import is about half a second of every imaging process)."""
    import subprocess
    import sys
    from pathlib import Path

    code = (
        "import sys, processing as P\n"
        "from tests.oracles.analytic import echo_recording\n"
        "rec = echo_recording(P.paper_8x8(), [(10, 0, 1.0, 1.0)])\n"
        "P.acoustic_images(rec, ['das', 'music-fbss', 'music-wb'], P.ProcessingSettings())\n"
        "print('scipy.signal' in sys.modules)\n"
    )
    root = Path(__file__).resolve().parents[3]  # the tests' package is importable there
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root
    )
    assert out.stdout.strip() == "False"
