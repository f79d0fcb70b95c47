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
:mod:`processing.imaging.snapshot`.  Near-field focusing uses that time exactly at the range
of each baseband sample, so ``d_m = 2 r / c - (|x - e| + |x - p_m|) / c``; far-field
steering uses its limit for large r, ``d_m = u . (e + p_m) / c``.

Scale: the recording is divided by its largest absolute sample before anything is
squared (inputs of any magnitude, 1e-160 or 1e+160, give the same energyscape); the
power is therefore relative to that sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal, get_args

import numpy as np
from scipy import fft as sfft

from processing.base.errors import InputError
from processing.base.settings import setting, validate
from processing.imaging.broadband.engines import (
    Baseband,
    OutputWindow,
    combine,
    compiled_engine,
    kernels,
    numpy_engine,
)
from processing.imaging.methods import BROADBAND_METHODS, BroadbandMethod, parse_method
from processing.imaging.steering import Grid
from processing.sensor.calls import Waveform
from processing.sensor.recording import Recording

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

    range_limits_m: tuple[float, float] = setting(
        (0.5, 5.0), "m", 0, 1e6, "range of the energyscape (min < max)", kind="interval"
    )
    decimation: int = setting(4, "", 1, 1 << 20, "baseband samples per output range bin")
    oversample: float = setting(2.0, "", 1, 1e3, "baseband rate over the band's width")
    weighting: Weighting = setting("plain", choices=get_args(Weighting), doc="matched filter")
    focus: Focus = setting("far", choices=get_args(Focus), doc="steering: plane wave or focus")
    upsample: int = setting(8, "", 1, 1 << 10, "FFT upsampling of the baseband (near field)")
    band_hz: tuple[float, float] | None = setting(
        None, "Hz", 0, 1e9, "band (low, high); None: the call's", kind="interval"
    )
    chunk: int = setting(16, "", 1, 1 << 20, "directions at once (numpy engine)")
    engine: Engine = setting("auto", choices=get_args(Engine), doc="numba, numpy or auto")
    interpolation: Interpolation = setting(
        "cubic", choices=get_args(Interpolation), doc="between upsampled baseband samples"
    )

    def __post_init__(self) -> None:
        validate(self)
        lo, hi = self.range_limits_m
        if not lo < hi:
            raise InputError("must be 0 <= min < max", key="range_limits_m", value=(lo, hi))


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
    th, ph = np.array(polar), np.array(around)
    # polar axis along +x; around the axis: y = sin(polar) cos(phi), z = sin(polar) sin(phi)
    u = np.stack([np.cos(th), np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph)], -1)
    if frontal:
        u = u[u[:, 0] > 1e-12]
    el = np.arcsin(np.clip(u[:, 2], -1, 1))
    az = np.arctan2(u[:, 1], u[:, 0])
    return Directions(az, el, None, np.full(az.size, area))


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
    from scipy.signal.windows import tukey  # imported here: about a second, for imaging alone

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
    spec = parse_method(method)
    if spec.family != "broadband":
        raise InputError(
            f"choose one of {', '.join(BROADBAND_METHODS)}", key="method", value=method
        )
    recording.array.require_mics("imaging")
    dirs = Directions.from_grid(directions) if isinstance(directions, Grid) else directions
    engine = settings.engine
    if engine == "auto":
        engine = "numba" if kernels() is not None else "numpy"
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
    window = OutputWindow(idx, rng, t)
    if engine == "numba":
        compiled_engine(recording, bb, u, window, spec, settings, out)
    else:
        numpy_engine(recording, bb, u, window, spec, settings, out)
    return Energyscape(
        power=out,
        range_m=r_out,
        directions=dirs,
        method=method,
        bin_range_m=c * D / bb.rate_hz / 2,
    )
