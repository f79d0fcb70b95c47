"""Broadband time-domain imaging: energyscapes by DAS, DAS-CF and DMAS(-CF).

The real sensors' own pipelines image the whole call, not one STFT bin: matched
filter over the call's band, delay-and-sum over every microphone, envelope, low-pass
and decimation into an *energyscape* of directions x ranges.  Steps here:

1. **Generalised matched filter** (:func:`baseband`): ``Y = X conj(H)`` per channel
   (``weighting="plain"``) or its phase only, ``Y / |Y|`` (``"phat"``), restricted to
   the call's band by a Tukey window (taper 0.2 of the band) -- one real FFT of the
   recording.
2. **Complex baseband**: the band's bins are shifted down by the centre bin f0 and
   inverse-transformed at a rate ``oversample * B`` (B the band's width): the
   analytic signal of the matched-filter output, demodulated and decimated in one
   step, exactly (no filter ripple; only the FFT's circular wrap at the ends).
3. **Fractional delays** (never rounded to whole samples): the aligned channel of
   microphone m for a focus point is ``z_m(t - d) exp(-j 2 pi f0 d)`` with ``d``
   the delay below.  The numpy engine steers the far field exactly, as a phase ramp
   on the baseband spectrum; the compiled engine (numba, :mod:`._bbkernel`)
   interpolates a baseband upsampled ``upsample`` (8) times by FFT, 4-point
   Lagrange for the far field (about -53 dB from the exact ramp) and linear for
   near-field focusing, whose delay changes with range (the numpy engine
   interpolates the same way there); ``benchmarks/broadband.py`` measures both.
   Plain far-field DAS needs no aligned channels: both engines (the compiled one up
   to 512 directions, where it is the faster) sum the phase-ramped spectra over the
   microphones and inverse-transform one beam per direction, exactly (the compiled
   kernel in float32, about -65 dB from float64).
4. **Combination** of the M aligned channels ``s_m`` at each direction and time:

   =========  ================================================================
   das        ``|sum s_m / M|^2``
   das-cf     das times the coherence factor ``CF = |sum s_m|^2 / (M sum |s_m|^2)``
   dmasP      ``|e_P(s^) / C(M, P)|^2``, P = 2..5, with ``s^_m = s_m |s_m|^(1/P - 1)``
              (the signed P-th root of the complex sample: its phase kept, its
              magnitude's P-th root) and ``e_P`` the elementary symmetric
              polynomial of degree P over the M microphones (the sum of the
              products of every P distinct channels), computed from the power
              sums ``p_k = sum s^_m^k`` by the Newton-Girard identities in O(M P)
   dmasP-cf   dmasP times CF
   =========  ================================================================

   For M coherent channels of equal amplitude every combination returns that
   amplitude squared (C(M, P) is the number of products), so all methods share one
   scale; incoherent side lobes are suppressed by the products and by CF.
5. **Envelope, low-pass, decimation**: the power is averaged over blocks of
   ``decimation`` baseband samples (a boxcar low-pass) -- one output range bin per
   block, at the block's mean range -- and averaged over the K measurements.

Geometry: a focus point at range r in direction u is ``x = r u`` (array
coordinates); its echo reaches microphone m at ``(|x - e| + |x - p_m|) / c`` after
the emission (e the emitter), and the range axis is ``c t / 2``, as in
:mod:`processing.snapshot`.  Near-field focusing uses that time exactly at the range
of each baseband sample, so ``d_m = 2 r / c - (|x - e| + |x - p_m|) / c``; far-field
steering uses its limit for large r, ``d_m = u . (e + p_m) / c``.

Scale: the recording is divided by its largest absolute sample before anything is
squared (inputs of any magnitude, 1e-160 or 1e+160, give the same energyscape); the
power is therefore relative to that sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from math import comb
from typing import Literal, get_args

import numpy as np
from scipy import fft as sfft
from scipy.signal.windows import tukey

from .arrays import Array
from .errors import InputError
from .kernels import optional_kernel
from .recording import Recording
from .steering import Grid
from .waveforms import Waveform

__all__ = [
    "BroadbandMethod",
    "BROADBAND_METHODS",
    "BroadbandSettings",
    "Baseband",
    "Directions",
    "Energyscape",
    "baseband",
    "energyscape",
    "sphere_partition",
    "fan",
    "combine",
]

BroadbandMethod = Literal[
    "das-bb",
    "das-cf-bb",
    "dmas2-bb",
    "dmas3-bb",
    "dmas4-bb",
    "dmas5-bb",
    "dmas2-cf-bb",
    "dmas3-cf-bb",
    "dmas4-cf-bb",
    "dmas5-cf-bb",
]
BROADBAND_METHODS: tuple[str, ...] = get_args(BroadbandMethod)

Weighting = Literal["plain", "phat"]
Focus = Literal["far", "near"]
Engine = Literal["auto", "numba", "numpy"]
Interpolation = Literal["linear", "cubic"]


@dataclass(frozen=True)
class BroadbandSettings:
    """Settings of a broadband energyscape.

    range_limits_m : (min, max) range of the energyscape, m (default 0.5-5 m, as the
        sensors' own pipeline).
    decimation : baseband samples averaged into one output range bin.
    oversample : baseband rate over the band's width (>= 2 keeps the squared
        envelope free of aliasing).
    weighting : 'plain' matched filter or 'phat' (phase transform).
    focus : 'far' (plane-wave steering) or 'near' (focus at each range).
    upsample : FFT upsampling of the baseband for near-field interpolation.
    band_hz : (low, high) band, Hz; None: the call's band.
    chunk : directions processed at once by the numpy engine (bounds the memory).
    engine : 'numba' (compiled kernels, linear interpolation on the upsampled
        baseband), 'numpy' (far field exact by phase ramps; slow) or 'auto' (numba
        when installed).
    interpolation : 'cubic' (4-point Lagrange) or 'linear' between the samples of
        the upsampled baseband, compiled far-field path (not plain DAS of up to 512
        directions: exact).
    """

    range_limits_m: tuple[float, float] = (0.5, 5.0)
    decimation: int = 4
    oversample: float = 2.0
    weighting: Weighting = "plain"
    focus: Focus = "far"
    upsample: int = 8
    band_hz: tuple[float, float] | None = None
    chunk: int = 16
    engine: Engine = "auto"
    interpolation: Interpolation = "cubic"

    def __post_init__(self) -> None:
        lo, hi = self.range_limits_m
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise InputError("must be 0 <= min < max", key="range_limits_m", value=(lo, hi))
        if int(self.decimation) < 1:
            raise InputError("must be >= 1", key="decimation", value=self.decimation)
        if not self.oversample >= 1:
            raise InputError("must be >= 1", key="oversample", value=self.oversample)
        if self.weighting not in get_args(Weighting):
            raise InputError(
                f"choose one of {get_args(Weighting)}", key="weighting", value=self.weighting
            )
        if self.engine not in get_args(Engine):
            raise InputError(f"choose one of {get_args(Engine)}", key="engine", value=self.engine)
        if self.interpolation not in get_args(Interpolation):
            raise InputError(
                f"choose one of {get_args(Interpolation)}",
                key="interpolation",
                value=self.interpolation,
            )
        if self.focus not in get_args(Focus):
            raise InputError(f"choose one of {get_args(Focus)}", key="focus", value=self.focus)
        if int(self.upsample) < 1 or int(self.chunk) < 1:
            raise InputError(
                "must be >= 1", key="upsample/chunk", value=(self.upsample, self.chunk)
            )


@dataclass(frozen=True, eq=False)
class Directions:
    """A set of G look directions.

    azimuth_rad, elevation_rad : (G,) each.  ``shape`` is (E, A) when the set is a
    product grid in elevation-major order (then an energyscape is an :class:`Image`),
    else None.  ``solid_angle_sr`` (G,): the area each direction stands for, or None.
    """

    azimuth_rad: np.ndarray
    elevation_rad: np.ndarray
    shape: tuple[int, int] | None = None
    solid_angle_sr: np.ndarray | None = None

    @classmethod
    def from_grid(cls, grid: Grid) -> Directions:
        el, az = np.meshgrid(grid.elevation_rad, grid.azimuth_rad, indexing="ij")
        return cls(az.ravel(), el.ravel(), grid.shape)

    @property
    def size(self) -> int:
        return self.azimuth_rad.size

    def unit(self) -> np.ndarray:
        """Unit vectors (G, 3), x forward, y left, z up."""
        az, el = self.azimuth_rad, self.elevation_rad
        return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1)


def fan(azimuth_deg: tuple[float, float] = (-90.0, 90.0), n: int = 181) -> Directions:
    """A horizontal fan of `n` azimuths (inclusive limits in degrees) at elevation 0."""
    az = np.deg2rad(np.linspace(azimuth_deg[0], azimuth_deg[1], int(n)))
    return Directions.from_grid(Grid(az, np.zeros(1)))


def sphere_partition(n: int, *, frontal: bool = True) -> Directions:
    """Centres of a recursive zonal equal-area partition of the sphere (Leopardi).

    The sphere is cut into two polar caps and collars of equal angular height, each
    collar into regions of exactly equal area ``4 pi / N``.  The poles point along
    +x and -x (forward and backward), so the collars are rings around the sensor's
    axis.  With ``frontal=True`` the partition has N = 2n regions and the n (about)
    whose centres face forward (x > 0) are returned.
    """
    N = 2 * int(n) if frontal else int(n)
    if N < 2:
        raise InputError("need at least 1 direction", key="n", value=n)
    area = 4 * np.pi / N
    theta_c = np.arccos(1 - 2 / N)  # polar cap of one region's area
    n_collars = max(1, int(round((np.pi - 2 * theta_c) / np.sqrt(area)))) if N > 2 else 0
    counts = [1]
    if n_collars:
        fit = (np.pi - 2 * theta_c) / n_collars
        edges = theta_c + fit * np.arange(n_collars + 1)
        ideal = 2 * np.pi * (np.cos(edges[:-1]) - np.cos(edges[1:])) / area
        carry = 0.0
        for v in ideal:
            m = int(round(v + carry))
            carry += v - m
            counts.append(m)
    counts.append(1)
    counts = np.array(counts)
    cum = np.cumsum(counts)
    # colatitude of each cap boundary from the cumulative area
    bounds = np.arccos(np.clip(1 - 2 * cum / N, -1, 1))
    bounds = np.concatenate([[0.0], bounds])
    polar, around = [], []
    for i, m in enumerate(counts):
        if m == 1 and (i == 0 or i == len(counts) - 1):
            polar.append(0.0 if i == 0 else np.pi)
            around.append(0.0)
            continue
        mid = 0.5 * (bounds[i] + bounds[i + 1])
        phi = (np.arange(m) + 0.5) * 2 * np.pi / m
        polar += [mid] * m
        around += list(phi)
    polar, around = np.array(polar), np.array(around)
    # polar axis along +x; around the axis: y = sin(polar) cos(phi), z = sin(polar) sin(phi)
    u = np.stack(
        [np.cos(polar), np.sin(polar) * np.cos(around), np.sin(polar) * np.sin(around)], -1
    )
    if frontal:
        u = u[u[:, 0] > 1e-12]
    el = np.arcsin(np.clip(u[:, 2], -1, 1))
    az = np.arctan2(u[:, 1], u[:, 0])
    return Directions(az, el, None, np.full(az.size, area))


@dataclass(frozen=True, eq=False)
class Baseband:
    """Complex baseband of the matched-filtered recording.

    spectrum : (K, M, N) baseband spectrum in FFT order (bin k at ``freq_hz[k]`` from
        ``f0_hz``).  :attr:`signal` : (K, M, N) its inverse transform, sample n at
        ``n / rate_hz - emission_s`` after the emission.
    """

    spectrum: np.ndarray
    freq_hz: np.ndarray
    f0_hz: float
    rate_hz: float
    emission_s: float

    @cached_property
    def signal(self) -> np.ndarray:
        return sfft.ifft(self.spectrum, axis=-1)


@lru_cache(maxsize=8)
def _template_bins(
    waveform: Waveform, fs: float, n: int, k_lo: int, k_hi: int, nb: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """conj(H) at the baseband bins, the band taper, the bins and the plain weight
    (cached per call)."""
    kb = np.fft.fftfreq(nb, 1 / nb).astype(int)  # baseband bin offsets in FFT order
    k0 = (k_lo + k_hi) // 2
    k = k0 + kb
    inside = (k >= k_lo) & (k <= k_hi)
    taper = np.zeros(nb)
    taper[inside] = tukey(k_hi - k_lo + 1, 0.2)[k[inside] - k_lo]
    kc = np.clip(k, 0, n // 2)
    H = np.conj(sfft.rfft(waveform.sampled(fs), n)[kc])
    # the plain matched filter, band taper and analytic-signal scale (2 nb / n) of the
    # n-point real inverse transform folded into one weight per baseband bin
    plain = H * (taper * (2 * nb / n) / max(np.abs(H).max(), 1e-300))
    for a in (H, taper, kb, kc, plain):
        a.flags.writeable = False
    return H, taper, kb, kc, plain


def baseband(
    recording: Recording, settings: BroadbandSettings, *, single: bool = False
) -> Baseband:
    """Steps 1-2: matched filter (plain or PHAT) over the band, complex baseband.

    `single`: transform in float32 (twice as fast; relative error about 1e-7).
    """
    x = recording.samples
    x = x[None] if x.ndim == 2 else x
    fs = recording.sample_rate_hz
    peak = max(x.max(), -x.min()) if x.size else 0.0  # max |x| without a temporary
    if not np.isfinite(peak):
        raise InputError("samples must be finite", key="samples", value=peak)
    h_size = int(np.ceil(recording.waveform.duration_s * fs - 1e-9))
    T = x.shape[-1]
    n = sfft.next_fast_len(T + h_size, real=True)
    lo, hi = settings.band_hz or recording.waveform.band_hz
    hi = min(hi, fs / 2)
    if not 0 <= lo < hi:
        raise InputError("the band is empty below Nyquist", key="band_hz", value=(lo, hi))
    df = fs / n
    k_lo, k_hi = int(np.ceil(lo / df)), int(np.floor(hi / df))
    k0 = (k_lo + k_hi) // 2
    nb = sfft.next_fast_len(int(np.ceil(settings.oversample * (k_hi - k_lo + 1))))
    H, taper, kb, kc, plain = _template_bins(recording.waveform, fs, n, k_lo, k_hi, nb)
    dtype = np.float32 if single else np.float64
    if peak > 0:  # normalise before anything is squared: any magnitude works
        x = np.divide(x, peak, out=np.empty(x.shape, dtype), casting="unsafe")
    else:
        x = x.astype(dtype)
    X = sfft.rfft(x, n, axis=-1, workers=-1)[..., kc]
    scale = 2 * nb / n  # analytic signal of the n-point real inverse transform
    if settings.weighting == "phat":
        Y = X * H
        mag = np.abs(Y)
        Y = np.divide(Y, mag, out=np.zeros_like(Y), where=mag > 1e-12 * mag.max(initial=0))
        Y *= (taper * scale).astype(Y.real.dtype)
    else:  # one product with the cached weight
        Y = X * plain.astype(X.dtype, copy=False)
    return Baseband(
        spectrum=Y,
        freq_hz=kb * df,
        f0_hz=k0 * df,
        rate_hz=nb * df,
        emission_s=recording.emission_index / fs,
    )


@dataclass(frozen=True, eq=False)
class Energyscape:
    """Power of G directions at R ranges.

    power : (R, G); range_m : (R,); directions : Directions; method : str.
    """

    power: np.ndarray
    range_m: np.ndarray
    directions: Directions
    method: str
    bin_range_m: float

    def to_grid(self) -> np.ndarray:
        """Power as (R, E, A) for a product grid of directions."""
        if self.directions.shape is None:
            raise InputError("the directions are not a product grid", key="directions")
        return self.power.reshape(self.power.shape[0], *self.directions.shape)


def _parse(method: str) -> tuple[str, int, bool]:
    if method not in BROADBAND_METHODS:
        raise InputError(
            f"choose one of {', '.join(BROADBAND_METHODS)}", key="method", value=method
        )
    head = method[: -len("-bb")]
    cf = head.endswith("-cf")
    head = head[:-3] if cf else head
    order = 1 if head == "das" else int(head[len("dmas") :])
    return head, order, cf


def combine(s: np.ndarray, order: int, cf: bool) -> np.ndarray:
    """Step 4 on aligned channels s (..., M, N): power (..., N).

    order 1 is DAS; 2-5 DMAS of that order; `cf` multiplies by the coherence factor.
    """
    M = s.shape[-2]
    total = s.sum(axis=-2)
    if order == 1:
        power = np.abs(total / M) ** 2
    else:
        mag = np.abs(s)
        with np.errstate(divide="ignore", invalid="ignore"):
            root = np.where(mag > 0, s * mag ** (1.0 / order - 1.0), 0)
        # Newton-Girard: k e_k = sum_{i=1..k} (-1)^(i-1) e_{k-i} p_i
        p = [None, root.sum(axis=-2)]
        power_k = root
        for _ in range(2, order + 1):
            power_k = power_k * root
            p.append(power_k.sum(axis=-2))
        e = [np.ones_like(p[1])]
        for kk in range(1, order + 1):
            acc = np.zeros_like(p[1])
            for i in range(1, kk + 1):
                term = e[kk - i] * p[i]
                acc = acc + term if i % 2 else acc - term
            e.append(acc / kk)
        power = np.abs(e[order] / comb(M, order)) ** 2
    if cf:
        energy = (s.real**2 + s.imag**2).sum(axis=-2)
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = np.where(energy > 0, np.abs(total) ** 2 / (M * energy), 0.0)
        power = power * factor
    return power


def _delays(array: Array, u: np.ndarray, range_m: np.ndarray | None, c: float) -> np.ndarray:
    """Delays d (G, M) far field, or (G, M, N) near field at ranges (N,), seconds."""
    p, e = array.positions_m, array.emitter_m
    if range_m is None:
        return (u @ (p + e).T) / c
    x = range_m[None, :, None] * u[:, None, :]  # (G, N, 3)
    d_e = np.linalg.norm(x - e, axis=-1)  # (G, N)
    d_m = np.linalg.norm(x[:, None] - p[None, :, None], axis=-1)  # (G, M, N)
    return (2 * range_m[None, None, :] - d_e[:, None, :] - d_m) / c


def energyscape(
    recording: Recording,
    directions: Directions | Grid,
    method: BroadbandMethod = "das-bb",
    settings: BroadbandSettings | None = None,
    *,
    bb: Baseband | None = None,
) -> Energyscape:
    """The broadband energyscape of a recording (module docstring, steps 1-5).

    Returns power (R, G) at the ranges of `settings.range_limits_m`.
    """
    settings = settings or BroadbandSettings()
    _, order, cf = _parse(method)
    dirs = Directions.from_grid(directions) if isinstance(directions, Grid) else directions
    engine = settings.engine
    if engine == "auto":
        engine = "numba" if _kernels() is not None else "numpy"
    bb = bb if bb is not None else baseband(recording, settings, single=engine == "numba")
    c = recording.speed_of_sound_m_s
    K, M, N = bb.spectrum.shape
    D = int(settings.decimation)
    # output window: whole blocks of D baseband samples inside the range limits
    t = np.arange(N) / bb.rate_hz - bb.emission_s
    rng = c * t / 2
    lo, hi = settings.range_limits_m
    idx = np.flatnonzero((rng >= lo) & (rng <= hi))
    if idx.size < D:
        raise InputError(
            "no range bin of the recording lies within the range limits",
            key="range_limits_m",
            value=settings.range_limits_m,
        )
    idx = idx[: idx.size // D * D]
    r_out = rng[idx].reshape(-1, D).mean(axis=1)
    u = dirs.unit()
    G = u.shape[0]
    out = np.empty((r_out.size, G))
    if engine == "numba":
        _compiled(recording, bb, u, idx, rng, order, cf, settings, out)
    else:
        _numpy(recording, bb, u, idx, rng, t, order, cf, settings, out)
    return Energyscape(
        power=out,
        range_m=r_out,
        directions=dirs,
        method=method,
        bin_range_m=c * D / bb.rate_hz / 2,
    )


def _kernels():
    """The compiled kernels, or None when numba is not installed."""
    return optional_kernel("processing._bbkernel")


def _fine(bb: Baseband, U: int, pad: int, dtype=complex) -> np.ndarray:
    """The baseband upsampled U times by FFT, `pad` zero baseband samples each side:
    (K, M, (N + 2 pad) U)."""
    K, M, N = bb.spectrum.shape
    spec = np.zeros((K, M, N * U), dtype)
    half = N // 2
    spec[..., :half] = bb.spectrum[..., :half]
    spec[..., -(N - half) :] = bb.spectrum[..., half:]
    fine = sfft.ifft(spec, axis=-1, overwrite_x=True, workers=-1)
    fine *= U
    return np.pad(fine, ((0, 0), (0, 0), (pad * U, pad * U)))


def _polyphase(bb: Baseband, U: int) -> np.ndarray:
    """The baseband upsampled U times by FFT, in polyphase order and complex64:
    (K, M, U, N), ``[k, m, p, n]`` = sample ``n U + p`` of :func:`_fine` (unpadded).

    Phase p is the N-point inverse transform of the spectrum delayed by ``p / U``
    samples (``exp(2j pi f p / (U rate))`` on the signed bins), so the U phases come
    straight out of one batched FFT with no transposing copy.
    """
    spec = bb.spectrum.astype(np.complex64)[:, :, None, :] * _phase_shifts(bb.spectrum.shape[-1], U)
    return sfft.ifft(spec, axis=-1, overwrite_x=True, workers=-1)


@lru_cache(maxsize=8)
def _phase_shifts(N: int, U: int) -> np.ndarray:
    """``exp(2j pi f p / (N U))`` (U, N) complex64 on the signed bins f of an N-point
    spectrum in FFT order (bin N/2 negative: _fine's zero-padding convention)."""
    signed = np.fft.fftfreq(N, 1 / N)
    if N % 2 == 0:
        signed[N // 2] = -N // 2
    shift = np.exp(2j * np.pi * np.arange(U)[:, None] * signed[None, :] / (N * U))
    shift = shift.astype(np.complex64)
    shift.flags.writeable = False
    return shift


def _split(z: np.ndarray, pad: int) -> tuple[np.ndarray, np.ndarray]:
    """Real and imaginary parts of z (..., N) as float32 (..., N + 2 pad), zero-padded."""
    shape = (*z.shape[:-1], z.shape[-1] + 2 * pad)
    zr, zi = np.zeros(shape, np.float32), np.zeros(shape, np.float32)
    zr[..., pad : pad + z.shape[-1]] = z.real
    zi[..., pad : pad + z.shape[-1]] = z.imag
    return zr, zi


def _rooted(z: np.ndarray, order: int) -> np.ndarray:
    if order == 1:
        return np.zeros((1,) * z.ndim, complex)
    mag = np.abs(z)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(mag > 0, z * mag ** (1.0 / order - 1.0), 0)


def _compiled(recording, bb, u, idx, rng, order, cf, settings, out) -> None:
    """Steps 3-5 in the compiled kernels (linear interpolation, U-times upsampled)."""
    kern = _kernels()
    arr = recording.array
    c = recording.speed_of_sound_m_s
    U = int(settings.upsample)
    reach = np.abs(np.concatenate([arr.positions_m, arr.emitter_m[None]])).sum(1).max()
    pad = int(np.ceil(2 * reach / c * bb.rate_hz)) + 2
    binom = float(comb(arr.n_mics, order))
    D = int(settings.decimation)
    # plain far-field DAS of a few hundred directions: the exact frequency-domain sum
    # is faster (no upsampling FFT); above about 500 directions the interpolation's
    # per-direction cost is lower (eRTIS, 32 x 16384 samples, measured)
    if settings.focus == "far" and order == 1 and not cf and u.shape[0] <= _SPECTRAL_DAS_MAX:
        _das_spectrum(kern, bb, _delays(arr, u, None, c), idx, arr.n_mics, D, out)
    elif settings.focus == "far":
        d = _delays(arr, u, None, c)  # (G, M)
        start = (idx[0] + pad) * U - d * bb.rate_hz * U
        i0 = np.floor(start).astype(np.int64)
        f = (start - i0)[..., None]
        if settings.interpolation == "cubic":  # Lagrange on the nodes -1, 0, 1, 2
            offsets = np.arange(-1, 3)
            taps = np.concatenate(
                [
                    -f * (f - 1) * (f - 2) / 6,
                    (f + 1) * (f - 1) * (f - 2) / 2,
                    -(f + 1) * f * (f - 2) / 2,
                    (f + 1) * f * (f - 1) / 6,
                ],
                axis=-1,
            )
        else:
            offsets = np.arange(2)
            taps = np.concatenate([1 - f, f], axis=-1)
        node = i0[..., None] + offsets  # (G, M, T) fine indices
        w = taps * np.exp(-2j * np.pi * bb.f0_hz * d)[..., None]
        Z = _polyphase(bb, U)
        zr, zi = _split(Z, pad)
        if order > 1:
            rr, ri = _split(_rooted(Z, order), pad)
        else:
            rr, ri = (np.zeros((1, 1, 1, 1), np.float32),) * 2
        kern.far_field(zr, zi, rr, ri, node // U, node % U, w, order, cf, binom, D, out)
    else:
        fine = _fine(bb, U, pad)
        rooted = _rooted(fine, order)
        rf = rooted if order > 1 else np.zeros((1, 1, 2), complex)
        step = c / (2 * bb.rate_hz)  # range per baseband sample
        kern.near_field(
            fine, rf, u, arr.positions_m, arr.emitter_m, float(rng[idx[0]]), step,
            float((idx[0] + pad) * U), bb.rate_hz * U, bb.f0_hz, c, order, cf, binom, D, out,
        )  # fmt: skip


_SPECTRAL_DAS_MAX = 512  # directions


def _das_spectrum(kern, bb: Baseband, d: np.ndarray, idx, M: int, D: int, out) -> None:
    """Plain far-field DAS, exact: the M channels steered by phase ramps and summed
    in the frequency domain (the compiled kernel), one inverse FFT per direction."""
    K, _, N = bb.spectrum.shape
    half = (N + 1) // 2  # FFT order -> ascending: bins N - N//2 .. N - 1 come first
    Nb = -(-N // 16) * 16
    Xr = np.zeros((K, bb.spectrum.shape[1], Nb), np.float32)
    Xi = np.zeros_like(Xr)
    Xr[..., : N - half] = bb.spectrum[..., half:].real
    Xr[..., N - half : N] = bb.spectrum[..., :half].real
    Xi[..., : N - half] = bb.spectrum[..., half:].imag
    Xi[..., N - half : N] = bb.spectrum[..., :half].imag
    df = float(bb.freq_hz[1] - bb.freq_hz[0]) if N > 1 else 0.0
    f_start = bb.f0_hz + float(bb.freq_hz[half]) if N > 1 else bb.f0_hz
    G = d.shape[0]
    beams = np.empty((K, G, N), np.complex64)
    kern.far_das_spectrum(Xr, Xi, d, f_start, df, beams)
    z = sfft.ifft(beams, axis=-1, overwrite_x=True, workers=-1)[..., idx[0] : idx[-1] + 1]
    # |z|^2 summed over the K measurements and blocks of D samples, in float32 pairs
    sq = z.view(np.float32)
    sq = np.square(sq, out=sq).reshape(K, G, -1, 2 * D).sum(axis=(0, 3))
    out[:] = (sq / (M * M * D * K)).T


def _numpy(recording, bb, u, idx, rng, t, order, cf, settings, out) -> None:
    """Steps 3-5 in numpy: far field exactly (phase ramps on the spectrum), near field
    by linear interpolation; the reference of the compiled path."""
    c = recording.speed_of_sound_m_s
    K, M, N = bb.spectrum.shape
    D = int(settings.decimation)
    G = u.shape[0]
    f_abs = bb.f0_hz + bb.freq_hz
    near = settings.focus == "near"
    if near:
        U = int(settings.upsample)
        fine = _fine(bb, U, 0)  # (K, M, N U), rate U * rate_hz
    for g0 in range(0, G, int(settings.chunk)):
        ug = u[g0 : g0 + int(settings.chunk)]
        if not near:
            d = _delays(recording.array, ug, None, c)  # (g, M)
            ramp = np.exp(-2j * np.pi * d[:, :, None] * f_abs)  # (g, M, N)
            if order == 1 and not cf:  # sum before the inverse transform
                beam = sfft.ifft(np.einsum("kmn,gmn->kgn", bb.spectrum, ramp), axis=-1)
                power = np.abs(beam[..., idx] / M) ** 2
            else:
                s = sfft.ifft(bb.spectrum[:, None] * ramp[None], axis=-1)[..., idx]
                power = combine(s, order, cf)
        else:
            d = _delays(recording.array, ug, rng[idx], c)  # (g, M, n)
            pos = (t[idx] + bb.emission_s - d) * bb.rate_hz * U  # fractional fine index
            i0 = np.clip(np.floor(pos).astype(int), 0, N * U - 2)
            frac = np.clip(pos - i0, 0.0, 1.0)
            m_idx = np.arange(M)[None, :, None]
            a = fine[:, m_idx, i0]
            b = fine[:, m_idx, i0 + 1]
            s = (a + frac * (b - a)) * np.exp(-2j * np.pi * bb.f0_hz * d)
            power = combine(s, order, cf)
        # power (K, g, n): mean over measurements, block mean over D samples
        out[:, g0 : g0 + ug.shape[0]] = power.mean(axis=0).reshape(ug.shape[0], -1, D).mean(-1).T
