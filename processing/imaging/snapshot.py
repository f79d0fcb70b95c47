"""STFT snapshots (section III-A of the paper, steps (c)-(d) of its Fig. 1).

The matched-filter output is transformed with a short-time Fourier transform (the
same transform as :class:`scipy.signal.ShortTimeFFT` over whole windows, computed on
strided frames because ShortTimeFFT loops over slices in Python: 0.4 s against a
few ms for 64 channels); one frequency bin is kept (the one of highest
energy, or a requested frequency), and of its time bins only those whose energy,
summed over microphones (and measurements), is at least `energy_fraction` of the
largest.  Each kept time bin is one range bin of the 3D image.

Time of a bin: the centre of its window, on the recording's time axis (see
:mod:`processing.formats.native`); its range is ``c * t / 2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from processing.base.api import folded_keywords
from processing.base.errors import InputError
from processing.imaging.steering import check_frequency

__all__ = ["Snapshot", "Stft", "BinGate", "stft_snapshot", "stft_window", "range_axis"]


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


@dataclass(frozen=True)
class Stft:
    """The STFT of the snapshots: `window` and `overlap` in samples (paper: 256 and
    240), the window's `window_type` (scipy.signal.get_window); `range_step_m`, m:
    frames every this much range, the same in any air, instead of one per hop (None,
    the paper's; see :func:`stft_snapshot`)."""

    window: int = 256
    overlap: int = 240
    window_type: str = "hann"
    range_step_m: float | None = None


#: the gate's default energy fraction: a room has echoes far weaker than the
#: strongest (the paper's single reflector used 0.5: :data:`PAPER_GATE`)
ENERGY_FRACTION = 1e-3
#: the default (min, max) range, m: from 0.25 m, beyond the emitter-to-microphone
#: crosstalk
RANGE_LIMITS_M: tuple[float, float] = (0.25, float("inf"))


@dataclass(frozen=True)
class BinGate:
    """Which range bins are kept: those whose energy is at least `energy_fraction`
    of the strongest's (default :data:`ENERGY_FRACTION`; the paper's 0.5 is
    :data:`PAPER_GATE`; 0 keeps every bin; bins with zero energy never: an all-zero
    recording yields none), inside `range_limits_m` (min, max) m (before the gate,
    e.g. to leave out the direct path; default :data:`RANGE_LIMITS_M`, None: every
    range), at most `max_bins` of them (the most energetic, in range order).  The
    defaults are the pipeline's and the command line's
    (:class:`processing.ProcessingSettings` reads them from here)."""

    energy_fraction: float = ENERGY_FRACTION
    range_limits_m: tuple[float, float] | None = RANGE_LIMITS_M
    max_bins: int | None = None


#: the defaults of :func:`stft_snapshot`: the paper's STFT, the pipeline's gate
STFT_DEFAULTS = Stft()
GATE_DEFAULTS = BinGate()
#: the paper's gate: half the strongest bin's energy, every range
PAPER_GATE = BinGate(energy_fraction=0.5, range_limits_m=None)


@folded_keywords("stft", Stft, ("window", "overlap", "window_type"), since="0.1.0")
@folded_keywords("gate", BinGate, ("energy_fraction", "range_limits_m", "max_bins"), since="0.1.0")
def stft_snapshot(
    mf: np.ndarray,
    sample_rate_hz: float,
    *,
    speed_of_sound_m_s: float = 343.0,
    emission_index: int = 0,
    stft: Stft = STFT_DEFAULTS,
    frequency_hz: float | None = None,
    band_hz: tuple[float, float] | None = None,
    gate: BinGate = GATE_DEFAULTS,
) -> Snapshot:
    """Snapshots of a matched-filtered recording at one STFT frequency.

    `mf` (M, T) or (K, M, T): matched-filter output (K measurements of a static scene
    allowed), sampled at `sample_rate_hz`; `stft`: window, overlap, window type;
    `frequency_hz`: the steering frequency (None: the STFT bin of highest energy,
    searched inside `band_hz` (low, high) when given: the call's band up to the
    array's alias-free limit); `gate`: which range bins are kept.

    With ``stft.range_step_m`` the time bins lie at the ranges ``lo + k * step`` (lo,
    hi: the gate's range limits, or 0 and the last whole frame), instead of one per hop
    (whose range step, c hop / (2 fs), changes with the air): each frame is centred on
    the sample nearest to ``emission_index + 2 r fs / c`` (within half a sample, c /
    (4 fs) in range; 0.2 mm at 450 kHz), and the snapshot reports those ranges. The
    same ranges in any air: what a dataset needs for images of one shape.
    """
    window, overlap = stft.window, stft.overlap
    x = _checked(mf, stft, gate)
    hop = window - overlap
    win = stft_window(stft.window_type, window)
    # frames[k, m, p, :] = x[k, m, p*hop : p*hop + window]: the STFT of scipy's
    # ShortTimeFFT restricted to whole windows, with bin times at the window centres.
    if stft.range_step_m is None:
        frames = sliding_window_view(x, window, axis=-1)[..., ::hop, :]
        n_frames = frames.shape[-2]
        times = (np.arange(n_frames) * hop + window // 2 - emission_index) / sample_rate_hz
        ranges = speed_of_sound_m_s * times / 2
        candidate = np.ones(n_frames, bool)
        bin_range_m = speed_of_sound_m_s * hop / sample_rate_hz / 2
    else:
        ranges = range_axis(
            stft,
            gate.range_limits_m,
            x.shape[-1],
            sample_rate_hz,
            speed_of_sound_m_s,
            emission_index,
        )
        frames, candidate = _frames_at(
            x, window, ranges, sample_rate_hz, speed_of_sound_m_s, emission_index
        )
        frames *= win  # gathered, so a copy already: tapered once, in place
        times = 2 * ranges / speed_of_sound_m_s
        bin_range_m = stft.range_step_m
    tapered = stft.range_step_m is not None
    taper = 1.0 if tapered else win
    if gate.range_limits_m is not None:
        lo, hi = gate.range_limits_m
        candidate &= (ranges >= lo) & (ranges <= hi)
    freqs = np.fft.rfftfreq(window, 1 / sample_rate_hz)
    found = None
    if frequency_hz is None:
        found = _strongest_bin(_candidates(frames, candidate), freqs, band_hz, taper)
        fbin = found.bin
    else:
        fbin = int(np.argmin(np.abs(freqs - _steering(frequency_hz, sample_rate_hz))))
    at = np.flatnonzero(candidate)  # only these frames can be kept (the others: energy 0)
    if found is not None and found.column is not None:
        column = found.column  # the search's products of the candidates at that bin
    else:
        kernel = taper * np.exp(-2j * np.pi * fbin * np.arange(window) / window)
        # (K, M, P'): one DFT bin of each candidate frame, as two real products (the
        # real frames are not copied to complex)
        cand = _candidates(frames, candidate)
        column = cand @ kernel.real + 1j * (cand @ kernel.imag)
    energy = np.zeros(candidate.size)
    energy[at] = (column.real**2 + column.imag**2).sum(axis=(0, 1))
    idx = _kept(energy, gate)
    data = np.moveaxis(column[:, :, np.searchsorted(at, idx)], 0, -1)  # (M, R, K)
    if data.shape[-1] == 1 and np.asarray(mf).ndim == 2:
        data = data[..., 0]
    return Snapshot(
        data=data,
        frequency_hz=float(freqs[fbin]),
        range_m=ranges[idx],
        time_s=times[idx],
        energy=energy[idx],
        bin_range_m=bin_range_m,
    )


def range_axis(
    stft: Stft,
    range_limits_m: tuple[float, float] | None,
    n_samples: int,
    sample_rate_hz: float,
    speed_of_sound_m_s: float,
    emission_index: int = 0,
) -> np.ndarray:
    """The ranges (R,), m, of the time bins with ``stft.range_step_m``: ``lo + k *
    step`` from the first range limit (0 without limits) up to the second, or up to
    the range of the last whole frame of a recording of `n_samples` when that limit
    is infinite or absent."""
    step = stft.range_step_m
    if step is None:
        raise ValueError("range bins need stft.range_step_m (m)")
    lo, hi = range_limits_m or (0.0, float("inf"))
    if not np.isfinite(hi):
        last = n_samples - stft.window + stft.window // 2 - emission_index
        hi = max(lo, speed_of_sound_m_s * last / sample_rate_hz / 2)
    return lo + step * np.arange(int(np.floor((hi - lo) / step + 1e-9)) + 1)


def _frames_at(x, window, ranges, fs, c, emission_index):
    """Frames (K, M, R, window) centred at the samples nearest to the delays of the
    ranges (R,), m, and which of them lie inside the recording (R,) bool (the others
    are the first frame, never kept)."""
    start = np.rint(emission_index + 2 * ranges * fs / c).astype(np.int64) - window // 2
    inside = (start >= 0) & (start + window <= x.shape[-1])
    frames = sliding_window_view(x, window, axis=-1)[..., np.where(inside, start, 0), :]
    return frames, inside


def _candidates(frames: np.ndarray, candidate: np.ndarray) -> np.ndarray:
    """The frames (..., P, window) where `candidate` (P,) is True: a view when they
    are consecutive (the usual case: the range limits' frames), else a copy."""
    idx = np.flatnonzero(candidate)
    if idx.size and idx[-1] - idx[0] + 1 == idx.size:
        return frames[..., idx[0] : idx[-1] + 1, :]
    return frames[..., idx, :]


@dataclass(frozen=True)
class _Strongest:
    """:func:`_strongest_bin`'s answer: the STFT `bin`, and the frames' DFT at that bin
    (..., P') complex when the search computed it (None: the full rfft's search)."""

    bin: int
    column: np.ndarray | None = None


def _strongest_bin(frames: np.ndarray, freqs: np.ndarray, band_hz, taper=1.0) -> _Strongest:
    """The STFT bin of highest energy, summed over the `frames` (..., window) tapered
    by `taper` (window,) (or 1.0: already tapered), inside `band_hz` when given.

    Only the band's bins are computed (a real product with their cosines and sines,
    the taper folded in: no copy of the frames), the same sums as the full
    ``rfft``'s for those bins; the winner's products are the frames' DFT at that bin
    (the snapshots: not computed twice).  Without a band, every bin by ``rfft``."""
    n = frames.shape[-1]
    if band_hz is None:
        spec = np.fft.rfft(frames * taper, axis=-1)  # (K, M, P', F)
        return _Strongest(int(np.argmax((spec.real**2 + spec.imag**2).sum(axis=(0, 1, 2)))))
    bins = np.flatnonzero((freqs >= band_hz[0]) & (freqs <= band_hz[1]))
    if bins.size == 0:  # bins wider than the band: the one nearest its centre
        return _Strongest(int(np.argmin(np.abs(freqs - np.mean(band_hz)))))
    phase = (2 * np.pi / n) * np.outer(np.arange(n), bins)  # (window, B)
    basis = np.asarray(taper)[..., None] * np.hstack([np.cos(phase), np.sin(phase)])
    proj = frames @ basis  # (K, M, P', 2B): real and imaginary parts of the bins
    power = np.einsum("kmpb,kmpb->b", proj, proj)
    b = int(np.argmax(power[: bins.size] + power[bins.size :]))
    return _Strongest(int(bins[b]), proj[..., b] - 1j * proj[..., bins.size + b])


def _checked(mf, stft: Stft, gate: BinGate) -> np.ndarray:
    """The matched-filter output as (K, M, T), the STFT and the gate checked."""
    x = np.asarray(mf)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3:
        raise InputError(f"mf must have shape (M, T) or (K, M, T), got {np.shape(mf)}")
    window, overlap = stft.window, stft.overlap
    if not 0 <= overlap < window:
        raise InputError(f"overlap must be in [0, window={window}), got {overlap}")
    if stft.range_step_m is not None and not stft.range_step_m > 0:
        raise InputError(f"range_step_m must be positive, got {stft.range_step_m}")
    if not 0 <= gate.energy_fraction <= 1:
        raise InputError(f"energy_fraction must be in [0, 1], got {gate.energy_fraction}")
    if x.shape[-1] < window:
        raise InputError(f"recording has {x.shape[-1]} samples, fewer than the window {window}")
    return x


def _kept(energy: np.ndarray, gate: BinGate) -> np.ndarray:
    """Indices of the range bins the gate keeps, in range order, from their energy
    (P,) (zero outside the range limits)."""
    top = energy.max() if energy.size else 0.0
    keep = (energy >= gate.energy_fraction * top) & (energy > 0)
    if gate.max_bins is not None and keep.sum() > gate.max_bins:
        order = np.argsort(energy)[::-1][: gate.max_bins]
        keep = np.zeros_like(keep)
        keep[order] = True
    return np.flatnonzero(keep)


def stft_window(name: str, n: int) -> np.ndarray:
    """The STFT window `name` of `n` samples, as ``scipy.signal.get_window(name, n)``
    gives it (periodic: DFT-even).  "hann" is computed here by scipy's own steps
    (the same bits: a test holds them equal), sparing an imaging process
    scipy.signal's import (about half a second); any other name asks scipy."""
    if name != "hann" or n <= 1:
        from scipy.signal import get_window  # imported here: about half a second

        return get_window(name, n)
    # scipy's general cosine window with a = (0.5, 0.5), extended by one sample for
    # DFT-even symmetry and truncated, in its order of operations
    fac = np.linspace(-np.pi, np.pi, n + 1, dtype=np.float64)
    w = np.zeros(n + 1, dtype=np.float64)
    for k, a in enumerate((0.5, 0.5)):
        w += a * np.cos(k * fac)
    return w[:-1]


def _steering(frequency_hz: float, sample_rate_hz: float) -> float:
    """A user's steering frequency checked: positive (:func:`check_frequency`) and not
    above the Nyquist frequency (where the nearest STFT bin would be the last)."""
    f = check_frequency(frequency_hz)
    if f > sample_rate_hz / 2:
        raise InputError(
            f"above the Nyquist frequency {sample_rate_hz / 2:g} Hz of the recording",
            key="frequency_hz",
            value=frequency_hz,
        )
    return f
