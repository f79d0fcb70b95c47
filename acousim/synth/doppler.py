"""Rendering echoes in motion: the call time-scaled by each path's Doppler factor.

The kinematics stage (:mod:`acousim.kinematics`) gives, per path and microphone, the
reception time of the start of the call and its Doppler factor (the time compression
``d tau / d t``); this module renders them.

``render_doppler`` (fast)
    Per path and microphone the emission time is taken linear in the reception
    time, ``tau = a (t - t0)`` (a from the exact solution at the first and last
    sample of the call, t0 shifted by the mean of the parabolic deviation measured at
    the middle sample; the deviation left is what this method neglects), so the
    echo is the call time-scaled by ``a``: ``w(a s)`` is again a sweep of the same
    kind (frequencies times a, duration over a), band-limited as the static
    renderer's call.  The templates are scaled about the middle of the call (the
    pivot p = T/2): ``w(p + a (s - p))``, the echo placed at ``t0 + p / a - p``
    (half the phase excursion over the Doppler factors of scaling about the start:
    fewer nodes and sets).  The scale factors of all paths lie in a small interval
    (widened to multiples of NODE_QUANTUM, so that a drive reuses its templates);
    the call is tabulated at K Chebyshev nodes of it and its interpolant in the
    factor written as a Chebyshev series: every path gets ``T_k(s)`` of its own
    factor (s mapped onto [-1, 1]; a three-term recurrence), the templates their
    Chebyshev coefficients; K chosen so the interpolation error stays below
    ``DOPPLER_TOLERANCE`` (K = 1 when all factors are equal, 6 for the corridor
    drive at 1 m/s).  With the Q separable terms of the path responses
    (absorption, directivity: :mod:`acousim.synth.response`) that makes K Q sets of
    gains, each with its filter; their sum is compressed to the few sets it needs
    (a real SVD from Gram matrices, per group: direct path, echoes, to
    ``COMPRESS_TOLERANCE``; 30 -> 6 on the corridor) and rendered as the static
    renderer does: fractional-delay impulses per set, FFT, products with the
    filters, summed.

The exact per-sample reference is
:func:`acousim.kinematics.reference.render_doppler_reference`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import fft as sfft

from acousim.core.echoes import Echoes
from processing import Waveform
from processing.waveforms import ANTI_ALIAS_CUTOFF

from .compress import compress
from .render import (
    DEFAULT_TAPS,
    FFT_WORKERS,
    FractionalDelay,
    _impulses,
    check_interpolator,
    response_factors,
)
from .response import PathResponse

__all__ = [
    "doppler_nodes",
    "DopplerPlan",
    "plan_doppler",
    "render_planned",
    "render_doppler",
    "scaled_call",
    "DOPPLER_TOLERANCE",
    "COMPRESS_TOLERANCE",
]

#: relative error of interpolating the time-scaled call between Doppler nodes (a
#: bound at the call's top frequency: the renderer's error stays far below it)
DOPPLER_TOLERANCE = 1e-3
#: Doppler ranges are widened to multiples of this, so consecutive poses of a drive
#: share their nodes and templates
NODE_QUANTUM = 2e-3
#: the gain sets are compressed to this relative amplitude of what is left out
#: (-63 dB): the renderer's error against the exact reference stays below -65 dB at
#: 2 m/s and 180 deg/s (BENCHMARKS.md, motion: its time against error, 3e-4 -> -71 dB
#: with 8 sets instead of 6 on the corridor)
COMPRESS_TOLERANCE = 7e-4
#: microphones rendered together: the corridor's 30 in two blocks renders in 0.95 of
#: the time of one block (paired runs; its buffers are smaller), in 1.01 with three
#: blocks and 1.08 with six (more, smaller FFT calls)
MICS_PER_BLOCK = 15


def scaled_call(waveform: Waveform, rate: float) -> Waveform:
    """The call time-scaled: ``w(rate t)``, a sweep of the same kind with its
    frequencies times `rate` and its duration over `rate` (exact for the linear and
    the hyperbolic sweep, and for the taper)."""
    return Waveform(
        waveform.kind,
        waveform.f_start_hz * rate,
        waveform.f_end_hz * rate,
        waveform.duration_s / rate,
        waveform.taper,
        waveform.amplitude,
    )


@lru_cache(maxsize=1024)
def _node_count(x: float, tolerance: float) -> int:
    """The fewest Chebyshev nodes that interpolate exp(i x s) on [-1, 1] to
    `tolerance`."""
    k = 1
    while k < 64 and _chebyshev_error(k, x) > tolerance:
        k += 1
    return k


def _chebyshev_error(k: int, x: float) -> float:
    """Largest error of interpolating exp(i x s), s in [-1, 1], at k Chebyshev nodes."""
    nodes = np.cos((2 * np.arange(k) + 1) * np.pi / (2 * k))
    s = np.linspace(-1, 1, 801)
    return float(np.max(np.abs(_lagrange(nodes, s) @ np.exp(1j * x * nodes) - np.exp(1j * x * s))))


def _lagrange(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Lagrange basis of `nodes` (K,) at `x` (...): weights (..., K) (barycentric)."""
    x = np.asarray(x, float)
    K = nodes.size
    if K == 1:
        return np.ones((*x.shape, 1))
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    bw = 1.0 / np.prod(diff, axis=1)
    w = x[..., None] - nodes  # in place from here: (..., K) is the large array
    hit = w == 0
    if hit.any():
        w[hit] = 1.0
    np.divide(bw, w, out=w)
    w /= (w @ np.ones(K))[..., None]  # a product: faster than a sum along a short axis
    if hit.any():
        on = hit.any(axis=-1)
        w[on] = hit[on]
    return w


def doppler_nodes(
    rate_min: float,
    rate_max: float,
    waveform: Waveform,
    sample_rate_hz: float,
    tolerance: float = DOPPLER_TOLERANCE,
) -> np.ndarray:
    """Chebyshev nodes (K,) covering [rate_min, rate_max] (widened to multiples of
    :data:`NODE_QUANTUM`): K is the fewest that interpolate ``w(p + a (s - p))``
    in a to `tolerance` (p = T / 2, the pivot of :func:`render_doppler`: the phase
    ``2 pi f (s - p) a`` spans ``x = 2 pi f_top (T / 2 + ringing) h``, h the half
    width; f_top the call's top frequency, the band limit for an untapered call,
    whose band-limit ringing of 256 samples counts too)."""
    if rate_max - rate_min < 1e-12:
        return np.array([rate_min])
    lo = np.floor(rate_min / NODE_QUANTUM) * NODE_QUANTUM
    hi = np.ceil(rate_max / NODE_QUANTUM) * NODE_QUANTUM
    f_top = max(waveform.band_hz) if waveform.taper > 0 else ANTI_ALIAS_CUTOFF * sample_rate_hz / 2
    # the templates are scaled about the call's middle (:func:`render_doppler`): the
    # time from the pivot reaches half the scaled call, and for an untapered call the
    # ringing of its band limit (a tapered call has no energy there)
    ringing = 0 if waveform.taper > 0 else 256 / sample_rate_hz
    reach = waveform.duration_s / (2 * lo) + ringing
    x = 2 * np.pi * f_top * reach * (hi - lo) / 2
    k = _node_count(float(np.ceil(x * 100) / 100), float(tolerance))
    centre, half = (hi + lo) / 2, (hi - lo) / 2
    return centre + half * np.cos((2 * np.arange(k) + 1) * np.pi / (2 * k))


_TEMPLATES: dict = {}


def _templates(waveform: Waveform, fs: float, nodes: np.ndarray) -> tuple[np.ndarray, int]:
    """Band-limited time-scaled calls (K, L), sample i at time (i + start) / fs."""
    calls = []
    start = 0
    for a in nodes:
        key = (waveform, fs, float(a))
        found = _TEMPLATES.get(key)  # one look-up: threads share the cache
        if found is None:
            if len(_TEMPLATES) > 256:
                _TEMPLATES.clear()
            # a tapered call has no energy where 8x oversampling would alias it
            over = 8 if waveform.taper > 0 else 64
            found = scaled_call(waveform, float(a)).band_limited(fs, oversample=over)
            _TEMPLATES[key] = found
        y, start = found
        calls.append(y)
    L = max(y.size for y in calls)
    out = np.zeros((len(calls), L))
    for j, y in enumerate(calls):
        out[j, : y.size] = y
    return out, start


@dataclass(frozen=True, eq=False, kw_only=True)
class DopplerPlan:
    """What :func:`render_doppler` computes from the echoes before the samples
    (:func:`plan_doppler`, steps 1-3): where the impulses go, the path gains times
    the Doppler terms and the path responses' separable terms.
    :func:`render_planned` compresses them into gain sets and makes the samples
    (steps 4-5).  A simulator plans the next measurement while the current one
    renders.

    positions (M, N): impulse positions, samples from the span's start (the span is
    output samples ``lo .. hi``); terms (K, N, M): path gains times the Chebyshev
    terms of their Doppler factors; responses (N, Q) and response_spectra (B, Q):
    the path responses' separable terms; templates (K, B): the Chebyshev
    coefficients of the time-scaled calls' spectra and products their products
    (:func:`_products`), over the ``band`` (F,) bins of an ``n_fft``-point real FFT;
    direct_paths (N,) and direct_terms (Q,): the direct path's group; single: the
    impulses and their spectra in single precision (with a path response).
    """

    positions: np.ndarray
    terms: np.ndarray
    responses: np.ndarray
    response_spectra: np.ndarray
    templates: np.ndarray
    products: np.ndarray
    direct_paths: np.ndarray
    direct_terms: np.ndarray
    band: np.ndarray
    lo: int
    hi: int
    n_fft: int
    n_mics: int
    n_samples: int
    interpolator: FractionalDelay
    taps: int
    compress_tolerance: float
    single: bool

    @property
    def empty(self) -> bool:
        return self.terms.shape[1] == 0


def render_doppler(
    echoes: Echoes,
    rate: np.ndarray,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    emission_index: int = 0,
    interpolator: FractionalDelay = "sinc",
    taps: int = DEFAULT_TAPS,
    response: PathResponse | None = None,
    tolerance: float = DOPPLER_TOLERANCE,
    compress_tolerance: float = COMPRESS_TOLERANCE,
) -> np.ndarray:
    """Microphone signals (M, T) of echoes time-scaled by `rate` (M, N): echo n at
    microphone m is ``g w_bl(rate (t - delay))`` (see the module docstring).

    `interpolator`: 'sinc' or 'lagrange' fractional delays, as the static renderer.
    `response`: air absorption and emitter directivity, factorised as the static
    renderer does (:mod:`acousim.synth.response`).  `tolerance`: of the Doppler
    nodes' interpolation; `compress_tolerance`: of the gain sets' compression.
    The same as :func:`render_planned` of :func:`plan_doppler`.
    """
    plan = plan_doppler(
        echoes,
        rate,
        waveform,
        sample_rate_hz,
        n_samples,
        emission_index=emission_index,
        interpolator=interpolator,
        taps=taps,
        response=response,
        tolerance=tolerance,
        compress_tolerance=compress_tolerance,
    )
    return render_planned(plan)


def plan_doppler(
    echoes: Echoes,
    rate: np.ndarray,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    emission_index: int = 0,
    interpolator: FractionalDelay = "sinc",
    taps: int = DEFAULT_TAPS,
    response: PathResponse | None = None,
    tolerance: float = DOPPLER_TOLERANCE,
    compress_tolerance: float = COMPRESS_TOLERANCE,
) -> DopplerPlan:
    """Steps 1-3 of :func:`render_doppler` (same arguments): the
    :class:`DopplerPlan` that :func:`render_planned` turns into samples."""
    check_interpolator(
        interpolator,
        ("sinc", "lagrange"),
        need="a moving scene",
        key="simulation.fractional_delay",
    )
    M = echoes.delay_s.shape[0]

    def nothing() -> DopplerPlan:
        none, no = np.zeros((0, 0)), np.zeros(0, bool)
        return DopplerPlan(
            positions=np.zeros((M, 0)),
            terms=np.zeros((1, 0, M)),
            responses=none,
            response_spectra=none,
            templates=none,
            products=none,
            direct_paths=no,
            direct_terms=no,
            band=no,
            lo=0,
            hi=0,
            n_fft=0,
            n_mics=M,
            n_samples=n_samples,
            interpolator=interpolator,
            taps=taps,
            compress_tolerance=compress_tolerance,
            single=False,
        )

    if echoes.n_paths == 0:
        return nothing()
    fs = sample_rate_hz
    # 1. Doppler nodes and the time-scaled calls there
    nodes = doppler_nodes(float(rate.min()), float(rate.max()), waveform, fs, tolerance)
    calls, start = _templates(waveform, fs, nodes)
    K, L = calls.shape
    # 2. the span of the output the echoes reach; each echo placed where its call's
    # middle (the pivot p) arrives less p: ``t0 + p / a - p``, and template j
    # advanced by p (1 / a_j - 1), so that every template is scaled about the pivot
    # (half the phase excursion over the Doppler factors of scaling about the start:
    # fewer nodes and sets)
    pivot = waveform.duration_s / 2
    advance = pivot * (1 / nodes - 1)  # (K,) s
    margin = int(np.ceil(np.abs(advance).max() * fs)) + 1
    d = (echoes.delay_s + pivot * (1 / rate - 1)) * fs + emission_index + start
    lo = int(np.floor(d.min())) - taps - margin
    hi = min(int(np.ceil(d.max())) + taps + L + 1 + margin, n_samples)
    if hi <= max(lo, 0):
        return nothing()
    n_span = hi - lo
    n = sfft.next_fast_len(n_span + L + 2 * taps + 258 + 2 * margin, real=True)
    key = (waveform, fs, tuple(nodes.tolist()), n)
    spectra = _cached(("spectra", *key), _template_spectra, calls, advance * fs, n)  # (K, F)
    g = echoes.gain
    N = echoes.n_paths
    # 3. path responses as separable terms u_q(f) v_q(n) (as the static renderer)
    shaped = response is not None and response.active
    if shaped:
        g, U, V, band, direct = response_factors(echoes, g, spectra[K // 2], fs, n, response)
    else:
        band = np.ones(spectra.shape[1], bool)
        U = np.ones((band.size, 1))
        V = np.ones((echoes.n_paths, 1))
        direct = np.zeros(1, bool)
    # the direct path is a group of its own only where it has its own response terms
    path_direct = echoes.order == 0 if direct.any() else np.zeros(N, bool)
    # the interpolant in the Doppler factor as a Chebyshev series: path gains times
    # T_p(s) (s the factor mapped onto [-1, 1]), (K, N, M), and the
    # templates' Chebyshev coefficients (the same polynomial as the Lagrange form,
    # with a three-term recurrence in place of the barycentric weights)
    gl = _chebyshev_terms(nodes, rate.T, g.T)
    W = _cached(("coefficients", *key, band.sum()), _chebyshev_coefficients, spectra[:, band])
    WW = _cached(("products", *key, band.sum()), _products, W)
    return DopplerPlan(
        positions=d - lo,
        terms=gl,
        responses=V,
        response_spectra=U,
        templates=W,
        products=WW,
        direct_paths=path_direct,
        direct_terms=direct,
        band=band,
        lo=lo,
        hi=hi,
        n_fft=n,
        n_mics=M,
        n_samples=n_samples,
        interpolator=interpolator,
        taps=taps,
        compress_tolerance=compress_tolerance,
        single=shaped,
    )


def render_planned(plan: DopplerPlan) -> np.ndarray:
    """Steps 4-5 of :func:`render_doppler`: the microphone signals (M, T) of a
    :class:`DopplerPlan`."""
    out = np.zeros((plan.n_mics, plan.n_samples))
    if plan.empty:
        return out
    lo, hi, n = plan.lo, plan.hi, plan.n_fft
    n_span = hi - lo
    dtype = np.float32 if plan.single else np.float64
    # 4. gain sets (path, microphone) x filters (template j times response term q):
    # the K x Q products compressed per group (direct path, echoes) to the rank
    # their sum needs
    gains, filt_band = compress(
        plan.terms,
        plan.responses,
        plan.templates,
        plan.products,
        plan.response_spectra,
        plan.direct_paths,
        plan.direct_terms,
        plan.compress_tolerance,
    )
    # the filters over the bins from the band's first to its last (zero elsewhere)
    band = plan.band
    b0, b1 = np.flatnonzero(band)[[0, -1]] + [0, 1]
    cdtype = np.complex64 if plan.single else complex
    filt = np.zeros((filt_band.shape[1], b1 - b0), cdtype)  # (sets, bins), contiguous
    filt[:, band[b0:b1]] = filt_band.T
    # 5. impulses per set, FFT, sum of products over the band, back: blocks of
    # microphones (the rows are independent: the same bits)
    M = plan.n_mics
    for m0 in range(0, M, MICS_PER_BLOCK):
        mics = slice(m0, min(m0 + MICS_PER_BLOCK, M))
        # gains (M, N, R): the sets contiguous, as the impulse sums take them
        h, pad = _impulses(
            plan.positions[mics], gains[mics], n_span, plan.interpolator, plan.taps, n, dtype
        )
        spectra = sfft.rfft(h, axis=-1, workers=FFT_WORKERS)  # (sets, mics, F)
        spec = np.zeros(spectra.shape[1:], spectra.dtype)
        inband = spec[:, b0:b1]
        np.multiply(spectra[0, :, b0:b1], filt[0], out=inband)
        term = np.empty_like(inband)
        for q in range(1, spectra.shape[0]):
            inband += np.multiply(spectra[q, :, b0:b1], filt[q], out=term)
        y = sfft.irfft(spec, n, axis=-1, workers=FFT_WORKERS)[:, pad : pad + n_span]
        out[mics, max(lo, 0) : hi] = y[:, max(lo, 0) - lo :]
    return out


def _chebyshev_terms(nodes: np.ndarray, rate: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """``gain T_p(s)`` (K, ...) for p < K, s the Doppler factors `rate` (...) mapped
    from the interval of the Chebyshev `nodes` (K,) onto [-1, 1]."""
    K = nodes.size
    out = np.empty((K, *rate.shape))
    out[0] = gain
    if K > 1:
        x = np.cos((2 * np.arange(K) + 1) * np.pi / (2 * K))
        half = (nodes[0] - nodes[-1]) / (x[0] - x[-1])
        s = (rate - (nodes[0] - half * x[0])) / half
        np.multiply(gain, s, out=out[1])
        s *= 2
        for p in range(2, K):
            np.multiply(s, out[p - 1], out=out[p])
            out[p] -= out[p - 2]
    return out


def _chebyshev_coefficients(values: np.ndarray) -> np.ndarray:
    """Chebyshev coefficients (K, ...) of the interpolant through `values` (K, ...)
    at the K Chebyshev nodes of :func:`doppler_nodes` (first kind, in its order)."""
    K = values.shape[0]
    theta = (2 * np.arange(K) + 1) * np.pi / (2 * K)
    C = np.cos(np.outer(np.arange(K), theta)) * (2.0 / K)  # C[p, j] = 2 T_p(x_j) / K
    C[0] /= 2
    return np.tensordot(C, values, axes=1)


def _template_spectra(calls: np.ndarray, advance: np.ndarray, n: int) -> np.ndarray:
    """Spectra (K, n // 2 + 1) of the templates `calls` (K, L) advanced by `advance`
    (K,) samples: ``y_j(i + advance_j)``, band-limited, exact (a linear phase)."""
    spectra = sfft.rfft(calls, n, axis=-1)
    if np.any(advance):
        f = np.arange(spectra.shape[1]) / n  # cycles per sample
        spectra *= np.exp(2j * np.pi * advance[:, None] * f[None, :])
    return spectra


def _products(W: np.ndarray) -> np.ndarray:
    """Re(conj(W_j) W_k) of the template spectra W (K, F) for j <= k (symmetric):
    (K (K + 1) / 2, F), rows in the order of ``np.triu_indices(K)``."""
    j, k = np.triu_indices(W.shape[0])
    return np.ascontiguousarray((W.conj()[j] * W[k]).real)


_CACHE: dict = {}


def _cached(key, fn, *args):
    """``fn(*args)``, computed once per key (one look-up: threads share the cache)."""
    found = _CACHE.get(key)
    if found is None:
        if len(_CACHE) > 8:
            _CACHE.clear()
        found = _CACHE[key] = fn(*args)
    return found
