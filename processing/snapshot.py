"""STFT snapshots (section III-A of the paper, steps (c)-(d) of its Fig. 1).

The matched-filter output is transformed with a short-time Fourier transform (the
same transform as :class:`scipy.signal.ShortTimeFFT` over whole windows, computed on
strided frames because ShortTimeFFT loops over slices in Python: 0.4 s against a
few ms for 64 channels); one frequency bin is kept (the one of highest
energy, or a requested frequency), and of its time bins only those whose energy,
summed over microphones (and measurements), is at least `energy_fraction` of the
largest.  Each kept time bin is one range bin of the 3D image.

Time of a bin: the centre of its window, on the recording's time axis (see
:mod:`processing.recording`); its range is ``c * t / 2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.signal import get_window

from .errors import InputError

__all__ = ["Snapshot", "stft_snapshot"]


@dataclass(frozen=True)
class Snapshot:
    """Narrow-band snapshots at the kept range bins.

    Attributes
    ----------
    data : ndarray, complex, shape (M, R) or (M, R, K)
        One complex sample per microphone and kept range bin (and measurement).
    frequency_hz : float
        Centre frequency of the STFT bin (the steering frequency).
    range_m : ndarray, shape (R,)
        Range of each kept bin.
    time_s : ndarray, shape (R,)
        Time after emission of each kept bin (window centre).
    energy : ndarray, shape (R,)
        Energy of each kept bin, summed over microphones and measurements.
    bin_range_m : float
        Spacing between consecutive STFT time bins, as a range.
    """

    data: np.ndarray
    frequency_hz: float
    range_m: np.ndarray
    time_s: np.ndarray
    energy: np.ndarray
    bin_range_m: float

    @property
    def n_bins(self) -> int:
        return self.range_m.size


def stft_snapshot(
    mf: np.ndarray,
    sample_rate_hz: float,
    *,
    speed_of_sound_m_s: float = 343.0,
    emission_index: int = 0,
    window: int = 256,
    overlap: int = 240,
    window_type: str = "hann",
    frequency_hz: float | None = None,
    band_hz: tuple[float, float] | None = None,
    energy_fraction: float = 0.5,
    range_limits_m: tuple[float, float] | None = None,
    max_bins: int | None = None,
) -> Snapshot:
    """Snapshots of a matched-filtered recording at one STFT frequency.

    Parameters
    ----------
    mf : ndarray, shape (M, T) or (K, M, T)
        Matched-filter output (K measurements of a static scene allowed).
    sample_rate_hz : float
    window, overlap : int
        STFT window length and overlap in samples (paper: 256 and 240).
    frequency_hz : float, optional
        Steering frequency; default: the STFT bin with the highest energy.
    band_hz : (low, high), optional
        Where to look for the bin of highest energy (e.g. the band of the call, up to
        the array's alias-free limit); when no bin lies in it (a window too short for
        the sample rate) the bin nearest its centre.  Ignored when `frequency_hz` is
        given.
    energy_fraction : float
        Keep time bins whose energy is at least this fraction of the maximum (paper:
        0.5).  0 keeps every bin.  Bins with zero energy are never kept, so an
        all-zero recording yields no bins.
    range_limits_m : (min, max), optional
        Only bins whose range lies in this interval are considered (before the
        energy gate), e.g. to exclude the direct path or stop at a maximum range.
    max_bins : int, optional
        Keep at most this many bins (the most energetic ones), in range order.
    """
    x = np.asarray(mf)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3:
        raise InputError(f"mf must have shape (M, T) or (K, M, T), got {np.shape(mf)}")
    if not 0 <= overlap < window:
        raise InputError(f"overlap must be in [0, window={window}), got {overlap}")
    if not 0 <= energy_fraction <= 1:
        raise InputError(f"energy_fraction must be in [0, 1], got {energy_fraction}")
    if x.shape[-1] < window:
        raise InputError(f"recording has {x.shape[-1]} samples, fewer than the window {window}")
    hop = window - overlap
    win = get_window(window_type, window)
    # frames[k, m, p, :] = x[k, m, p*hop : p*hop + window]: the STFT of scipy's
    # ShortTimeFFT restricted to whole windows, with bin times at the window centres.
    frames = sliding_window_view(x, window, axis=-1)[..., ::hop, :]
    n_frames = frames.shape[-2]
    times = (np.arange(n_frames) * hop + window // 2 - emission_index) / sample_rate_hz
    ranges = speed_of_sound_m_s * times / 2
    candidate = np.ones(n_frames, bool)
    if range_limits_m is not None:
        lo, hi = range_limits_m
        candidate &= (ranges >= lo) & (ranges <= hi)
    freqs = np.fft.rfftfreq(window, 1 / sample_rate_hz)
    if frequency_hz is None:
        spec = np.fft.rfft(frames[..., candidate, :] * win, axis=-1)  # (K, M, P', F)
        power = (spec.real**2 + spec.imag**2).sum(axis=(0, 1, 2))
        if band_hz is not None:
            inband = (freqs >= band_hz[0]) & (freqs <= band_hz[1])
            if not inband.any():  # bins wider than the band: the one nearest its centre
                inband = np.arange(freqs.size) == np.argmin(np.abs(freqs - np.mean(band_hz)))
            power = np.where(inband, power, -1.0)
        fbin = int(np.argmax(power))
    else:
        fbin = int(np.argmin(np.abs(freqs - frequency_hz)))
    kernel = win * np.exp(-2j * np.pi * fbin * np.arange(window) / window)
    column = frames @ kernel  # (K, M, P): one DFT bin of every frame
    energy = (column.real**2 + column.imag**2).sum(axis=(0, 1))
    energy = np.where(candidate, energy, 0.0)
    top = energy.max() if energy.size else 0.0
    keep = (energy >= energy_fraction * top) & (energy > 0)
    if max_bins is not None and keep.sum() > max_bins:
        order = np.argsort(energy)[::-1][:max_bins]
        keep = np.zeros_like(keep)
        keep[order] = True
    idx = np.flatnonzero(keep)
    data = np.moveaxis(column[:, :, idx], 0, -1)  # (M, R, K)
    if data.shape[-1] == 1 and np.asarray(mf).ndim == 2:
        data = data[..., 0]
    return Snapshot(
        data=data,
        frequency_hz=float(freqs[fbin]),
        range_m=ranges[idx],
        time_s=times[idx],
        energy=energy[idx],
        bin_range_m=speed_of_sound_m_s * hop / sample_rate_hz / 2,
    )
