"""What a calibration compares: the energy of the matched-filter output per frequency
band, look direction and range bin.

Every step from the microphone signals to the complex envelopes is linear (matched
filter, delay-and-sum steering, band selection, analytic signal), so the envelopes of
a sum of path groups are the sums of the groups' envelopes; only the energy (the sum
of ``|y|^2`` over a range bin) is quadratic.

Why energy per range bin and direction, and not the waveform sample by sample: the
diffuse (Lambert) tail of a wall is one draw of a random field.  The tracer samples
it with its rays, and a real wall with its roughness; two draws (another ray count,
another wall) put the tail's wavelets at other delays with other phases, so their
waveforms are uncorrelated where their energies agree.  A waveform residual would
read that randomness as a model error and drive the diffuse fraction to zero (the
tail that cannot be matched costs less when it is absent).  The energy of a bin that
spans several resolution cells is a sum of many such wavelets: its expectation is set
by the materials, its spread shrinks with the bin's time-bandwidth product.

The steps, on one real FFT of ``n >= T + L`` points (no wrap-around):

1. matched filter: the spectrum times the conjugate call spectrum;
2. steering: per direction u_d, ``Y_d(f) = (1/M) sum_m X_m(f) exp(-2 pi i f p_m.u_d / c)``
   (far field; p_m the microphone's position in the sensor frame);
3. bands: the call's band split into B equal bands, each tapered (Tukey, 0.5: a
   hard edge rings as 1/t in time and would carry the direct path, tens of dB above
   every echo, across the gate); each band's bins shifted to
   zero frequency and inverse transformed on ``n2`` points: the complex envelope at
   ``fs n2 / n`` samples per second (its modulus is exact at those instants);
4. range bins: ``r = c (t - t_0) / 2`` of each envelope sample, bins `bin_m` wide
   from `min_range_m` (the direct path and the crosstalk before it are gated out)
   to `max_range_m`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft
from scipy.signal import windows

import processing as P
from processing.base.errors import InputError

__all__ = ["FeatureSpace", "Directions", "DEFAULT_AZIMUTHS_DEG", "DEFAULT_ELEVATIONS_DEG"]

DEFAULT_AZIMUTHS_DEG = tuple(float(a) for a in range(-60, 61, 10))
DEFAULT_ELEVATIONS_DEG = (-30.0, 0.0, 30.0)
TAPER = 0.5  # Tukey taper of each band: the fraction of its width in the two ramps
BASEBAND_MARGIN = 1.25  # envelope samples per band bin (above 1: no aliasing)


@dataclass(frozen=True)
class Directions:
    """Look directions of the energy features (degrees, sensor frame: azimuth from x
    towards +y, elevation towards +z)."""

    azimuth_deg: tuple[float, ...] = DEFAULT_AZIMUTHS_DEG
    elevation_deg: tuple[float, ...] = DEFAULT_ELEVATIONS_DEG

    def units(self) -> np.ndarray:
        """(D, 3) unit vectors, azimuth varying fastest."""
        az, el = np.meshgrid(
            np.deg2rad(self.azimuth_deg), np.deg2rad(self.elevation_deg), indexing="xy"
        )
        az, el = az.ravel(), el.ravel()
        return np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])

    def angles_deg(self) -> np.ndarray:
        """(D, 2) azimuth and elevation of each direction."""
        az, el = np.meshgrid(self.azimuth_deg, self.elevation_deg, indexing="xy")
        return np.column_stack([az.ravel(), el.ravel()])


class FeatureSpace:
    """The linear map from microphone signals (..., M, T) to band envelopes
    (..., B, D, T') inside the range gate, and the energies per range bin.

    Built from a recording's sampling (rate, length, emission index, call, array,
    speed of sound); `bands` B equal bands over the call's band; range bins `bin_m`
    wide between `min_range_m` and `max_range_m`.

    noise_unit (B, R): the mean energy per bin of white noise of unit variance per
    sample; noise_dof (B, R): the independent complex samples that noise has in a bin
    (its energy is a chi-square of ``2 noise_dof`` degrees of freedom).
    """

    def __init__(
        self,
        recording: P.Recording,
        *,
        bands: int = 1,
        directions: Directions = Directions(),
        min_range_m: float = 0.5,
        max_range_m: float | None = None,
        bin_m: float = 0.1,
    ) -> None:
        fs, T = recording.sample_rate_hz, recording.n_samples
        c = recording.speed_of_sound_m_s
        call = recording.waveform.sampled(fs)
        self.n = n = sfft.next_fast_len(T + call.size, real=True)
        self.n_mics = recording.array.n_mics
        freqs = np.arange(n // 2 + 1) * fs / n
        lo, hi = min(recording.waveform.band_hz), max(recording.waveform.band_hz)
        edges = np.linspace(lo, hi, int(bands) + 1)
        self.band_hz = 0.5 * (edges[1:] + edges[:-1])
        self.band_bins = [
            np.flatnonzero((freqs >= a) & (freqs < b if i < bands - 1 else freqs <= b))
            for i, (a, b) in enumerate(zip(edges[:-1], edges[1:]))
        ]
        if min(b.size for b in self.band_bins) < 4:
            raise InputError("too many bands for the recording's length", key="bands", value=bands)
        # each band tapered (Tukey, half its width in the ramps): a hard band edge
        # would ring in time, as 1/t, and leak the direct path across the gate
        self._taper = [windows.tukey(b.size, TAPER).astype(np.complex64) for b in self.band_bins]
        self.n2 = sfft.next_fast_len(int(np.ceil(BASEBAND_MARGIN * max(map(len, self.band_bins)))))
        self.call_spectrum = np.conj(sfft.rfft(call, n))
        used = np.concatenate(self.band_bins)
        self._used = used
        pos = recording.array.positions_m
        u = directions.units()
        self.directions = directions
        # steering (D, M, K) over the bands' bins, 1/M included
        phase = (-2j * np.pi / c) * np.einsum("k,dm->dmk", freqs[used], u @ pos.T)
        self._steer = (np.exp(phase) / pos.shape[0]).astype(np.complex64)
        # envelope sample i2 is at sample i2 n / n2 of the full rate
        t = (np.arange(self.n2) * n / self.n2 - recording.emission_index) / fs
        r = c * t / 2
        if max_range_m is None:
            max_range_m = float(r[r < T / fs * c / 2].max())
        which, counts = self._range_bins(r, min_range_m, max_range_m, bin_m)
        self.range_m = min_range_m + (which[self.bin_starts] + 0.5) * bin_m
        self.bin_samples = counts
        # noise energy per range bin for white noise of unit variance per sample
        spectra = [
            np.abs(self.call_spectrum[b] * w) ** 2 for b, w in zip(self.band_bins, self._taper)
        ]
        power = np.array([np.sum(p) for p in spectra])
        self.noise_unit = np.outer(power * n / (self.n_mics * self.n2**2), counts)  # (B, R)
        self.noise_dof = np.array([_independent_samples(p, self.n2, counts) for p in spectra])

    def _range_bins(self, r: np.ndarray, lo: float, hi: float, bin_m: float):
        """Sets the gate and the bins' first samples from the envelope samples'
        ranges `r`; returns each gated sample's bin index and the bins' sizes."""
        if not 0 <= lo < hi:
            raise InputError(f"must be below max_range_m={hi:g}", key="min_range_m", value=lo)
        inside = np.flatnonzero((r >= lo) & (r < hi))
        self.gate = slice(int(inside[0]), int(inside[-1]) + 1)
        which = np.floor((r[self.gate] - lo) / bin_m).astype(int)
        counts = np.bincount(which - which[0])
        if counts.size > 1 and counts[-1] < counts[0]:  # a partial last bin: dropped
            self.gate = slice(self.gate.start, self.gate.stop - int(counts[-1]))
            which = which[: which.size - int(counts[-1])]
        self.bin_starts = np.flatnonzero(np.diff(which, prepend=-1))
        counts = np.diff(np.append(self.bin_starts, which.size))
        if counts.min() < 2:
            step = (r[1] - r[0]) * 100
            raise InputError(
                f"range bins hold fewer than 2 envelope samples (one every {step:.2f} cm); "
                "widen them",
                key="bin_m",
                value=bin_m,
            )
        return which, counts

    @property
    def shape(self) -> tuple[int, int, int]:
        """(B, D, R)."""
        return (len(self.band_bins), self._steer.shape[0], self.bin_starts.size)

    def envelopes(self, x: np.ndarray) -> np.ndarray:
        """(..., M, T) signals -> (..., B, D, T') complex64 envelopes in the gate."""
        X = sfft.rfft(x, self.n, axis=-1, workers=2)[..., self._used]
        X *= self.call_spectrum[self._used]
        Y = np.einsum("...mk,dmk->...dk", X.astype(np.complex64), self._steer)
        out = []
        start = 0
        for bins, taper in zip(self.band_bins, self._taper):
            buf = np.zeros((*Y.shape[:-1], self.n2), np.complex64)
            buf[..., : bins.size] = Y[..., start : start + bins.size] * taper
            start += bins.size
            out.append(sfft.ifft(buf, axis=-1, workers=2)[..., self.gate])
        return np.stack(out, axis=-3)

    def energies(self, y: np.ndarray) -> np.ndarray:
        """(..., B, D, T') envelopes -> (..., B, D, R) energies per range bin."""
        return np.add.reduceat(np.abs(y) ** 2, self.bin_starts, axis=-1)

    def bin_sums(self, v: np.ndarray) -> np.ndarray:
        """Sums of (..., T') over the range bins: (..., R)."""
        return np.add.reduceat(v, self.bin_starts, axis=-1)


def _independent_samples(power: np.ndarray, n2: int, lengths: np.ndarray) -> np.ndarray:
    """The independent complex samples (R,) that Gaussian noise of power spectrum
    `power` (its band's bins, at baseband on `n2` points) has in bins of `lengths`
    envelope samples: ``mean(E)^2 / var(E)`` of the bin's energy E, which for
    circular Gaussian noise is ``L^2 / sum_(|k| < L) (L - |k|) |rho_k|^2`` (rho
    the envelope's correlation from one sample to the next k, the inverse transform
    of the power spectrum)."""
    buf = np.zeros(n2)
    buf[: power.size] = power
    rho = np.abs(sfft.ifft(buf)) ** 2
    rho /= rho[0]
    out = []
    for L in lengths:
        k = np.arange(1, min(int(L), n2))
        out.append(L**2 / (L + 2 * np.sum((L - k) * rho[k])))
    return np.array(out)
