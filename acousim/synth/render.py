"""Rendering echoes into microphone signals: eq. 1 with fractional delays.

``s_m(t) = sum_n g[m, n] * w(t - d[m, n])``

The recorded call is band-limited, as the sensor's anti-alias filter makes it
(:meth:`processing.Waveform.band_limited`): an untapered chirp sampled directly
carries -42 dB of aliasing from its edges that no sampled system records.

Interpolators (``interpolator=``, :data:`FractionalDelay`), measured against
``reference`` in ``BENCHMARKS.md``:

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

No interpolator adds a global delay: an echo with delay d peaks, after the matched
filter, at ``d * fs`` samples after the emission.

Where ``sinc``, ``lagrange`` and ``nearest`` sum the echoes (``domain=``,
:data:`~acousim.core.rendering.RenderDomain`): by FFT over the span the echoes
reach (cost set by the span: the recording's range), or in time, each path's
filtered call added at its delay through the same weights (:mod:`.timedomain`:
cost per path, microphone and call sample); by default whichever is estimated
cheaper.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from scipy import fft as sfft
from scipy.special import i0

from acousim.core.echoes import Echoes
from acousim.core.rendering import (
    DEFAULT_INTERPOLATOR,
    INTERPOLATORS,
    SHAPED_INTERPOLATORS,
    FractionalDelay,
    RenderDomain,
    ShapedDelay,
    check_interpolator,
)
from acousim.synth import baseband
from acousim.synth.response import PathResponse, factorise
from acousim.synth.timedomain import filtered_calls, prefer_time, render_time, trimmed
from processing import Waveform
from processing.base.kernels import optional_kernel
from processing.sensor.calls import ANTI_ALIAS_CUTOFF

__all__ = [
    "render",
    "render_with",
    "FractionalDelay",
    "ShapedDelay",
    "INTERPOLATORS",
    "SHAPED_INTERPOLATORS",
    "DEFAULT_INTERPOLATOR",
    "DEFAULT_TAPS",
    "check_interpolator",
]

DEFAULT_TAPS = 6
KAISER_BETA = 8.0
TABLE_PHASES = 4096
FFT_WORKERS = 2  # scipy.fft threads
RESPONSE_POINTS = 64  # frequencies at which path responses are factorised
LN10_20 = np.log(10) / 20  # 10^(x / 20) = exp(x LN10_20): exp is the faster
FILTER_TAILS = 256  # samples a set's filter adds on each side of the call (an estimate)
#: microphones whose impulses are summed and transformed together by
#: :func:`_sets_by_fft` (one buffer reused from block to block).  The corridor's
#: moving render, CPU time, in-process alternation over 20 poses x 3, medians of
#: ratios to blocks of 5: in a process configured as the command line does
#: (:func:`acousim.process.configure`: freed memory kept) blocks of 3 1.07, 10 0.97,
#: 15 1.00, all 30 1.01; in one that is not (a script's), 15 1.12, 15 with
#: FFT_WORKERS threads 1.21, 3 1.10, 10 1.03, 30 1.08
MICS_PER_BLOCK = 5


def render(
    echoes: Echoes,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    emission_index: int = 0,
    interpolator: FractionalDelay = DEFAULT_INTERPOLATOR,
    taps: int = DEFAULT_TAPS,
    response: PathResponse | None = None,
) -> np.ndarray:
    """Microphone signals of `echoes`, shape (M, T), float64.

    `response` adds air absorption and emitter directivity per path (see
    :mod:`acousim.synth.response`); it needs a
    :data:`ShapedDelay` interpolator (sinc, lagrange or nearest).  The sinc,
    lagrange and nearest interpolators sum the echoes in time or by FFT, whichever
    is estimated cheaper (:func:`render_with` takes the choice).

    Echoes that start after the end of the window are expected to have been
    dropped by the caller (:func:`acousim.synth.signal_model.simulate`); those that start
    inside it and run past its end are truncated.
    """
    kernel = (interpolator, taps)
    return _render(echoes, waveform, sample_rate_hz, n_samples, emission_index, kernel, response)


def render_with(
    echoes: Echoes, capture, options, response: PathResponse | None = None
) -> np.ndarray:
    """:func:`render` of the :class:`~acousim.synth.options.Capture` `capture` (call,
    sample rate, samples) with the emission sample, fractional delays and render
    domain of the :class:`~acousim.synth.options.RenderOptions` `options`
    (``options.domain``, :data:`~acousim.core.rendering.RenderDomain`: 'frequency',
    impulses and FFTs; 'time', :mod:`acousim.synth.timedomain`; 'auto', the cheaper
    by estimate): microphone signals (M, T)."""
    return _render(
        echoes,
        capture.waveform,
        capture.sample_rate_hz,
        capture.n_samples,
        options.emission_index,
        (options.interpolator, options.taps),
        response,
        options.domain,
    )


def _render(
    echoes, waveform, fs, n_samples, emission_index, kernel, response, domain="auto"
) -> np.ndarray:
    """:func:`render`, the fractional delays' `kernel` (method, taps) and `domain`."""
    interpolator, taps = kernel
    shaped = response is not None and response.active
    check_interpolator(
        interpolator,
        SHAPED_INTERPOLATORS if shaped else INTERPOLATORS,
        need="a path response (absorption, directivity)" if shaped else "",
    )
    M = echoes.delay_s.shape[0]
    out = np.zeros((M, n_samples))
    if echoes.n_paths == 0:
        return out
    d = echoes.delay_s * fs + emission_index  # (M, N) in samples
    g = echoes.gain
    if interpolator == "exact":
        return _render_exact(d, g, waveform, fs, n_samples, out)
    if interpolator == "reference":
        return _render_reference(d, g, waveform, fs, n_samples)
    call, start = waveform.band_limited(fs)
    d = d + start  # sample i of `call` is at i + start
    if interpolator == "fft":
        return _render_fft(d, g, call, n_samples)
    # span of the output that echoes reach: only that part is computed
    lo, hi = _span(d, 0 if interpolator == "nearest" else taps, call.size, n_samples)
    if hi <= max(lo, 0):
        return out
    into = (out, lo)  # the span's sample i is the output's lo + i
    if shaped:
        return _shaped(echoes, d - lo, call, fs, hi - lo, (kernel, domain), response, into)
    return _unshaped(d - lo, g, call, hi - lo, kernel, domain, into)


def _placed(y: np.ndarray, into: tuple[np.ndarray, int]) -> np.ndarray:
    """The span's samples `y` (M, n_span) copied into the output `into` = (out (M,
    T), lo: the output sample of the span's first), those before sample 0 dropped:
    the output."""
    out, lo = into
    hi = lo + y.shape[1]
    out[:, max(lo, 0) : hi] = y[:, max(lo, 0) - lo :]
    return out


def _span(d: np.ndarray, half: int, call_size: int, n_samples: int) -> tuple[int, int]:
    """The output samples [lo, hi) that impulses at `d` (samples) of calls of
    `call_size` samples reach; it may start before sample 0: the band-limited call
    starts before its echo's delay, and the direct path arrives within a few samples."""
    lo = int(np.floor(d.min())) - half
    return lo, min(int(np.ceil(d.max())) + half + call_size + 1, n_samples)


def render_baseband(
    echoes: Echoes, capture, options, response: PathResponse, band_db: float
) -> np.ndarray:
    """:func:`render` with a path `response` at complex baseband
    (:mod:`acousim.synth.baseband`: the echoes' band, the bins within `band_db` of
    the strongest): microphone signals (M, T) of the
    :class:`~acousim.synth.options.Capture` `capture`, with the fractional delays
    and emission sample of the :class:`~acousim.synth.options.RenderOptions` `options`.
    Echoes few enough that their sum in time is estimated cheaper (``options.domain``
    'auto', or 'time') are summed in time at the sample rate, as :func:`render` sums
    them (a scene of few paths pays no transform)."""
    check_interpolator(options.interpolator, SHAPED_INTERPOLATORS, need="a path response")
    fs, n_samples = capture.sample_rate_hz, capture.n_samples
    out = np.zeros((echoes.delay_s.shape[0], n_samples))
    if echoes.n_paths == 0:
        return out
    call, start = capture.waveform.band_limited(fs)
    d = echoes.delay_s * fs + options.emission_index + start
    lo, hi = _span(d, options.taps, call.size, n_samples)
    if hi <= max(lo, 0):
        return out
    kernel = (options.interpolator, options.taps)
    n, grid, (g, U, V, band) = _factors(echoes, call, fs, hi - lo, options.taps, response)
    # few paths are summed in time at either rate (cheaper than any transform)
    call_span = call.size + 2 * FILTER_TAILS
    if _in_time(options.domain, g.shape, V.shape[1], kernel, call_span, n):
        return _shaped_in_time(d - lo, (g, U, V, band), grid, n, kernel, hi - lo, (out, lo))
    factors = (g, U, V, grid.W, band)
    return _shaped_baseband(echoes, d - lo, factors, n, kernel, hi - lo, band_db, (out, lo))


def _unshaped(d, g, call, n_span: int, kernel, domain: RenderDomain, into) -> np.ndarray:
    """The impulses at `d` (M, N; samples from the span's start) of gains `g` (M, N)
    convolved with `call` (L,), no path response: the span's samples (M, n_span),
    summed in time (:mod:`.timedomain`) or by FFT (:func:`_convolved`) as `domain`
    says, placed in the output `into` (:func:`_placed`; returned); `kernel`: the
    fractional delays' (method, taps)."""
    calls, lead = trimmed(call[None], 0)  # the call without its silent padding
    if not _in_time(domain, g.shape, 1, kernel, calls.shape[1], n_span + call.size):
        return _placed(_convolved(d, g, call, n_span, kernel), into)
    row = np.zeros(g.shape[1], np.intp)  # every path: the call
    taps = _taps(d, *kernel)
    return render_time(d, g, calls, lead=lead, kernel=taps, row=row, n_samples=n_span, into=into)


def _convolved(d: np.ndarray, g: np.ndarray, call: np.ndarray, n_span: int, kernel) -> np.ndarray:
    """The impulses at `d` (M, N; samples from the span's start) of gains `g` (M, N)
    convolved with `call` (L,): the span's samples (M, n_span).  The impulses are
    summed and stored, with their FFTs, in single precision, in buffers of the FFT's
    length (no copy), as :func:`_shaped_by_fft` does (float32 rounding: -135.2 dB
    relative to float64 sums and FFTs, the shoebox's first pose at 30 microphones;
    float64 FFTs cost twice as much); the transforms shared among
    :data:`FFT_WORKERS` threads.  `kernel`: the fractional delays' (method, taps)."""
    method, taps = kernel
    pad = taps + 1  # the layout of the impulses' buffers: span sample i at pad + i
    # no wrap-around into the span: the last tap (at most pad + n_span + pad) plus
    # the call's length stays within n
    n = sfft.next_fast_len(n_span + call.size + 2 * pad, real=True)
    h, pad = _impulses(d, g, n_span, (method, taps), n, np.float32)  # (1, M, n)
    spec = sfft.rfft(h[0], axis=-1, workers=FFT_WORKERS)
    spec *= sfft.rfft(call, n).astype(np.complex64)
    return sfft.irfft(spec, n, axis=-1, workers=FFT_WORKERS)[:, pad : pad + n_span]


def _render_reference(d, g, waveform: Waveform, fs: float, n_samples: int) -> np.ndarray:
    """The exact band-limited echoes (the ``reference`` interpolator): the analytic
    call at 64 times the sample rate, low-passed at 0.8 Nyquist and decimated."""
    U = 64
    fine = _render_exact(
        d * U, g, waveform, fs * U, n_samples * U, np.zeros((d.shape[0], n_samples * U))
    )
    spec = sfft.rfft(fine, axis=-1)
    spec[:, int(ANTI_ALIAS_CUTOFF * n_samples / 2) + 1 :] = 0.0
    return sfft.irfft(spec, n_samples * U, axis=-1)[:, ::U]


def _in_time(domain: str, shape, sets: int, kernel, call: int, n: int, mixed: int = 1) -> bool:
    """Whether to sum in time (:mod:`.timedomain`): `domain` says so, or it is 'auto'
    and the time domain is estimated cheaper for echoes of `shape` (M, N), `sets`
    gain sets, `kernel` (method, taps), a call of `call` samples and FFTs of `n`;
    `mixed`: each copy's call mixed from that many sets' calls (moving poses)."""
    if domain == "auto":
        taps = 0 if kernel[0] == "nearest" else kernel[1]
        M, N = shape
        return prefer_time(mics=M, paths=N, taps=taps, call=call, sets=sets, n_fft=n, mixed=mixed)
    return domain == "time"


def _factors(echoes, call, fs: float, n_span: int, taps: int, response):
    """The FFT length n of a span of `n_span` samples, the `call`'s spectrum W on it
    and :func:`response_factors`' (g, U, V, band) of `echoes`."""
    n = sfft.next_fast_len(n_span + call.size + 2 * taps + 258, real=True)
    grid = call_grid(call, fs, n)
    g, U, V, band, _ = response_factors(echoes, echoes.gain, grid.W, fs, n, response, grid)
    return n, grid, (g, U, V, band)


@dataclass(frozen=True, eq=False)
class CallGrid:
    """A call's spectrum on an n-point real FFT at fs and the frequencies the path
    responses are factorised over (:func:`response_factors`): W (F,) complex, F = n
    // 2 + 1; band (F,) bool, the bins where W is above 1e-6 of its peak; fb the
    band's frequencies (Hz); coarse (F',) the factorisation's grid over where W is
    within 60 dB of its peak (Hz); f_c the band's centre, weighted by |W|^2 (Hz).
    The arrays are read-only (shared by the renders of a call)."""

    W: np.ndarray
    band: np.ndarray
    fb: np.ndarray
    coarse: np.ndarray
    f_c: float
    #: the band's bins (F_band,) and W there
    bins: np.ndarray
    W_band: np.ndarray

    @classmethod
    def of(cls, W: np.ndarray, fs: float, n: int) -> CallGrid:
        """The grid of the spectrum `W` of an n-point real FFT at `fs` (Hz)."""
        freqs = np.arange(W.size) * fs / n
        band = np.abs(W) > 1e-6 * np.abs(W).max()
        fb = freqs[band]
        # the coarse grid covers where the call has its energy (within 60 dB of its
        # peak); beyond, the interpolation holds the end values
        main = freqs[np.abs(W) > 1e-3 * np.abs(W).max()]
        coarse = np.linspace(main[0], main[-1], min(RESPONSE_POINTS, main.size))
        f_c = np.average(freqs[band], weights=np.abs(W[band]) ** 2)
        return cls(W, band, fb, coarse, float(f_c), np.flatnonzero(band), W[band])


def call_grid(call: np.ndarray, fs: float, n: int) -> CallGrid:
    """The :class:`CallGrid` of `call` (L,) real, on an n-point real FFT at `fs`
    (Hz): computed once per call (by its bytes), rate and length, the last few kept
    (every pose of a scene renders the same call, mostly on the same FFT length)."""
    call = np.ascontiguousarray(call, np.float64)
    return _call_grid(call.tobytes(), float(fs), int(n))


@lru_cache(maxsize=8)
def _call_grid(call: bytes, fs: float, n: int) -> CallGrid:
    grid = CallGrid.of(sfft.rfft(np.frombuffer(call, np.float64), n), fs, n)
    for a in (grid.W, grid.band, grid.fb, grid.coarse, grid.bins, grid.W_band):
        a.flags.writeable = False
    return grid


def _shaped(echoes, d, call, fs, n_span, how, response, into):
    """The echoes at `d` (M, N; samples from the span's start) with their path
    `response`: the span's samples (M, n_span), summed by FFT
    (:func:`_shaped_by_fft`) or in time (:func:`_shaped_in_time`) as `domain` says,
    placed in the output `into` (:func:`_placed`; returned); `how`: (kernel, the
    fractional delays' (method, taps); domain, a :data:`RenderDomain`)."""
    kernel, domain = how
    n, grid, factors = _factors(echoes, call, fs, n_span, kernel[1], response)
    g, V = factors[0], factors[2]
    if _in_time(domain, g.shape, V.shape[1], kernel, call.size + 2 * FILTER_TAILS, n):
        return _shaped_in_time(d, factors, grid, n, kernel, n_span, into)
    return _shaped_by_fft(d, factors, grid.W, n, kernel, n_span, into)


def _shaped_in_time(d, factors, grid, n: int, kernel, n_span: int, into=None) -> np.ndarray:
    """:func:`_shaped_by_fft`'s sum in time (:mod:`.timedomain`): each set's filter
    applied to the call once, each path's response its sets' filtered calls (added
    into `into`, :func:`.timedomain.render_time`); `grid`: the call's
    :class:`CallGrid`."""
    g, U, V, band = factors
    spec = np.zeros((V.shape[1], grid.W.size), complex)
    filters = np.multiply(grid.W_band[None, :], U.T)  # (Q, F_band): W U over the band
    for q in range(spec.shape[0]):
        spec[q, grid.bins] = filters[q]
    calls, lead = filtered_calls(spec, n)
    paths = V @ calls  # (N, L): each path's response, its sets' filtered calls
    taps = _taps(d, *kernel)
    return render_time(d, g, paths, lead=lead, kernel=taps, n_samples=n_span, into=into)


def _shaped_by_fft(d, factors, W, n: int, kernel, n_span: int, into) -> np.ndarray:
    """Impulses times separable path responses, summed in the frequency domain:
    `factors` (g, U, V, band) of :func:`response_factors`, W the call's spectrum
    on an n-point real FFT; the span's samples (n_span of them) placed in the output
    `into` (:func:`_placed`; returned).

    The direct path (order 0, tens of dB above every echo) is factorised apart from
    the echoes, so that its level does not set the accuracy of theirs.  The impulses
    and their FFTs are single precision (faster; BENCHMARKS.md): the error against
    exact per-path filtering stays that of the factorisation, float32 rounding is far
    below it (tests/acousim/synth/test_synth.py pins it under -75 dB; -81.4 dB there).  The order
    of the float32 sums is part of the output's bytes: summing the Q spectra in a
    loop instead of einsum, and absorption as exp instead of a power, moved the
    corridor's samples by -138 dB (relative RMS), the same seed giving the same bytes
    before and after.
    """
    g, U, V, band = factors
    b0, b1 = np.flatnonzero(band)[[0, -1]] + [0, 1]
    filt = np.zeros((V.shape[1], b1 - b0), np.complex64)  # (sets, bins), contiguous
    filt[:, band[b0:b1]] = (W[band, None] * U).T
    out, lo = into
    into = (out[:, : lo + n_span], lo)
    _sets_by_fft(d, (g, V), filt, (b0, b1, n), kernel, True, into)
    return out


def _sets_by_fft(d, gains, filt, fft, kernel, single: bool, into) -> np.ndarray:
    """Sets of impulses at `d` (M, N; samples from the span's start), their FFTs,
    the sum of their products with the sets' filters, back: the span written into
    `into` = (out (M, lo + n_span), lo: the output sample of the span's first; those
    before sample 0 dropped), out returned.  `gains`: (G (M, N, R), None) the sets'
    gains, or (g (M, N), V (N, R)) their factors (:func:`_impulses`); `filt` (R, b1
    - b0) the sets' filters over the bins b0 .. b1 of `fft` = (b0, b1, n), an n-point
    real FFT (zero elsewhere); `kernel`: the fractional delays' (method, taps);
    `single`: impulses and spectra in float32.

    Blocks of :data:`MICS_PER_BLOCK` microphones (the rows are independent: the same
    bits), each block's impulses written into one buffer (every element: no
    clearing) and its sum of products into one spectrum (zero outside the band),
    both reused, so their memory is touched once per render, not once per block;
    the transforms in this thread (a simulator renders while it prepares the next
    pose; :data:`FFT_WORKERS` threads measured 1.05x the CPU time at blocks of 5,
    corridor, in-process alternation)."""
    (b0, b1, n), (G, V), (method, taps) = fft, gains, kernel
    out, lo = into
    M, n_span = d.shape[0], out.shape[1] - lo
    dtype, cdtype = (np.float32, np.complex64) if single else (np.float64, complex)
    size = min(MICS_PER_BLOCK, M)
    buffer = np.empty((filt.shape[0], size, n), dtype)
    spec = np.zeros((size, n // 2 + 1), cdtype)
    term = np.empty((size, b1 - b0), cdtype)
    for m0 in range(0, M, size):
        mics = slice(m0, min(m0 + size, M))
        c = mics.stop - m0
        h, pad = _impulses(
            d[mics], G[mics], n_span, (method, taps), n, dtype, V, buffer if c == size else None
        )
        spectra = sfft.rfft(h, axis=-1, workers=1)  # (sets, mics, F)
        _summed_products(spectra, filt, b0, spec[:c], term[:c])
        y = sfft.irfft(spec[:c], n, axis=-1, workers=1)[:, pad : pad + n_span]
        _placed(y, (out[mics], lo))
    return out


def _summed_products(spectra, filt, b0: int, out, term) -> None:
    """``out[c, b0 + i] = sum_q spectra[q, c, b0 + i] filt[q, i]`` (the bins of
    `filt` (R, F) from b0; out's others untouched): compiled
    (:mod:`._spectra_kernel`), or in numpy with `term` (C, F) a buffer."""
    kernel = optional_kernel("acousim.synth._spectra_kernel", "summed_products")
    if kernel is not None:
        kernel(spectra, filt, b0, out)
        return
    b1 = b0 + filt.shape[1]
    inband = out[:, b0:b1]
    np.multiply(spectra[0, :, b0:b1], filt[0], out=inband)
    for q in range(1, filt.shape[0]):
        inband += np.multiply(spectra[q, :, b0:b1], filt[q], out=term)


def _shaped_baseband(echoes, d, factors, n, kernel, n_span, floor_db, into) -> np.ndarray:
    """:func:`_shaped_by_fft` at complex baseband: of `factors`
    (:func:`response_factors`' g, U, V and the call's spectrum W over its band), the
    echoes' sets g V (M, N, Q) with the filters W U over their band
    (:func:`.baseband.spectra`), one inverse FFT per microphone, placed in the
    output `into` (:func:`_placed`; returned); the direct path's sets summed in time
    onto them (:mod:`.timedomain`, as :func:`_shaped_in_time`); `kernel`: the
    fractional delays' (method, taps)."""
    g, U, V, W, band = factors
    filters = np.zeros((V.shape[1], W.size), complex)
    filters[:, band] = (W[band, None] * U).T
    gains = g[:, :, None] * V[None]
    direct = echoes.order == 0
    energy, echo = baseband.set_energy(gains), baseband.echo_sets(gains, direct)
    if echo.any():
        pad = kernel[1] + 1  # the same layout as the impulses' buffers
        sets = np.flatnonzero(echo)
        spec = baseband.spectra(d + pad, gains, filters, sets, energy, floor_db, np.complex64, n)
        y = sfft.irfft(spec, n, axis=-1, workers=1, overwrite_x=True)
        _placed(y[:, pad : pad + n_span], into)
    if not echo.all():
        paths, own = np.flatnonzero(direct), np.flatnonzero(~echo)
        calls, lead = filtered_calls(filters[own], n)
        dp = d[:, paths]
        taps = _taps(dp, *kernel)
        mixed = V[paths][:, own] @ calls  # (N_d, L): each direct path's filtered call
        render_time(dp, g[:, paths], mixed, lead=lead, kernel=taps, n_samples=n_span, into=into)
    return into[0]


def response_factors(echoes, g: np.ndarray, W: np.ndarray, fs: float, n: int, response, grid=None):
    """The per-microphone absorption gain and the separable path-response terms.

    Returns ``(g (M, N), U (F_band, Q), V (N, Q), band (F,) bool, direct (Q,) bool)``:
    the path response over the call's band is ``U @ V.T``, factorised on a coarse grid
    (it is smooth in f) with each path weighted by its gain, so that the rank is set by
    the error of the rendered signal; the direct path (order 0) is factorised apart from
    the echoes (``direct`` marks its terms), so its level does not set their accuracy.
    `W` is the call's spectrum on an n-point real FFT at `fs`; `grid`: its
    :class:`CallGrid` if known (None: found here).
    """
    return _response_factors(echoes, g, W, fs, n, response, grid)[:5]


def _response_factors(echoes, g, W, fs: float, n: int, response, grid=None):
    """:func:`response_factors` and the terms on the coarse grid, Uc (F', Q): U is
    their linear interpolation onto the band's bins."""
    grid = CallGrid.of(W, fs, n) if grid is None else grid
    band, fb, coarse = grid.band, grid.fb, grid.coarse
    # the per-microphone part of the path length: a gain at the band's centre; H (F',
    # N) factorised on a coarse grid over the band (H is smooth in f), U
    # interpolated; each path weighted by its RMS gain, so the rank is set by the
    # error of the rendered signal and thousands of weak scatterers do not inflate
    # it; the columns of each group side by side
    alpha = response.alpha_db_per_m(grid.f_c)
    length, g, weight = _mic_gains(g, echoes.path_length_m, -alpha * LN10_20)
    groups, order = _groups(echoes.order)
    angles, interactions, weight_h = echoes.angles(), echoes.interactions, weight
    if order is not None:  # the direct path not first: the groups side by side
        length, angles, weight_h = length[order], angles[order], weight[order]
        interactions = None if interactions is None else interactions[order]
    H = response.weighted_matrix(coarse, length, angles, interactions, weight_h)
    Vs, Us = [], []
    start = 0
    for group in groups:
        count = int(group.sum()) if isinstance(group, np.ndarray) else group.stop - group.start
        Uc, Vw = factorise(H[:, start : start + count])
        start += count
        V = np.zeros((echoes.n_paths, Vw.shape[1]))
        V[group] = Vw / weight[group, None]
        Vs.append(V)
        Us.append(Uc)
    V, Uc = np.concatenate(Vs, axis=1), np.concatenate(Us, axis=1)
    U = np.stack([np.interp(fb, coarse, Uc[:, q]) for q in range(V.shape[1])], axis=1)
    direct = np.concatenate(
        [np.full(u.shape[1], i == 0 and (echoes.order == 0).any()) for i, u in enumerate(Us)]
    )
    return g, U, V, band, direct, Uc


def _groups(order: np.ndarray) -> tuple[list, np.ndarray | None]:
    """The paths' groups by their `order` (N,): the direct path (order 0), the
    echoes; those that have paths, and the order (N,) that puts them side by side
    (None: they are already, the direct paths first; the groups then slices)."""
    direct = order == 0
    k = int(np.count_nonzero(direct))
    if not direct[:k].all():
        groups = [grp for grp in (direct, ~direct) if grp.any()]
        return groups, np.concatenate([np.flatnonzero(grp) for grp in groups])
    return [grp for grp in (slice(0, k), slice(k, order.size)) if grp.stop > grp.start], None


def _mic_gains(g: np.ndarray, length_m: np.ndarray, c: float):
    """The paths' mean lengths over the microphones (N,), the gains `g` (M, N) times
    ``exp(c (length_m - mean))`` (M, N; C order: the paths of a microphone side by
    side) and the paths' RMS gains plus 1e-300 (N,): compiled
    (:mod:`._response_kernel`) or in numpy."""
    kernel = optional_kernel("acousim.synth._response_kernel", "mic_gains")
    if kernel is None:
        length = length_m.mean(axis=0)
        out = np.multiply(g, np.exp(c * (length_m - length[None, :])), out=np.empty(np.shape(g)))
        return length, out, np.sqrt(np.mean(out**2, axis=0)) + 1e-300
    M, N = np.shape(g)
    out, length, weight = np.empty((M, N)), np.empty(N), np.empty(N)
    L = np.ascontiguousarray(length_m, float)
    kernel(np.ascontiguousarray(g, float), L, float(c), out, length, weight)
    return length, out, weight


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

    Looking up the nearest fraction costs less than evaluating sinc and Bessel
    functions per echo; it moves an echo by at most 1/8192 sample (a phase error of
    1.5e-4 rad at 0.19 fs, -76 dB).
    """
    return _kernel(np.linspace(0.0, 1.0, TABLE_PHASES + 1), method, taps)[1]


@lru_cache(maxsize=8)
def _table(method: str, taps: int, dtype: np.dtype) -> np.ndarray:
    """The weights' table of :func:`_taps` in `dtype` (read-only)."""
    table = np.ones((1, 1)) if method == "nearest" else _kernel_table(method, taps)
    table = table.astype(dtype)
    table.flags.writeable = False
    return table


def _taps(d: np.ndarray, method: str, taps: int):
    """The fractional delays `d` (M, N; samples) as tabulated taps:
    ``(n0 (M, N), phase (M, N) intp, table (P, K), offsets (K,))``: impulse (m, n)
    puts ``table[phase[m, n], j]`` at sample ``n0[m, n] + offsets[j]`` (for
    ``nearest``, one tap at the rounded delay; else the nearest of TABLE_PHASES
    tabulated fractions, :func:`_kernel_table`)."""
    if method == "nearest":
        return np.rint(d), np.zeros(d.shape, np.intp), np.ones((1, 1)), np.zeros(1, np.int64)
    n0 = np.floor(d)
    phase = np.rint((d - n0) * TABLE_PHASES).astype(np.intp)
    return n0, phase, _kernel_table(method, taps), np.arange(-taps + 1, taps + 1)


def _impulses(
    d: np.ndarray,
    g: np.ndarray,
    n_span: int,
    kernel: tuple[str, int],
    width: int | None = None,
    dtype: type = np.float64,
    V: np.ndarray | None = None,
    out: np.ndarray | None = None,
):
    """Sum of interpolated impulses (`kernel`: the fractional delays' method, taps);
    d in samples from the span start.

    `g` is (M, N), or (M, N, Q) for Q sets of gains sharing the same delays, or
    (M, N) with `V` (N, Q): the sets ``g[m, n] * V[n, q]`` (not formed in memory
    when compiled): the kernel weights are looked up once and applied to every set.
    The sums run in a compiled loop (:mod:`._impulse_kernel`, numba) or, without
    numba, as sparse products; both give the same bits.  Without `width`: returns
    (M, n_span) or (Q, M, n_span).  With `width` (a buffer length, for an FFT):
    returns ``(h, pad)`` with h of shape (Q, M, width) and span sample i at buffer
    index ``pad + i``.  Taps beyond the span's margin of `taps` samples are dropped.
    `dtype` is the output's and the sums' (float32: the precision the impulses are
    stored and transformed in; -140 dB relative to summing in float64 and rounding,
    the corridor's 30 microphones, below the rounding of the float32 FFTs that
    follow; 1.7x faster: no float64 accumulator to clear and copy).  `out` (Q, M,
    width) of `dtype`, C-contiguous: a buffer the sums are written into (every element: it
    need not be zero; a buffer reused for several blocks of microphones touches its
    memory once), returned as h.
    """
    (M, N), (method, taps), many = d.shape, kernel, g.ndim == 3
    pad = taps + 1
    buf = n_span + 2 * pad if width is None else width
    if buf < n_span + 2 * pad:
        raise ValueError(f"buffer width {buf} shorter than the span {n_span} and its margins")
    compiled = _compiled()
    if compiled is not None:
        start, phase = compiled.placed(d, TABLE_PHASES, taps, n_span, method == "nearest")
    else:
        start, phase = _placed_taps(d, method, taps, n_span)
    table = _table(method, taps, np.dtype(dtype))
    if compiled is not None:
        if V is not None:  # g (M, N) times V (N, Q), formed in the kernel
            scale, gains = g, np.broadcast_to(V[None], (M, *V.shape))
        else:
            scale, gains = np.broadcast_to(1.0, (M, N)), g if many else g[..., None]
        h = np.empty((gains.shape[2], M, buf), dtype) if out is None else out
        compiled.accumulate(start, phase, scale, gains, table, h)
    else:
        G = g[:, :, None] * V[None] if V is not None else g if many else g[..., None]
        start = start + (np.arange(M) * buf)[:, None]
        h = _impulses_sparse(start, phase, G, table, M * buf, dtype).reshape(-1, M, buf)
        if out is not None:
            out[...] = h
            h = out
    many = many or V is not None
    if width is not None:
        return h, pad
    h = h[:, :, pad : pad + n_span]
    return h if many else h[0]


def _placed_taps(d: np.ndarray, method: str, taps: int, n_span: int):
    """Each impulse's first tap in its microphone's buffer of ``_impulses``
    (M, N) int64 and its row of the weights' table (M, N) intp, for impulses at `d`
    (M, N; samples from the span's start): :func:`._impulse_kernel.placed` in numpy."""
    n0, phase, _, _ = _taps(d, method, taps)
    pad = taps + 1
    if method == "nearest":
        return np.clip(n0.astype(np.int64), -pad, n_span + pad - 1) + pad, phase
    return np.clip(n0.astype(np.int64), -1, n_span) + pad + 1 - taps, phase


def _impulses_sparse(start, phase, G, table, rows_out, dtype) -> np.ndarray:
    """The sums of :func:`._impulse_kernel.accumulate` as one sparse product per set
    of gains, each into its own contiguous row (2.7x faster than one product for all
    sets followed by a transpose, corridor, Q = 5), in `dtype` (`table`'s): (Q,
    rows_out); `start` indexes the flattened (M * buffer) rows."""
    M, N, Q = G.shape
    k = table.shape[1]
    rows = (start[..., None] + np.arange(k)).ravel()
    weights = table[phase].ravel()
    S = sp.csc_matrix((weights, rows, np.arange(0, M * N * k + 1, k)), shape=(rows_out, M * N))
    Gt = np.ascontiguousarray(G.reshape(M * N, Q).T, dtype)
    h = np.empty((Q, rows_out), dtype)
    for q, gains in enumerate(Gt):
        h[q] = S @ gains
    return h


def _compiled():
    """The compiled impulse kernels (:mod:`._impulse_kernel`), or None when numba is
    not installed."""
    return optional_kernel("acousim.synth._impulse_kernel")
