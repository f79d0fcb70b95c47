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

import dataclasses
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import fft as sfft

from acousim.core.cache import LruCache
from acousim.core.echoes import Echoes
from acousim.synth import baseband
from acousim.synth.compress import ChebyshevGains, coarse_products, compress
from acousim.synth.options import (
    COMPRESS_TOLERANCE,
    DEFAULT_OPTIONS,
    DOPPLER_TOLERANCE,
    RenderOptions,
)
from acousim.synth.render import (
    FILTER_TAILS,
    CallGrid,
    _in_time,
    _placed,
    _response_factors,
    _sets_by_fft,
    _taps,
    check_interpolator,
)
from acousim.synth.response import PathResponse
from acousim.synth.timedomain import filtered_calls, render_time
from processing import Waveform
from processing.base.kernels import optional_kernel
from processing.sensor.calls import ANTI_ALIAS_CUTOFF

__all__ = [
    "doppler_nodes",
    "DopplerPlan",
    "DopplerCache",
    "plan_doppler",
    "render_planned",
    "render_doppler",
    "scaled_call",
    "DOPPLER_TOLERANCE",
    "COMPRESS_TOLERANCE",
]

#: Doppler ranges are widened to multiples of this, so consecutive poses of a drive
#: share their nodes and templates
NODE_QUANTUM = 2e-3


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


class DopplerCache:
    """What the Doppler renderer reuses from one measurement to the next (the nodes
    of a drive's consecutive poses are shared: :data:`NODE_QUANTUM`): the band-limited
    time-scaled calls per node, and per set of nodes their spectra, Chebyshev
    coefficients and products.  Owned by its user (a :class:`acousim.Simulator`
    has one), bounded, safe across threads (:class:`acousim.core.cache.LruCache`)."""

    def __init__(self, templates: int = 256, spectra: int = 12) -> None:
        self.templates = LruCache(templates)
        self.spectra = LruCache(spectra)


def _scaled_template(waveform: Waveform, fs: float, a: float) -> tuple[np.ndarray, int]:
    # a tapered call has no energy where 8x oversampling would alias it
    over = 8 if waveform.taper > 0 else 64
    return scaled_call(waveform, a).band_limited(fs, oversample=over)


def _templates(
    waveform: Waveform, fs: float, nodes: np.ndarray, cache: DopplerCache
) -> tuple[np.ndarray, int]:
    """Band-limited time-scaled calls (K, L), sample i at time (i + start) / fs
    (read-only: kept in the `cache`, per set of nodes, as the calls are per node)."""
    key = ("stacked", waveform, fs, tuple(nodes.tolist()))
    return cache.templates.get(key, lambda: _stacked(waveform, fs, nodes, cache))


def _stacked(
    waveform: Waveform, fs: float, nodes: np.ndarray, cache: DopplerCache
) -> tuple[np.ndarray, int]:
    """:func:`_templates` computed: each node's call (from the `cache`) zero-padded
    to the longest."""
    calls = []
    start = 0
    for a in nodes:
        key = (waveform, fs, float(a))
        y, start = cache.templates.get(key, lambda a=a: _scaled_template(waveform, fs, float(a)))
        calls.append(y)
    L = max(y.size for y in calls)
    out = np.zeros((len(calls), L))
    for j, y in enumerate(calls):
        out[j, : y.size] = y
    out.flags.writeable = False
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
    output samples ``lo .. hi``); terms: path gains times the Chebyshev
    terms of their Doppler factors (K, N, M, held as their factors:
    :class:`~.compress.ChebyshevGains`); responses (N, Q) and response_spectra (B,
    Q): the path responses' separable terms; templates (K, B): the Chebyshev
    coefficients of the time-scaled calls' spectra and products their products
    (:func:`_products`), over the ``band`` (F,) bins of an ``n_fft``-point real FFT;
    direct_paths (N,) and direct_terms (Q,): the direct path's group; options: the
    fractional delays and the compression's tolerance; single: the impulses and
    their spectra in single precision (with a path response); coarse_spectra (F',
    Q): the response terms on the coarse grid U is interpolated from, and
    coarse_products (:func:`~.compress.coarse_products`): the template products
    folded onto it (None: without a path response); call: the templates' length
    (samples).
    """

    positions: np.ndarray
    terms: ChebyshevGains
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
    options: RenderOptions
    single: bool
    coarse_spectra: np.ndarray | None = None
    coarse_products: np.ndarray | None = None
    call: int = 0

    @property
    def empty(self) -> bool:
        return self.terms.n_paths == 0

    @property
    def folded_products(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(coarse_products, coarse_spectra): :func:`~.compress.compress`'s products
        folded onto the coarse grid (None without them)."""
        if self.coarse_spectra is None or self.coarse_products is None:
            return None
        return self.coarse_products, self.coarse_spectra


def render_doppler(*args, **kwargs) -> np.ndarray:
    """Microphone signals (M, T) of echoes time-scaled by `rate` (M, N): echo n at
    microphone m is ``g w_bl(rate (t - delay))`` (see the module docstring).  The
    arguments of :func:`plan_doppler` (echoes, rate, waveform, sample rate, samples;
    `options`: the fractional delays ('sinc' or 'lagrange', as the static renderer),
    the emission's sample and the tolerances; `response`: air absorption and emitter
    directivity, factorised as the static renderer does; `cache`: reused between
    calls): :func:`render_planned` of its plan."""
    return render_planned(plan_doppler(*args, **kwargs))


def _empty_plan(n_mics: int, n_samples: int, options: RenderOptions) -> DopplerPlan:
    """A plan of no echo: silence."""
    none = dict.fromkeys(("responses", "response_spectra", "templates", "products"))
    return DopplerPlan(
        positions=np.zeros((n_mics, 0)),
        terms=ChebyshevGains(np.zeros((n_mics, 0)), None, 1),
        **{k: np.zeros((0, 0)) for k in none},
        **{k: np.zeros(0, bool) for k in ("direct_paths", "direct_terms", "band")},
        **dict.fromkeys(("lo", "hi", "n_fft"), 0),
        n_mics=n_mics,
        n_samples=n_samples,
        options=options,
        single=False,
    )


def _response_terms(echoes: Echoes, grid: CallGrid, fs: float, n: int, response):
    """Step 3 of :func:`plan_doppler`: the path responses as separable terms u_q(f)
    v_q(n) (as the static renderer), over the :class:`~.render.CallGrid` of the
    middle template's spectrum: gains (M, N), U (F, Q), V (N, Q), the band (F,),
    which terms are the direct path's (Q,) and U on the grid's coarse frequencies
    (F', Q; None without a response): whether a response shapes them."""
    if response is not None and response.active:
        return (*_response_factors(echoes, echoes.gain, grid.W, fs, n, response, grid), True)
    band = np.ones(grid.W.size, bool)
    U = np.ones((band.size, 1))
    V = np.ones((echoes.n_paths, 1))
    return echoes.gain, U, V, band, np.zeros(1, bool), None, False


def plan_doppler(
    echoes: Echoes,
    rate: np.ndarray,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    options: RenderOptions = DEFAULT_OPTIONS,
    response: PathResponse | None = None,
    cache: DopplerCache | None = None,
) -> DopplerPlan:
    """Steps 1-3 of :func:`render_doppler`: its :class:`DopplerPlan`."""
    check_interpolator(options.interpolator, ("sinc", "lagrange"), need=_NEED, key=_KEY)
    M = echoes.delay_s.shape[0]
    if echoes.n_paths == 0:
        return _empty_plan(M, n_samples, options)
    cache = DopplerCache() if cache is None else cache
    fs, taps = sample_rate_hz, options.taps
    # 1. Doppler nodes and the time-scaled calls there
    nodes = doppler_nodes(rate.min(), rate.max(), waveform, fs, options.doppler_tolerance)
    calls, start = _templates(waveform, fs, nodes, cache)
    L = calls.shape[1]
    # 2. the span of the output the echoes reach
    d, s, span, advance, margin = _placement(
        echoes.delay_s, rate, nodes, waveform.duration_s, fs, (options.emission_index, start)
    )
    lo, hi, n, n_grid = _span_lengths(span, L, taps, margin, n_samples)
    if hi <= max(lo, 0):
        return _empty_plan(M, n_samples, options)
    key = (waveform, fs, tuple(nodes.tolist()), n)
    spectra, grid = cache.spectra.get(
        ("spectra", *key, n_grid), lambda: _spectra_and_grid(calls, advance * fs, (n, n_grid), fs)
    )
    # 3. path responses (the direct path a group of its own if it has its own terms)
    g, U, V, band, direct, Uc, shaped = _response_terms(echoes, grid, fs, n, response)
    path_direct = echoes.order == 0 if direct.any() else np.zeros(echoes.n_paths, bool)
    W, products, folded = _template_tables(cache, key, spectra, grid, band, Uc is not None)
    d -= lo
    return DopplerPlan(
        positions=d,
        terms=ChebyshevGains(g, s, nodes.size),
        responses=V,
        response_spectra=U,
        templates=W,
        products=products,
        coarse_spectra=Uc,
        coarse_products=folded,
        direct_paths=path_direct,
        direct_terms=direct,
        band=band,
        lo=lo,
        hi=hi,
        n_fft=n,
        n_mics=M,
        n_samples=n_samples,
        options=options,
        single=shaped,
        call=L,
    )


_KEY, _NEED = "simulation.fractional_delay", "a moving scene"


def _span_lengths(span, L: int, taps: int, margin: int, n_samples: int):
    """The output samples [lo, hi) that impulses at `span` (least, greatest; samples)
    of templates of L samples reach, cut at the recording's `n_samples`; the FFT
    length n (:func:`_fft_length`) and n_grid, that of the spectrum the response
    grid is found on (:func:`_spectra_and_grid`)."""
    lo = int(np.floor(span[0])) - taps - margin
    reach = int(np.ceil(span[1])) + taps + L + 1 + margin  # the last echo's end
    hi = min(reach, n_samples)
    n_grid = sfft.next_fast_len(hi - lo + L + 2 * taps + 258 + 2 * margin, real=True)
    return lo, hi, _fft_length(lo, reach, taps, margin, L), n_grid


def _fft_length(lo: int, reach: int, taps: int, margin: int, call: int) -> int:
    """The FFT length of the span from output sample `lo` to `reach`, where the last
    echo ends (beyond the recording's end when it is cut there): the smallest fast
    length whose circular convolution wraps nothing into the output.  A set's filter
    is a template (the call and its band-limit ringing) advanced by at most `margin`
    samples and shaped by the path response, whose tails are taken as 258 samples
    (:data:`~.render.FILTER_TAILS` and two); the impulses' `taps` reach beyond their
    positions.  What spills past ``lo + n`` wraps onto the buffer's margin ahead of
    ``lo``, what precedes lo onto the samples after `reach`: neither is output.
    (The span to `reach` already holds the templates: the filters add only their
    tails, not the call's length again; echoes cut at the recording's end, -110 dB
    against FFTs four times as long: tests/acousim/synth/test_fft_route.py.)  And
    at least twice the templates' `call` samples and their tails, for the sum in
    time (:func:`~.timedomain.filtered_calls`: the filtered call in the first half
    of the inverse transform, what precedes it in the second): it binds only for
    short spans, of few echoes."""
    tails = 258 + margin
    return sfft.next_fast_len(max(reach - lo + taps + tails, 2 * (call + tails)), real=True)


def _template_tables(cache: DopplerCache, key: tuple, spectra, grid, band, coarse: bool):
    """The interpolant in the Doppler factor as a Chebyshev series
    (:func:`_chebyshev_argument`): the templates' coefficients W (K, F) over the `band`
    (F,) bins of their `spectra`, their products (:func:`_products`) and, for
    response terms interpolated from the `grid`'s coarse frequencies (`coarse`), the
    products folded onto those (:func:`~.compress.coarse_products`; None): per drive,
    in the `cache` under `key`."""
    W = cache.spectra.get(
        ("coefficients", *key, band.sum()), lambda: _chebyshev_coefficients(spectra[:, band])
    )
    WW = cache.spectra.get(("products", *key, band.sum()), lambda: _products(W))
    if not coarse:
        return W, WW, None
    fold = cache.spectra.get(
        ("coarse", *key, band.sum()), lambda: coarse_products(WW, grid.fb, grid.coarse)
    )
    return W, WW, fold


def _spectra_and_grid(calls: np.ndarray, shifts: np.ndarray, lengths: tuple[int, int], fs):
    """The templates' spectra (:func:`_template_spectra`) on n-point real FFTs and the
    middle one's :class:`~.render.CallGrid` (the path responses' frequencies), kept
    together; `lengths`: (n, n_grid), the coarse grid and the band's centre found on
    the middle template's spectrum of n_grid points (the span, a call and the
    filters' tails: the length the FFTs had before :func:`_fft_length`, so that the
    responses are factorised at the same frequencies: found at n instead, the grid
    moves by a fraction of a bin and the corridor's recordings by -92 dB re its
    echoes)."""
    n, n_grid = lengths
    spectra = _template_spectra(calls, shifts, n)
    grid = CallGrid.of(spectra[len(spectra) // 2], fs, n)
    if n_grid == n:
        return spectra, grid
    j = slice(len(calls) // 2, len(calls) // 2 + 1)
    middle = _template_spectra(calls[j], shifts[j], n_grid)
    found = CallGrid.of(middle[0], fs, n_grid)
    return spectra, dataclasses.replace(grid, coarse=found.coarse, f_c=found.f_c)


def _placement(delay_s, rate, nodes, duration_s: float, fs: float, shift=(0, 0)):
    """Where each echo's impulse goes (M, N), in samples from the emission (before
    the templates' start) plus the two `shift` (samples, added in turn): where its
    call's middle (the pivot p) arrives less p, ``t0 + p / a - p``; the Doppler
    factors mapped onto the Chebyshev interval of the nodes (M, N, C order;
    :func:`_chebyshev_argument`, None for one node); the positions' range (least,
    greatest); template j advanced by ``p (1 / a_j - 1)`` (K,) s, so that every
    template is scaled about the pivot (half the phase excursion over the Doppler
    factors of scaling about the start: fewer nodes and sets); and the margin
    (samples) the advances need.  One compiled pass (:mod:`._doppler_kernel`), or
    numpy without numba: the same operations, the same bits."""
    pivot = duration_s / 2
    advance = pivot * (1 / nodes - 1)  # (K,) s
    margin = int(np.ceil(np.abs(advance).max() * fs)) + 1
    kernel = optional_kernel("acousim.synth._doppler_kernel", "place")
    if kernel is None:
        d = (delay_s + pivot * (1 / rate - 1)) * fs
        d = d + shift[0] + shift[1]
        s = _chebyshev_argument(nodes, rate)
        return d, s, (d.min(), d.max()), advance, margin
    offset, half = _chebyshev_interval(nodes) if nodes.size > 1 else (0.0, 1.0)
    d = np.empty_like(delay_s, float)  # the layout of the delays
    s = np.empty(np.shape(rate) if nodes.size > 1 else (0, 0))
    arrays = (delay_s, rate, d, s)
    if not d.flags.c_contiguous:  # the kernel runs along rows: (N, M) views of F order
        arrays = tuple(a.T for a in arrays)
    t, a, dd, ss = arrays
    span = kernel(t, a, pivot, fs, float(shift[0]), float(shift[1]), offset, half, dd, ss)
    return d, (s if nodes.size > 1 else None), span, advance, margin


def render_planned(plan: DopplerPlan) -> np.ndarray:
    """Steps 4-5 of :func:`render_doppler`: the microphone signals (M, T) of a
    :class:`DopplerPlan`."""
    out = np.zeros((plan.n_mics, plan.n_samples))
    if plan.empty:
        return out
    lo, n = plan.lo, plan.n_fft
    # 4. gain sets (path, microphone) x filters (template j times response term q):
    # the K x Q products compressed per group (direct path, echoes) to the rank
    # their sum needs
    gains, filt_band = compress(
        plan.terms,
        plan.responses,
        plan.templates,
        plan.products if plan.coarse_spectra is None else plan.folded_products,
        plan.response_spectra,
        plan.direct_paths,
        plan.direct_terms,
        plan.options.compress_tolerance,
    )
    R, opts = filt_band.shape[1], plan.options
    call = plan.call + 2 * FILTER_TAILS  # the filtered calls' length, about
    kernel = (opts.interpolator, opts.taps)
    # the sum in time is single precision: a double-precision render (no path
    # response) stays in the frequency domain unless asked
    domain = opts.domain if plan.single or opts.domain != "auto" else "frequency"
    # few paths are summed in time at either rate (cheaper than any transform)
    if _in_time(domain, gains.shape[:2], R, kernel, call, n, mixed=R):
        return _planned_in_time(plan, gains, filt_band, out)
    if opts.rate == "baseband":
        return _render_baseband(plan, gains, filt_band, out)
    # the filters over the bins from the band's first to its last (zero elsewhere)
    band = plan.band
    b0, b1 = np.flatnonzero(band)[[0, -1]] + [0, 1]
    cdtype = np.complex64 if plan.single else complex
    filt = np.zeros((filt_band.shape[1], b1 - b0), cdtype)  # (sets, bins), contiguous
    filt[:, band[b0:b1]] = filt_band.T
    # 5. impulses per set, FFT, sum of products over the band, back
    into, d = (out[:, : plan.hi], lo), plan.positions
    r = _direct_sets(plan, gains, kernel, call) if domain == "auto" else 0
    # the echoes' sets by FFT (the direct path among the impulses with zero gains:
    # none added), the direct path's own first r sets summed in time onto them
    _sets_by_fft(d, (gains[:, :, r:], None), filt[r:], (b0, b1, n), kernel, plan.single, into)
    if r:
        paths = np.flatnonzero(plan.direct_paths)
        _planned_in_time(plan, gains[:, paths, :r], filt_band[:, :r], out, paths=paths)
    return out


def _direct_sets(plan: DopplerPlan, gains: np.ndarray, kernel, call: int) -> int:
    """How many of the first sets (r) to sum in time while the rest go by FFT: those
    of the direct path, when only it uses them and the sum in time is estimated
    cheaper than their forward FFTs (:func:`~.timedomain.prefer_time`); else 0.
    :func:`~.compress.compress` gives each group its own sets, the direct path's
    first: `gains` (M, N, R) is zero off the blocks (direct paths, first r sets)
    and (echoes, the others)."""
    paths = np.flatnonzero(plan.direct_paths)
    n_d = paths.size
    if n_d == 0 or n_d == plan.direct_paths.size:
        return 0
    own = gains[:, paths]  # (M, N_d, R): few paths
    used = np.flatnonzero(np.any(own != 0, axis=(0, 1)))
    r = int(used[-1]) + 1 if used.size else 0
    if r == 0 or r == gains.shape[2] or used.size != r:
        return 0
    # r sets fewer on the FFT route: r forward FFTs a microphone (the inverse stays)
    shape = (gains.shape[0], n_d)
    return r if _in_time("auto", shape, r - 1, kernel, call, plan.n_fft, r) else 0


def _planned_in_time(plan: DopplerPlan, gains, filt_band, out, paths=None) -> np.ndarray:
    """Step 5 summed in time (:mod:`.timedomain`, few paths): each set's filter
    applied to the time-scaled calls once, each copy its gains' mix of the sets'
    filtered calls through the same fractional-delay weights; `gains` (M, N, R),
    `filt_band` (B, R) the sets' filters over the band: added into `out` (M, T).
    `paths` (N,): the plan's paths the columns of `gains` are (None: all)."""
    spec = np.zeros((filt_band.shape[1], plan.n_fft // 2 + 1), complex)
    spec[:, plan.band] = filt_band.T
    calls, lead = filtered_calls(spec, plan.n_fft)
    d, opts, lo, hi = plan.positions, plan.options, plan.lo, plan.hi
    d = d if paths is None else d[:, paths]
    kernel = _taps(d, opts.interpolator, opts.taps)
    row = np.zeros(d.shape[1], np.intp)  # every path: the R sets' calls
    return render_time(
        d, gains, calls, lead=lead, kernel=kernel, n_samples=hi - lo, row=row, into=(out, lo)
    )


def _render_baseband(plan: DopplerPlan, gains, filt_band, out) -> np.ndarray:
    """Step 5 at complex baseband: the echoes' sets over their band
    (:func:`.baseband.spectra`), one inverse FFT per microphone (in the plan's
    precision, in this thread); the direct path's sets, tens of dB above the echoes,
    summed in time onto them as the full-rate renderer sums them
    (:func:`_planned_in_time`)."""
    n, lo, hi, opts = plan.n_fft, plan.lo, plan.hi, plan.options
    echoes = baseband.echo_sets(gains, plan.direct_paths)
    # the compression's sets have unit energy (orthonormal gains: their weights are
    # in the filters), so the band's centre weighs the filters alone
    energy = np.ones(gains.shape[2])
    if echoes.any():
        filters = np.zeros((gains.shape[2], n // 2 + 1), complex)
        filters[:, plan.band] = filt_band.T
        pad = opts.taps + 1  # the full-rate renderer's layout: the same span
        cdtype = np.complex64 if plan.single else complex
        sets = np.flatnonzero(echoes)
        q = plan.positions + pad
        spec = baseband.spectra(q, gains, filters, sets, energy, opts.band_floor_db, cdtype, n)
        y = sfft.irfft(spec, n, axis=-1, workers=1, overwrite_x=True)[:, pad : pad + hi - lo]
        _placed(y, (out, lo))
    if not echoes.all():
        paths, own = np.flatnonzero(plan.direct_paths), np.flatnonzero(~echoes)
        _planned_in_time(plan, gains[:, paths][:, :, own], filt_band[:, own], out, paths=paths)
    return out


def _chebyshev_argument(nodes: np.ndarray, rate: np.ndarray) -> np.ndarray | None:
    """The Doppler factors `rate` (...) mapped from the interval of the Chebyshev
    `nodes` (K,) onto [-1, 1] (C order; None for one node): the interpolant of the
    time-scaled call in the Doppler factor is a Chebyshev series, the path gains times
    T_p of this (:class:`~.compress.ChebyshevGains`) and the templates' Chebyshev
    coefficients (:func:`_chebyshev_coefficients`; the same polynomial as the Lagrange
    form, without barycentric weights)."""
    if nodes.size == 1:
        return None
    offset, half = _chebyshev_interval(nodes)
    s = np.subtract(rate, offset, out=np.empty(np.shape(rate)))  # C order
    s /= half
    return s


def _chebyshev_interval(nodes: np.ndarray) -> tuple[float, float]:
    """(offset, half): a factor a maps onto ``(a - offset) / half`` in [-1, 1] from
    the interval of the K > 1 Chebyshev `nodes` (K,)."""
    K = nodes.size
    x = np.cos((2 * np.arange(K) + 1) * np.pi / (2 * K))
    half = (nodes[0] - nodes[-1]) / (x[0] - x[-1])
    return float(nodes[0] - half * x[0]), float(half)


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
