"""Rendering echoes into microphone signals: eq. 1 with fractional delays.

``s_m(t) = sum_n g[m, n] * w(t - d[m, n])``

The recorded call is band-limited, as the sensor's anti-alias filter makes it
(:meth:`processing.Waveform.band_limited`): an untapered chirp sampled directly
carries -42 dB of aliasing from its edges that no sampled system records.

Methods (``method=``), measured against ``reference`` in ``BENCHMARKS.md``:

``reference``
    The analytic call evaluated at ``t - d`` for every echo at 64 times the sample
    rate, low-passed at 0.8 times Nyquist and decimated: the exact band-limited
    echo (cost 64 M N L, L the call length in samples).
``exact``
    The analytic call evaluated at ``t - d`` on the samples (aliased edges).
``sinc``
    Each echo becomes a Kaiser-windowed sinc impulse of ``2 * taps`` samples at its
    fractional delay; the impulse responses are convolved with the band-limited call
    by FFT over the span that echoes reach.  Cost M N taps + M T log T.
``lagrange``
    The same with Lagrange interpolation through ``2 * taps`` samples.
``fft``
    Per microphone, the spectrum of the call times ``sum_n g e^{-j w d}``: exact
    fractional delays of the band-limited call, cost M N F; only for few echoes.
``nearest``
    Delays rounded to the nearest sample: a baseline, not for use.

No method adds a global delay: an echo with delay d peaks, after the matched
filter, at ``d * fs`` samples after the emission.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import fft as sfft
from scipy.signal import fftconvolve
from scipy.special import i0

from processing import Waveform
from processing.waveforms import ANTI_ALIAS_CUTOFF

from .echoes import Echoes

__all__ = ["render", "METHODS", "DEFAULT_METHOD", "DEFAULT_TAPS"]

METHODS = ("reference", "exact", "sinc", "lagrange", "fft", "nearest")
DEFAULT_METHOD = "sinc"
DEFAULT_TAPS = 6
KAISER_BETA = 8.0
_CHUNK = 2_000_000  # kernel entries per accumulation chunk (memory bound)
TABLE_PHASES = 1024


def render(
    echoes: Echoes,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    emission_index: int = 0,
    method: str = DEFAULT_METHOD,
    taps: int = DEFAULT_TAPS,
) -> np.ndarray:
    """Microphone signals of `echoes`, shape (M, T), float64.

    Echoes that start after the end of the window are expected to have been
    dropped by the caller (:func:`acousim.synth.model.simulate`); those that start
    inside it and run past its end are truncated.
    """
    if method not in METHODS:
        raise ValueError(f"unknown fractional-delay method {method!r}; choose one of {METHODS}")
    M = echoes.delay_s.shape[0]
    out = np.zeros((M, n_samples))
    if echoes.n_paths == 0:
        return out
    fs = sample_rate_hz
    d = echoes.delay_s * fs + emission_index  # (M, N) in samples
    g = echoes.gain
    if method == "exact":
        return _render_exact(d, g, waveform, fs, n_samples, out)
    if method == "reference":
        U = 64
        fine = _render_exact(
            d * U, g, waveform, fs * U, n_samples * U, np.zeros((M, n_samples * U))
        )
        spec = sfft.rfft(fine, axis=-1)
        spec[:, int(ANTI_ALIAS_CUTOFF * n_samples / 2) + 1 :] = 0.0
        return sfft.irfft(spec, n_samples * U, axis=-1)[:, ::U]
    call, start = waveform.band_limited(fs)
    d = d + start  # sample i of `call` is at i + start
    if method == "fft":
        return _render_fft(d, g, call, n_samples)
    # span of the output that echoes reach: only that part is computed
    half = 0 if method == "nearest" else taps
    lo = max(int(np.floor(d.min())) - half, 0)
    hi = min(int(np.ceil(d.max())) + half + call.size + 1, n_samples)
    if hi <= lo:
        return out
    n_span = hi - lo
    h = _impulses(d - lo, g, n_span, method, taps)  # (M, n_span)
    out[:, lo:hi] = fftconvolve(h, call[None, :], axes=-1)[:, :n_span]
    return out


def _render_exact(d, g, waveform, fs, n_samples, out):
    L = int(np.ceil(waveform.duration_s * fs)) + 1
    for m in range(d.shape[0]):
        for start in range(0, d.shape[1], 256):
            dm, gm = d[m, start : start + 256], g[m, start : start + 256]
            n0 = np.floor(dm).astype(int)
            idx = n0[:, None] + np.arange(L + 1)[None, :]  # samples each echo covers
            vals = gm[:, None] * waveform.at((idx - dm[:, None]) / fs)
            ok = (idx >= 0) & (idx < n_samples)
            np.add.at(out[m], idx[ok], vals[ok])
    return out


def _render_fft(d, g, call, n_samples):
    n = sfft.next_fast_len(n_samples + call.size, real=True)
    f = np.arange(n // 2 + 1) / n  # cycles per sample
    W = sfft.rfft(call, n)
    spec = np.empty((d.shape[0], f.size), complex)
    for m in range(d.shape[0]):
        spec[m] = W * (np.exp(-2j * np.pi * np.outer(f, d[m])) @ g[m])
    return sfft.irfft(spec, n, axis=-1)[:, :n_samples]


def _kernel(frac: np.ndarray, method: str, taps: int) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (K,) and weights (..., K), K = 2*taps, for fractional parts in [0, 1).

    Tap ``n0 + offsets[j]`` gets weight ``w[..., j]`` for an impulse at ``n0 + frac``.
    """
    offsets = np.arange(-taps + 1, taps + 1)
    if method == "sinc":
        x = offsets - frac[..., None]
        window = i0(KAISER_BETA * np.sqrt(np.clip(1 - (x / taps) ** 2, 0, 1)))
        return offsets, np.sinc(x) * window / i0(KAISER_BETA)
    # Lagrange basis polynomials through the K nodes, evaluated at frac
    diff = frac[..., None] - offsets
    w = np.empty(diff.shape)
    for j in range(offsets.size):
        others = np.delete(np.arange(offsets.size), j)
        w[..., j] = np.prod(diff[..., others], axis=-1) / np.prod(offsets[j] - offsets[others])
    return offsets, w


@lru_cache(maxsize=8)
def _kernel_table(method: str, taps: int) -> np.ndarray:
    """Kernel weights at TABLE_PHASES + 1 fractions in [0, 1]: (TABLE_PHASES + 1, 2*taps).

    Interpolating it linearly costs less than evaluating sinc and Bessel functions
    per echo; the interpolation error is below -100 dB (second order in 1/phases).
    """
    return _kernel(np.linspace(0.0, 1.0, TABLE_PHASES + 1), method, taps)[1]


def _impulses(d: np.ndarray, g: np.ndarray, n_span: int, method: str, taps: int) -> np.ndarray:
    """Sum of interpolated impulses, shape (M, n_span); d in samples from the span start."""
    M, N = d.shape
    h = np.zeros(M * n_span)
    base = (np.arange(M) * n_span)[:, None]
    if method == "nearest":
        idx = np.rint(d).astype(int)
        ok = (idx >= 0) & (idx < n_span)
        h += np.bincount((base + idx)[ok], g[ok], minlength=M * n_span)
        return h.reshape(M, n_span)
    step = max(1, _CHUNK // (M * 2 * taps))
    offsets = np.arange(-taps + 1, taps + 1)
    table = _kernel_table(method, taps)
    for s in range(0, N, step):
        dd, gg = d[:, s : s + step], g[:, s : s + step]
        n0 = np.floor(dd)
        # kernel weights: linear interpolation in a table of TABLE_PHASES fractions
        pos = (dd - n0) * TABLE_PHASES
        i = np.minimum(pos.astype(int), TABLE_PHASES - 1)
        t = (pos - i)[..., None]
        w = (1 - t) * table[i] + t * table[i + 1]
        idx = n0.astype(int)[..., None] + offsets  # (M, n, K)
        ok = (idx >= 0) & (idx < n_span)
        flat = (base[..., None] + idx)[ok]
        h += np.bincount(flat, (gg[..., None] * w)[ok], minlength=M * n_span)
    return h.reshape(M, n_span)
