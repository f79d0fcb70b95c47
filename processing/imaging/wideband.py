"""Wideband subspace imaging: Capon/MVDR and MUSIC over the call's band, incoherently.

The narrowband methods of :mod:`processing.imaging.doa` image one STFT bin.  Their wideband
versions image every STFT bin of the call's band (up to the array's alias-free
limit, at most ``max_freqs`` bins spread evenly) at the same kept range bins and
combine them incoherently:

1. The range bins are those of the narrowband snapshot (its energy gate).
2. For each frequency f of the band, the snapshot of every kept range bin at f (one
   DFT bin of the same Hann-windowed frames).
3. The per-bin spectrum P_f of the method (covariance per range bin, FBSS for URAs
   when asked), steered at f.
4. Capon/MVDR: the mean of the P_f (each an output power, so they add);
   MUSIC: the reciprocal of the mean of the 1/P_f (the incoherent-MUSIC sum of the
   noise-subspace projections ``a_f^H E_f E_f^H a_f``).
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from processing.base.api import folded_keywords
from processing.base.errors import InputError
from processing.imaging.doa import SUBSPACE_DEFAULTS, SubspaceOptions, doa_spectrum
from processing.imaging.methods import WIDEBAND_METHODS, WidebandMethod
from processing.imaging.snapshot import stft_window
from processing.imaging.steering import Grid
from processing.sensor.arrays import Array

__all__ = ["WidebandMethod", "WIDEBAND_METHODS", "band_frequencies", "wideband_spectrum"]


def band_frequencies(
    band_hz: tuple[float, float], sample_rate_hz: float, window: int, max_freqs: int = 12
) -> np.ndarray:
    """STFT bin frequencies (Hz) inside the band, at most `max_freqs` spread evenly."""
    freqs = np.fft.rfftfreq(window, 1 / sample_rate_hz)
    inside = np.flatnonzero((freqs >= band_hz[0]) & (freqs <= band_hz[1]))
    if inside.size == 0:
        inside = np.array([int(np.argmin(np.abs(freqs - np.mean(band_hz))))])
    if inside.size > max_freqs:
        inside = inside[np.round(np.linspace(0, inside.size - 1, max_freqs)).astype(int)]
    return freqs[inside]


def band_snapshots(
    mf: np.ndarray,
    sample_rate_hz: float,
    emission_index: int,
    time_s: np.ndarray,
    window: int,
    freqs_hz: np.ndarray,
) -> np.ndarray:
    """Snapshots (F, M, R, K) at the frames centred at `time_s` (R,), frequencies (F,).

    mf : (M, T) or (K, M, T) matched-filter output.  Same frames and window as
    :func:`processing.imaging.snapshot.stft_snapshot`.
    """
    x = np.asarray(mf)
    x = x[None] if x.ndim == 2 else x
    start = np.round(np.asarray(time_s) * sample_rate_hz + emission_index - window // 2)
    start = np.clip(start.astype(int), 0, x.shape[-1] - window)
    frames = sliding_window_view(x, window, axis=-1)[..., start, :]  # (K, M, R, W)
    n = np.arange(window)
    kernel = stft_window("hann", window)[:, None] * np.exp(
        -2j * np.pi * np.outer(n, np.asarray(freqs_hz)) / sample_rate_hz
    )  # (W, F)
    col = frames @ kernel  # (K, M, R, F)
    return np.moveaxis(col, (3, 0), (0, 3))  # (F, M, R, K)


@folded_keywords("options", SubspaceOptions, ("subarray", "loading", "n_sources"), since="0.1.0")
def wideband_spectrum(
    snapshots: np.ndarray,
    array: Array,
    freqs_hz: np.ndarray,
    grid: Grid,
    method: WidebandMethod,
    *,
    speed_of_sound_m_s: float = 343.0,
    options: SubspaceOptions = SUBSPACE_DEFAULTS,
) -> np.ndarray:
    """Incoherent wideband spectrum (R, E, A) from snapshots (F, M, R, K) (steps 3-4)."""
    if method not in WIDEBAND_METHODS:
        raise InputError(f"unknown wideband method {method!r}; choose one of {WIDEBAND_METHODS}")
    narrow = method[: -len("-wb")]
    music = narrow.startswith("music")
    acc = None
    for x, f in zip(snapshots, freqs_hz):
        p = doa_spectrum(
            x,
            array,
            float(f),
            grid,
            narrow,
            speed_of_sound_m_s=speed_of_sound_m_s,
            options=options,
        )
        if music:
            p = np.divide(1.0, p, out=np.zeros_like(p), where=p > 0)
        acc = p if acc is None else acc + p
    if acc is None:
        raise InputError("no frequencies to sum", key="freqs_hz", value=freqs_hz)
    acc /= len(freqs_hz)
    if music:
        acc = np.divide(1.0, acc, out=np.zeros_like(acc), where=acc > 0)
    return acc
