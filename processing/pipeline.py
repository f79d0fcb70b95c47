"""The whole processing flow of the paper's Fig. 1, from a Recording to Images.

recording -> matched filter -> STFT snapshot (kept range bins) -> DOA -> Image
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .doa import doa_spectrum
from .image import Image
from .matched_filter import matched_filter
from .recording import Recording
from .snapshot import Snapshot, stft_snapshot
from .steering import Grid

__all__ = ["ProcessingSettings", "recording_snapshot", "acoustic_images", "acoustic_image"]


@dataclass(frozen=True)
class ProcessingSettings:
    """Parameters of the flow; defaults are the paper's.

    window, overlap : STFT window and overlap in samples.
    frequency_hz : steering frequency (None: the STFT bin of highest energy within the
        call's band and below the array's alias-free limit, see ``Array.alias_free_hz``).
    energy_fraction : range-bin energy gate relative to the strongest bin.
    range_limits_m : (min, max) range considered, or None for all.
    max_bins : keep at most this many range bins (the strongest).
    subarray : smoothing subarray (None: 5/8 of each dimension).
    loading : Capon load in units of the noise floor.
    n_sources : MUSIC signal subspace size (None: the mean-eigenvalue rule).
    """

    window: int = 256
    overlap: int = 240
    frequency_hz: float | None = None
    energy_fraction: float = 0.5
    range_limits_m: tuple[float, float] | None = None
    max_bins: int | None = None
    subarray: tuple[int, int] | None = None
    loading: float = -0.5
    n_sources: int | None = None
    grid: Grid = field(default_factory=lambda: Grid.degrees(step=2.0))


def recording_snapshot(recording: Recording, settings: ProcessingSettings) -> Snapshot:
    """Matched filter and STFT snapshot of a recording (all its measurements)."""
    template = recording.waveform.sampled(recording.sample_rate_hz)
    mf = matched_filter(recording.samples, template)
    return stft_snapshot(
        mf,
        recording.sample_rate_hz,
        speed_of_sound_m_s=recording.speed_of_sound_m_s,
        emission_index=recording.emission_index,
        window=settings.window,
        overlap=settings.overlap,
        frequency_hz=settings.frequency_hz,
        band_hz=_search_band(recording),
        energy_fraction=settings.energy_fraction,
        range_limits_m=settings.range_limits_m,
        max_bins=settings.max_bins,
    )


def _search_band(recording: Recording) -> tuple[float, float]:
    lo, hi = recording.waveform.band_hz
    limit = recording.array.alias_free_hz(recording.speed_of_sound_m_s)
    return lo, max(lo, min(hi, limit))


def acoustic_images(
    recording: Recording,
    methods: Sequence[str] = ("das",),
    settings: ProcessingSettings | None = None,
    *,
    snapshot: Snapshot | None = None,
) -> dict[str, Image]:
    """Images of one recording by several methods, sharing the matched filter and STFT."""
    settings = settings or ProcessingSettings()
    snap = snapshot if snapshot is not None else recording_snapshot(recording, settings)
    grid = settings.grid
    out = {}
    for method in methods:
        if snap.n_bins == 0:
            power = np.zeros((0, *grid.shape))
        else:
            power = doa_spectrum(
                snap.data,
                recording.array,
                snap.frequency_hz,
                grid,
                method,
                speed_of_sound_m_s=recording.speed_of_sound_m_s,
                subarray=settings.subarray,
                loading=settings.loading,
                n_sources=settings.n_sources,
            )
        out[method] = Image(
            power=power,
            range_m=snap.range_m,
            elevation_rad=grid.elevation_rad,
            azimuth_rad=grid.azimuth_rad,
            method=method,
            frequency_hz=snap.frequency_hz,
            bin_range_m=snap.bin_range_m,
        )
    return out


def acoustic_image(
    recording: Recording, method: str = "das", settings: ProcessingSettings | None = None
) -> Image:
    """The image of one recording by one method."""
    return acoustic_images(recording, [method], settings)[method]
