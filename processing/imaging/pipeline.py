"""The whole processing flow of the paper's Fig. 1, from a Recording to Images.

Narrowband (the paper): recording -> matched filter -> STFT snapshot (kept range
bins) -> DOA -> Image.  Wideband (``*-wb``): the same kept range bins, every STFT bin
of the band (:mod:`processing.imaging.wideband`).  Broadband (``*-bb``): a time-domain
energyscape on the grid's directions (:mod:`processing.imaging.broadband.energyscape`).

Every method name is one of :data:`METHODS` (the :data:`Method` literal), checked in
one place, :func:`check_method`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from processing.base.errors import InputError
from processing.base.settings import setting, settings_of, validate
from processing.imaging.broadband.energyscape import BroadbandSettings, Directions, energyscape
from processing.imaging.doa import SUBSPACE_DEFAULTS, SubspaceOptions, doa_spectra
from processing.imaging.image import Image
from processing.imaging.matched_filter import matched_filter
from processing.imaging.methods import (
    METHODS,
    BroadbandMethod,
    Method,
    WidebandMethod,
    check_method,
    parse_method,
    requires_ura,
)
from processing.imaging.snapshot import (
    ENERGY_FRACTION,
    RANGE_LIMITS_M,
    BinGate,
    Snapshot,
    Stft,
    stft_snapshot,
)
from processing.imaging.steering import FREQUENCY_HZ, Grid
from processing.imaging.wideband import band_frequencies, band_snapshots, wideband_spectrum
from processing.sensor.recording import Recording

__all__ = [
    "find_echo",
    "Method",
    "METHODS",
    "check_method",
    "parse_method",
    "requires_ura",
    "ProcessingSettings",
    "recording_snapshot",
    "acoustic_images",
    "acoustic_image",
    "estimate_memory_bytes",
    "front_end_bytes",
    "check_memory",
]

#: Default limit on the memory one imaging call may allocate (bytes); override with
#: ``ProcessingSettings(memory_limit_bytes=...)``.
MEMORY_LIMIT_BYTES = 4 * 2**30
#: the default range considered (m): from beyond the emitter-to-microphone crosstalk


@dataclass(frozen=True)
class ProcessingSettings:
    """Parameters of the flow.

    window, overlap : STFT window and overlap in samples.
    frequency_hz : steering frequency (None: the STFT bin of highest energy within the
        call's band and below the array's alias-free limit, see ``Array.alias_free_hz``;
        one set above that limit on a URA images grating lobes and warns,
        :class:`processing.GratingLobeWarning`).
    energy_fraction : range-bin energy gate relative to the strongest bin (default
        1e-3: a room has echoes far weaker than the strongest; the paper's single
        reflector used 0.5).
    range_limits_m : (min, max) range considered, or None for all (default: from
        0.25 m, beyond the emitter-to-microphone crosstalk).

    These defaults are the command line's too (``acousim image`` reads them from
    here): one declaration.
    max_bins : keep at most this many range bins (the strongest).
    grid : the directions imaged (default :meth:`Grid.degrees`: azimuth -90..90 and
        elevation -40..40 degrees every 2 degrees, the command line's).
    range_step_m : range bins every this many metres from ``range_limits_m[0]``, the
        same in any air (None, the default: one bin per STFT hop, c hop / (2 fs), which
        follows the speed of sound); up to ``range_limits_m[1]`` or the recording's end.
    subarray : smoothing subarray (None: 5/8 of each dimension).
    loading : Capon load in units of the noise floor.
    eig_floor : Capon's white-noise floor under the eigenvalues, a fraction of the
        mean eigenvalue (default 1e-3, ``processing.imaging.doa.EIG_FLOOR``).
    n_sources : MUSIC signal subspace size (None: the mean-eigenvalue rule).
    broadband : settings of the ``-bb`` methods (their range limits default to
        `range_limits_m` when that is given).
    max_freqs : frequencies of the ``-wb`` methods.
    memory_limit_bytes : refuse a job estimated to need more (see
        :func:`estimate_memory_bytes`).
    """

    window: int = setting(256, "samples", 2, 1 << 20, "STFT window")
    overlap: int = setting(240, "samples", 0, 1 << 20, "STFT overlap (below the window)")
    frequency_hz: float | None = setting(
        None,
        FREQUENCY_HZ.unit,
        FREQUENCY_HZ.lo,
        FREQUENCY_HZ.hi,
        "steering frequency; None: the strongest bin",
        kind="float",
    )
    energy_fraction: float = setting(
        ENERGY_FRACTION,
        "",
        0,
        1,
        "keep range bins with at least this fraction of the strongest's energy",
    )
    #: (min, max) m, max may be inf; None: all (checked in __post_init__)
    range_limits_m: tuple[float, float] | None = RANGE_LIMITS_M
    max_bins: int | None = setting(None, "", 1, 1 << 30, "keep the strongest bins", kind="int")
    subarray: tuple[int, int] | None = setting(
        None,
        "",
        1,
        1 << 10,
        "smoothing subarray (rows, columns); None: 5/8 of each dimension",
        kind="vector",
        length=2,
    )
    loading: float = setting(
        SUBSPACE_DEFAULTS.loading, "", -1e6, 1e6, "Capon load (noise floor units)"
    )
    n_sources: int | None = setting(None, "", 1, 1 << 20, "MUSIC subspace size", kind="int")
    eig_floor: float = field(  # SubspaceOptions' declaration: one home
        default=SUBSPACE_DEFAULTS.eig_floor,
        metadata={"setting": settings_of(SubspaceOptions)["eig_floor"]},
    )
    grid: Grid = field(default_factory=Grid.degrees)  # the command line's grid
    broadband: BroadbandSettings = field(default_factory=BroadbandSettings)
    max_freqs: int = setting(12, "", 1, 1 << 16, "frequencies of the -wb methods")
    memory_limit_bytes: float = setting(
        float(MEMORY_LIMIT_BYTES), "B", 0, float("inf"), "refuse a larger imaging job"
    )
    range_step_m: float | None = setting(
        None, "m", 1e-6, 1e3, "range-bin spacing; None: one per STFT hop", kind="float"
    )

    @property
    def subspace(self) -> SubspaceOptions:
        """The covariance methods' options of these settings."""
        return SubspaceOptions(self.subarray, self.loading, self.n_sources, self.eig_floor)

    def __post_init__(self) -> None:
        validate(self)
        subarray = whole_subarray(self.subarray, "ProcessingSettings.subarray")
        object.__setattr__(self, "subarray", subarray)
        if self.overlap >= self.window:
            raise InputError(
                "must be below the window", key="ProcessingSettings.overlap", value=self.overlap
            )
        limits = self.range_limits_m
        if limits is not None:
            try:
                lo, hi = (float(x) for x in limits)
            except (TypeError, ValueError):
                lo = hi = float("nan")
            if not 0 <= lo <= hi:  # NaN fails too
                raise InputError(
                    "must be (min, max) with 0 <= min <= max (max may be inf), or None",
                    key="ProcessingSettings.range_limits_m",
                    value=limits,
                )
        if not isinstance(self.grid, Grid):
            raise InputError("must be a Grid", key="ProcessingSettings.grid", value=self.grid)
        if not isinstance(self.broadband, BroadbandSettings):
            raise InputError(
                "must be a BroadbandSettings",
                key="ProcessingSettings.broadband",
                value=self.broadband,
            )


def whole_subarray(value: tuple[float, float] | None, key: str) -> tuple[int, int] | None:
    """A subarray (rows, columns) checked by its declaration as whole numbers: ints (an
    InputError naming `key` and the value for a fraction); None stays None."""
    if value is None:
        return None
    if not all(float(v).is_integer() for v in value):
        raise InputError("must be two whole numbers (rows, columns)", key=key, value=value)
    rows, cols = (int(v) for v in value)
    return rows, cols


def recording_snapshot(recording: Recording, settings: ProcessingSettings) -> Snapshot:
    """Matched filter and STFT snapshot of a recording (all its measurements); an
    InputError, before allocating, when they would need more than
    ``settings.memory_limit_bytes``."""
    _check_memory(recording, [], settings)
    template = recording.waveform.sampled(recording.sample_rate_hz)
    mf = matched_filter(recording.samples, template)
    return stft_snapshot(
        mf,
        recording.sample_rate_hz,
        speed_of_sound_m_s=recording.speed_of_sound_m_s,
        emission_index=recording.emission_index,
        stft=Stft(settings.window, settings.overlap, range_step_m=settings.range_step_m),
        frequency_hz=settings.frequency_hz,
        band_hz=_search_band(recording),
        gate=BinGate(settings.energy_fraction, settings.range_limits_m, settings.max_bins),
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

    Every job first samples the call and matched-filters the recording
    (:func:`front_end_bytes`); then narrowband: the image and two temporaries of its
    size (R x E x A float64) plus the steering tables (E x A x (M + 2 sqrt(M)));
    broadband: the output (R x G) and one chunk of aligned channels (chunk x M x N
    complex, three times). `n_bins` is the number of kept range bins when known
    (else every STFT frame).
    """
    E, A = settings.grid.shape
    G = E * A
    M = recording.array.n_mics
    K = recording.n_measurements
    T = recording.n_samples
    hop = max(1, settings.window - settings.overlap)
    R = n_bins if n_bins is not None else T // hop
    total = front_end_bytes(recording, settings)
    for m in methods:
        if parse_method(m).family == "broadband":
            bb = settings.broadband
            lo, hi = recording.waveform.band_hz
            N = int(bb.oversample * (hi - lo) * (T / recording.sample_rate_hz + 0.01)) + 1
            r_out = N // int(bb.decimation) + 1
            total = max(total, r_out * G * 8 + 3 * 16 * K * min(G, bb.chunk) * M * N)
        else:
            total = max(total, 3 * R * G * 8 + G * (M + 2 * int(np.sqrt(M)) + 2) * 16)
    return int(total)


def front_end_bytes(recording: Recording, settings: ProcessingSettings) -> int:
    """Bytes of the stages every method shares, at their peak: the sampled call
    (L = duration x rate samples, a few float64 temporaries of its length), the
    matched filter (K x M channels on an FFT of T + L points: the input, its
    spectrum and the product, the output) and the STFT snapshot (the B bins of the
    band searched for the strongest, real and imaginary parts of K x M x P frames,
    then the kept bin's real and imaginary parts and their complex sum); within 1.5
    times the peak numpy allocates (tests/system/test_reliability.py)."""
    w = recording.waveform
    K, M, T = recording.n_measurements, recording.array.n_mics, recording.n_samples
    L = float(w.duration_s) * float(recording.sample_rate_hz)  # float: never overflows
    n = T + L
    template = 8.0 * 8 * L
    mf = float(K * M) * (8 * T + 2 * 16 * (n / 2 + 1) + 8 * n)
    hop = max(1, settings.window - settings.overlap)
    P = max(0, (T - settings.window) // hop + 1)
    freqs = np.fft.rfftfreq(settings.window, 1 / recording.sample_rate_hz)
    lo, hi = _search_band(recording)
    B = 0 if settings.frequency_hz is not None else int(((freqs >= lo) & (freqs <= hi)).sum())
    # the band's bins of every candidate frame (real, imaginary), then the kept bin's
    frames = K * M * P * (16 * max(B, 1) + 32)
    snapshot = K * M * T * 8 + frames
    return int(min(template + max(mf, snapshot), 2.0**62))


def check_memory(
    recording: Recording,
    methods: Sequence[str] = (),
    settings: ProcessingSettings | None = None,
    n_bins: int | None = None,
) -> None:
    """An InputError, before anything is allocated, when imaging `recording` by
    `methods` (none: the matched filter and snapshots only) would need more than
    ``settings.memory_limit_bytes`` (see :func:`estimate_memory_bytes`)."""
    _check_memory(recording, list(methods), settings or ProcessingSettings(), n_bins)


def _check_memory(recording, methods, settings, n_bins=None) -> None:
    need = estimate_memory_bytes(recording, methods, settings, n_bins)
    if need > settings.memory_limit_bytes:
        front = front_end_bytes(recording, settings)
        if front > settings.memory_limit_bytes:
            w = recording.waveform
            raise InputError(
                f"imaging would need about {front / 2**30:.1f} GiB for the matched filter "
                f"and snapshots alone ({recording.n_samples} samples of "
                f"{recording.array.n_mics} microphones, a {w.duration_s:g} s call at "
                f"{recording.sample_rate_hz:g} Hz), above the limit of "
                f"{settings.memory_limit_bytes / 2**30:.1f} GiB "
                "(ProcessingSettings(memory_limit_bytes=...))",
                key="sample_rate_hz, waveform.duration_s",
                value=(recording.sample_rate_hz, w.duration_s),
            )
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
        lo, hi = settings.range_limits_m
        bb = replace(bb, range_limits_m=(lo, min(hi, _end_range(recording))))
    grid = settings.grid
    # (a name check_method has checked: one of the broadband methods)
    es = energyscape(recording, Directions.from_grid(grid), cast(BroadbandMethod, method), bb)
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


def _end_range(recording: Recording) -> float:
    """The range (m) the recording's last sample reaches: ``c (T - emission_index) /
    (2 fs)``."""
    t_end = (recording.n_samples - recording.emission_index) / recording.sample_rate_hz
    return recording.speed_of_sound_m_s * t_end / 2


def _check_reaches(recording: Recording, settings: ProcessingSettings) -> None:
    """An InputError, with both numbers, when the recording ends before the minimum of
    ``settings.range_limits_m``: no range bin could be imaged, by any method."""
    if settings.range_limits_m is None:
        return
    lo, end = settings.range_limits_m[0], _end_range(recording)
    if end <= lo:
        raise InputError(
            f"the recording is too short for the range limits: its "
            f"{recording.n_samples} samples (emission at sample "
            f"{recording.emission_index}, {recording.sample_rate_hz:g} Hz) reach "
            f"{end:.4g} m, not beyond the minimum range {lo:g} m",
            key="ProcessingSettings.range_limits_m",
            value=settings.range_limits_m,
        )


def _band_snapshots(recording: Recording, settings: ProcessingSettings, snap: Snapshot):
    """The frequencies (F,) of the ``-wb`` methods and the snapshots (F, M, R, K) of
    the kept range bins of `snap` at each."""
    freqs = band_frequencies(
        _search_band(recording), recording.sample_rate_hz, settings.window, settings.max_freqs
    )
    mf = matched_filter(recording.samples, recording.waveform.sampled(recording.sample_rate_hz))
    xb = band_snapshots(
        mf, recording.sample_rate_hz, recording.emission_index, snap.time_s, settings.window, freqs
    )
    return freqs, xb


def acoustic_images(
    recording: Recording,
    methods: Sequence[str] = ("das",),
    settings: ProcessingSettings | None = None,
    *,
    snapshot: Snapshot | None = None,
) -> dict[str, Image]:
    """Images of one recording by several methods (any of :data:`METHODS`), sharing
    the matched filter and STFT.  Raises InputError for an unknown method, an array
    of fewer than 2 microphones, a recording that ends before the minimum range
    (``settings.range_limits_m``) or a job above ``settings.memory_limit_bytes``."""
    settings = settings or ProcessingSettings()
    family = {m: parse_method(m).family for m in methods}
    recording.array.require_mics("imaging")
    broadband = [m for m in methods if family[m] == "broadband"]
    _check_memory(recording, broadband, settings)
    _check_reaches(recording, settings)
    out = {m: _broadband_image(recording, m, settings) for m in broadband}
    rest = [m for m in methods if family[m] != "broadband"]
    if not rest:
        return {m: out[m] for m in methods}
    snap = snapshot if snapshot is not None else recording_snapshot(recording, settings)
    _check_memory(recording, rest, settings, snap.n_bins)
    grid = settings.grid
    freqs = None
    spectra = _narrowband(recording, snap, settings, [m for m in rest if family[m] == "narrowband"])
    for method in rest:
        if snap.n_bins == 0:
            power = np.zeros((0, *grid.shape))
        elif family[method] == "wideband":
            if freqs is None:
                freqs, xb = _band_snapshots(recording, settings, snap)
            power = wideband_spectrum(
                xb,
                recording.array,
                freqs,
                grid,
                cast(WidebandMethod, method),  # checked: one of the wideband methods
                speed_of_sound_m_s=recording.speed_of_sound_m_s,
                options=settings.subspace,
            )
        else:
            power = spectra[method]
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


def _narrowband(recording: Recording, snap: Snapshot, settings, methods: list[str]) -> dict:
    """The narrowband `methods`' spectra of the snapshots, together (what they share
    is made once: :func:`processing.imaging.doa.doa_spectra`); none without bins."""
    if not methods or not snap.n_bins:
        return {}
    return doa_spectra(
        snap.data,
        recording.array,
        snap.frequency_hz,
        settings.grid,
        methods,
        speed_of_sound_m_s=recording.speed_of_sound_m_s,
        options=settings.subspace,
    )


def acoustic_image(
    recording: Recording, method: Method = "das", settings: ProcessingSettings | None = None
) -> Image:
    """The image of one recording by one method."""
    return acoustic_images(recording, [method], settings)[method]


def find_echo(recording: Recording, min_range_m: float, max_range_m: float) -> np.ndarray:
    """The position (3,) in the sensor frame of the strongest peak of the recording's
    DAS image between `min_range_m` and `max_range_m`."""
    img = acoustic_image(
        recording, "das", ProcessingSettings(range_limits_m=(min_range_m, max_range_m))
    )
    peaks = img.peaks(-60.0, max_peaks=1)
    if len(peaks) == 0:
        raise InputError(
            "no echo in the range window", key="range_m", value=[min_range_m, max_range_m]
        )
    az, el, r = peaks.azimuth_rad[0], peaks.elevation_rad[0], peaks.range_m[0]
    return r * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
