"""The whole processing flow of the paper's Fig. 1, from a Recording to Images.

Narrowband (the paper): recording -> matched filter -> STFT snapshot (kept range
bins) -> DOA -> Image.  Wideband (``*-wb``): the same kept range bins, every STFT bin
of the band (:mod:`processing.wideband`).  Broadband (``*-bb``): a time-domain
energyscape on the grid's directions (:mod:`processing.broadband`).

Every method name is one of :data:`METHODS` (the :data:`Method` literal), checked in
one place, :func:`check_method`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal, get_args

import numpy as np

from .broadband import BroadbandMethod, BroadbandSettings, Directions, energyscape
from .doa import NarrowbandMethod, doa_spectrum
from .errors import InputError, unknown_choice
from .image import Image
from .matched_filter import matched_filter
from .recording import Recording
from .snapshot import Snapshot, stft_snapshot
from .steering import Grid
from .wideband import WidebandMethod, band_frequencies, band_snapshots, wideband_spectrum

__all__ = [
    "Method",
    "METHODS",
    "check_method",
    "requires_ura",
    "ProcessingSettings",
    "recording_snapshot",
    "acoustic_images",
    "acoustic_image",
    "estimate_memory_bytes",
]

Method = Literal[NarrowbandMethod, WidebandMethod, BroadbandMethod]
#: Every imaging method: narrowband (processing.doa), wideband (``-wb``), broadband
#: (``-bb``).  Callers (command line, dataset specs) check names against this tuple.
METHODS: tuple[str, ...] = get_args(Method)  # nested Literals flatten

#: Default limit on the memory one imaging call may allocate (bytes); override with
#: ``ProcessingSettings(memory_limit_bytes=...)``.
MEMORY_LIMIT_BYTES = 4 * 2**30


def requires_ura(method: str) -> bool:
    """True for the spatially smoothed methods (``-fss``, ``-fbss``), which need a URA."""
    return "-fss" in check_method(method) or "-fbss" in method


def check_method(name: str) -> Method:
    """`name` when it is one of :data:`METHODS`, else an InputError naming it."""
    if name not in METHODS:
        raise InputError(
            unknown_choice("method", name, METHODS) + " (all: processing.METHODS)",
            key="method",
            value=name,
        )
    return name  # type: ignore[return-value]


@dataclass(frozen=True)
class ProcessingSettings:
    """Parameters of the flow.

    window, overlap : STFT window and overlap in samples.
    frequency_hz : steering frequency (None: the STFT bin of highest energy within the
        call's band and below the array's alias-free limit, see ``Array.alias_free_hz``).
    energy_fraction : range-bin energy gate relative to the strongest bin (default
        1e-3: a room has echoes far weaker than the strongest; the paper's single
        reflector used 0.5).
    range_limits_m : (min, max) range considered, or None for all (default: from
        0.25 m, beyond the emitter-to-microphone crosstalk).

    These defaults are the command line's too (``acousim image`` reads them from
    here): one declaration.
    max_bins : keep at most this many range bins (the strongest).
    subarray : smoothing subarray (None: 5/8 of each dimension).
    loading : Capon load in units of the noise floor.
    n_sources : MUSIC signal subspace size (None: the mean-eigenvalue rule).
    broadband : settings of the ``-bb`` methods (their range limits default to
        `range_limits_m` when that is given).
    max_freqs : frequencies of the ``-wb`` methods.
    memory_limit_bytes : refuse a job estimated to need more (see
        :func:`estimate_memory_bytes`).
    """

    window: int = 256
    overlap: int = 240
    frequency_hz: float | None = None
    energy_fraction: float = 1e-3
    range_limits_m: tuple[float, float] | None = (0.25, float("inf"))
    max_bins: int | None = None
    subarray: tuple[int, int] | None = None
    loading: float = -0.5
    n_sources: int | None = None
    grid: Grid = field(default_factory=lambda: Grid.degrees(step=2.0))
    broadband: BroadbandSettings = field(default_factory=BroadbandSettings)
    max_freqs: int = 12
    memory_limit_bytes: float = MEMORY_LIMIT_BYTES


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


def estimate_memory_bytes(
    recording: Recording,
    methods: Sequence[str],
    settings: ProcessingSettings,
    n_bins: int | None = None,
) -> int:
    """Bytes an imaging job needs at its peak (an estimate, before allocating).

    Narrowband: the image and two temporaries of its size (R x E x A float64) plus
    the steering tables (E x A x (M + 2 sqrt(M))); broadband: the output (R x G)
    and one chunk of aligned channels (chunk x M x N complex, three times).
    `n_bins` is the number of kept range bins when known (else every STFT frame).
    """
    E, A = settings.grid.shape
    G = E * A
    M = recording.array.n_mics
    K = recording.n_measurements
    T = recording.n_samples
    hop = max(1, settings.window - settings.overlap)
    R = n_bins if n_bins is not None else T // hop
    total = 0
    for m in methods:
        if m.endswith("-bb"):
            bb = settings.broadband
            lo, hi = recording.waveform.band_hz
            N = int(bb.oversample * (hi - lo) * (T / recording.sample_rate_hz + 0.01)) + 1
            r_out = N // int(bb.decimation) + 1
            total = max(total, r_out * G * 8 + 3 * 16 * K * min(G, bb.chunk) * M * N)
        else:
            total = max(total, 3 * R * G * 8 + G * (M + 2 * int(np.sqrt(M)) + 2) * 16)
    return int(total)


def _check_memory(recording, methods, settings, n_bins=None) -> None:
    need = estimate_memory_bytes(recording, methods, settings, n_bins)
    if need > settings.memory_limit_bytes:
        raise InputError(
            f"imaging would need about {need / 2**30:.1f} GiB, above the limit of "
            f"{settings.memory_limit_bytes / 2**30:.1f} GiB (a coarser grid step, fewer "
            "range bins, or ProcessingSettings(memory_limit_bytes=...))",
            key="grid",
            value=f"{settings.grid.shape[0]} x {settings.grid.shape[1]} directions",
        )


def _broadband_image(recording: Recording, method: str, settings: ProcessingSettings) -> Image:
    bb = settings.broadband
    if settings.range_limits_m is not None:
        t_end = (recording.n_samples - recording.emission_index) / recording.sample_rate_hz
        lo, hi = settings.range_limits_m
        hi = min(hi, recording.speed_of_sound_m_s * t_end / 2)
        bb = replace(bb, range_limits_m=(lo, hi))
    grid = settings.grid
    es = energyscape(recording, Directions.from_grid(grid), method, bb)
    lo, hi = recording.waveform.band_hz
    return Image(
        power=es.to_grid(),
        range_m=es.range_m,
        elevation_rad=grid.elevation_rad,
        azimuth_rad=grid.azimuth_rad,
        method=method,
        frequency_hz=0.5 * (lo + hi),
        bin_range_m=es.bin_range_m,
    )


def acoustic_images(
    recording: Recording,
    methods: Sequence[str] = ("das",),
    settings: ProcessingSettings | None = None,
    *,
    snapshot: Snapshot | None = None,
) -> dict[str, Image]:
    """Images of one recording by several methods (any of :data:`METHODS`), sharing
    the matched filter and STFT.  Raises InputError for an unknown method or a job
    above ``settings.memory_limit_bytes``."""
    settings = settings or ProcessingSettings()
    methods = [check_method(m) for m in methods]
    _check_memory(recording, [m for m in methods if m.endswith("-bb")], settings)
    out = {m: _broadband_image(recording, m, settings) for m in methods if m.endswith("-bb")}
    rest = [m for m in methods if not m.endswith("-bb")]
    if not rest:
        return {m: out[m] for m in methods}
    snap = snapshot if snapshot is not None else recording_snapshot(recording, settings)
    _check_memory(recording, rest, settings, snap.n_bins)
    grid = settings.grid
    freqs = mf = None
    for method in rest:
        if snap.n_bins == 0:
            power = np.zeros((0, *grid.shape))
        elif method.endswith("-wb"):
            if freqs is None:
                freqs = band_frequencies(
                    _search_band(recording),
                    recording.sample_rate_hz,
                    settings.window,
                    settings.max_freqs,
                )
                mf = matched_filter(
                    recording.samples, recording.waveform.sampled(recording.sample_rate_hz)
                )
                xb = band_snapshots(
                    mf,
                    recording.sample_rate_hz,
                    recording.emission_index,
                    snap.time_s,
                    settings.window,
                    freqs,
                )
            power = wideband_spectrum(
                xb,
                recording.array,
                freqs,
                grid,
                method,
                speed_of_sound_m_s=recording.speed_of_sound_m_s,
                subarray=settings.subarray,
                loading=settings.loading,
                n_sources=settings.n_sources,
            )
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
    return {m: out[m] for m in methods}


def acoustic_image(
    recording: Recording, method: Method = "das", settings: ProcessingSettings | None = None
) -> Image:
    """The image of one recording by one method."""
    return acoustic_images(recording, [method], settings)[method]
