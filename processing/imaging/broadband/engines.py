"""The engines of the broadband energyscape (:mod:`processing.imaging.broadband.energyscape`,
steps 3-5):
the combination of aligned channels (:func:`combine`), the focusing delays, and the
compiled (numba, :mod:`._bbkernel`) and numpy engines that write the power of every
direction and output range bin."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from math import comb

import numpy as np
from scipy import fft as sfft

from processing.base.kernels import optional_kernel
from processing.sensor.arrays import Array

__all__ = ["Baseband", "OutputWindow", "combine", "compiled_engine", "numpy_engine", "kernels"]


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


@dataclass(frozen=True, eq=False)
class OutputWindow:
    """The baseband samples an energyscape keeps: `index` (whole blocks of the
    decimation) into the baseband's `range_m` (N,) and `time_s` (N,) axes."""

    index: np.ndarray
    range_m: np.ndarray
    time_s: np.ndarray


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


def kernels():
    """The compiled kernels, or None when numba is not installed."""
    return optional_kernel("processing.imaging.broadband.kernel")


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


def compiled_engine(recording, bb, u, window: OutputWindow, spec, settings, out) -> None:
    """Steps 3-5 in the compiled kernels (linear interpolation, U-times upsampled):
    the power of directions `u` (G, 3) over the output `window` into `out` (R, G)
    for the method `spec` (:class:`processing.imaging.methods.MethodSpec`)."""
    kern = kernels()
    idx, rng = window.index, window.range_m
    order, cf = spec.order, spec.coherence_factor
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


def numpy_engine(recording, bb, u, window: OutputWindow, spec, settings, out) -> None:
    """Steps 3-5 in numpy: far field exactly (phase ramps on the spectrum), near field
    by linear interpolation; the reference of the compiled path (arguments as
    :func:`compiled_engine`)."""
    idx, rng, t = window.index, window.range_m, window.time_s
    order, cf = spec.order, spec.coherence_factor
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
