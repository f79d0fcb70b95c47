"""Aligning a simulation on a real recording of the same sensor (step 1 of
:mod:`acousim.compare.comparison`).

The time of emission comes from the direct emitter -> microphone path: the lag that
best aligns the first milliseconds of the two matched-filter outputs, refined to a
fraction of a sample (parabolic).  Without a direct path in the simulation, the
whole recording sets the lag.  Then one overall gain, by least squares on the
matched-filter envelopes after the direct path (the echoes).  Both are reported
(:class:`Alignment`), never hidden.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.fft import next_fast_len
from scipy.signal import hilbert

import processing as P

__all__ = [
    "DIRECT_WINDOW_S",
    "Alignment",
    "AlignedEnvelopes",
    "align",
    "align_envelopes",
    "aligned_recording",
    "envelope",
    "fractional_shift",
    "matched_filter_output",
    "mean_samples",
]

DIRECT_WINDOW_S = 1.0e-3  # beyond the call: the direct path's part used for alignment


@dataclass(frozen=True)
class Alignment:
    """Shift applied to the simulation (samples, and seconds) and gain real/sim."""

    emission_shift_samples: float
    emission_shift_s: float
    gain: float


@dataclass(frozen=True, eq=False)
class AlignedEnvelopes:
    """The alignment and the two matched-filter envelopes (M, T): the real one, and
    the simulated one shifted by the alignment's lag and scaled by its gain."""

    alignment: Alignment
    real: np.ndarray
    sim: np.ndarray


def mean_samples(rec: P.Recording) -> np.ndarray:
    """The samples (M, T) of `rec`; of a recording of K measurements (K, M, T), their
    mean over the measurements."""
    return rec.samples if rec.samples.ndim == 2 else rec.samples.mean(axis=0)


def matched_filter_output(rec: P.Recording) -> np.ndarray:
    """The matched filter (its call) applied to :func:`mean_samples` of `rec`: (M, T)."""
    return P.matched_filter(mean_samples(rec), rec.waveform.sampled(rec.sample_rate_hz))


def envelope(x: np.ndarray) -> np.ndarray:
    """Envelope |analytic signal| of x (..., T), zero-padded to twice its length: the
    FFT-based Hilbert transform is circular, and without padding the strong direct
    path at the start wraps around into the last samples (the range profiles' last
    0.5 m climbed 30-50 dB)."""
    n = x.shape[-1]
    return np.abs(hilbert(x, N=next_fast_len(2 * n), axis=-1)[..., :n])


def fractional_shift(x: np.ndarray, samples: float) -> np.ndarray:
    """Delay x (..., T) by a fractional number of samples (FFT phase shift, zero-padded
    to twice its length)."""
    n = x.shape[-1]
    f = np.fft.rfftfreq(2 * n)
    X = np.fft.rfft(x, 2 * n, axis=-1) * np.exp(-2j * np.pi * f * samples)
    return np.fft.irfft(X, 2 * n, axis=-1)[..., :n]


def align(real: P.Recording, sim: P.Recording, max_lag_s: float = 0.5e-3) -> tuple[float, float]:
    """(shift in samples to apply to `sim`, gain real/sim)."""
    fit = align_envelopes(
        real, matched_filter_output(real), matched_filter_output(sim), max_lag_s
    ).alignment
    return fit.emission_shift_samples, fit.gain


def _lag(real: P.Recording, mf_r: np.ndarray, mf_s: np.ndarray, max_lag_s: float) -> float:
    """The lag (samples, within `max_lag_s`) that best aligns the simulated matched-filter
    output `mf_s` (M, T) on the real one `mf_r`: on the direct path's window, or on the
    whole recording when the simulation has (almost) no direct path."""
    fs = real.sample_rate_hz
    win = int((real.waveform.duration_s + DIRECT_WINDOW_S) * fs)
    early = np.sum(mf_s[:, :win] ** 2) >= 0.01 * np.sum(mf_s**2)
    span = win if early else mf_s.shape[-1]
    a, b = mf_r[:, :span], mf_s[:, :span]
    max_lag = int(max_lag_s * fs)
    n = 2 * span
    xc = np.fft.irfft(np.fft.rfft(a, n) * np.conj(np.fft.rfft(b, n)), n).sum(axis=0)
    lags = np.concatenate([np.arange(0, max_lag + 1), np.arange(-max_lag, 0)])
    vals = np.concatenate([xc[: max_lag + 1], xc[n - max_lag :]])
    k = int(np.argmax(vals))
    lag = float(lags[k])
    # parabolic refinement
    left = vals[k - 1]  # vals runs over lags 0..max, -max..-1: index -1 is lag -1
    right = vals[(k + 1) % len(vals)]
    den = left - 2 * vals[k] + right
    if den < 0:
        lag += 0.5 * (left - right) / den
    return lag


def align_envelopes(
    real: P.Recording, mf_r: np.ndarray, mf_s: np.ndarray, max_lag_s: float = 0.5e-3
) -> AlignedEnvelopes:
    """The alignment and the matched-filter envelopes, from the matched-filter outputs
    (M, T) of `real` (`mf_r`) and of the simulation (`mf_s`) computed once by the
    caller (:func:`matched_filter_output`)."""
    lag = _lag(real, mf_r, mf_s, max_lag_s)
    # the gain: least squares on the matched-filter envelopes after the direct path
    # (the echoes): envelopes do not depend on the carrier's phase, and the direct
    # path of a real sensor is often clipped and would set the gain alone.  The
    # matched filter commutes with the delay, so its output is shifted, not recomputed.
    win = int((real.waveform.duration_s + DIRECT_WINDOW_S) * real.sample_rate_hz)
    env_s = envelope(fractional_shift(mf_s, lag))
    env_r = envelope(mf_r)
    denom = float(np.sum(env_s[:, win:] ** 2))
    gain = float(np.sum(env_r[:, win:] * env_s[:, win:]) / denom) if denom > 0 else 0.0
    fit = Alignment(lag, lag / real.sample_rate_hz, gain)
    return AlignedEnvelopes(fit, env_r, gain * env_s)


def aligned_recording(sim: P.Recording, alignment: Alignment) -> P.Recording:
    """`sim` (:func:`mean_samples`) shifted by the alignment's lag and scaled by its gain."""
    shifted = fractional_shift(mean_samples(sim), alignment.emission_shift_samples)
    return sim.with_samples(alignment.gain * shifted)
