"""Section IV of the paper: every experiment, its CSV and its figure.

``run_study(StudyConfig(...), out_dir)`` runs Figs. 3-4, 6-7, 9-10, 11 and 12 and
returns their statistics (:class:`StudyResults`, small frozen dataclasses whose field
names are the CSV columns); :mod:`acousim.experiments.report` turns them into
``docs/REPRODUCTION.md``.  Readings of the paper fixed here (and stated in the
report): SNR as in :mod:`acousim.synth.noise`; spreading 1/(2 r) as in eq. 1; the
steering frequency 31.25 kHz the paper states; 5x5 subarrays; Capon loading -0.5
times the noise floor; resolution metrics as in :mod:`processing.imaging.metrics`.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, fields
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

import processing as P
from acousim.experiments.trials import (
    FREQUENCY_HZ,
    FS,
    PAPER_ARRAY,
    PAPER_METHODS,
    C,
    Trial,
    azimuth_cut_trial,
    resolution_trial,
    simulate_trial,
)
from processing.base import interrupt
from processing.base.atomic import atomic_path, write_text
from processing.base.errors import InputError
from processing.base.settings import setting, validate
from processing.imaging.steering import FREQUENCY_HZ as STEERING

POSITIONS = ((0.0, 0.0, 1.0), (30.0, 30.0, 1.0), (60.0, 60.0, 1.0))


@dataclass(frozen=True)
class StudyConfig:
    """Parameters of the study; the defaults are the paper's.

    array : the simulated array, a name of ``processing.PRESETS`` (the paper's 8x8
        URA; ``urtis_v1`` is the μRTIS).
    methods : the DOA methods compared (names of ``processing.METHODS``); the report
        (:mod:`acousim.experiments.report`) needs the paper's five.
    sample_rate_hz : of the simulated recordings (Hz; 8.2 ms of samples each).
    frequency_hz : the steering frequency of every image (Hz).
    """

    repetitions: int = 20
    snrs_db: tuple[float, ...] = tuple(range(-16, 21, 2))
    snapshots: tuple[int, ...] = tuple(range(1, 16))
    spacings_deg: tuple[float, ...] = tuple(range(40, 9, -2))
    grid_step_deg: float = 0.25
    cut_step_deg: float = 0.25
    seed: int = 2021
    workers: int = field(default_factory=lambda: os.cpu_count() or 1)
    array: str = setting(PAPER_ARRAY, "", doc="the simulated array", choices=tuple(P.PRESETS))
    methods: tuple[str, ...] = setting(
        PAPER_METHODS, "", doc="the DOA methods compared", kind="strings", choices=P.METHODS
    )
    sample_rate_hz: float = setting(FS, "Hz", 50e3, 10e6, "sample rate of the recordings")
    frequency_hz: float = setting(
        FREQUENCY_HZ, "Hz", STEERING.lo, STEERING.hi, "steering frequency of the images"
    )

    def __post_init__(self) -> None:
        validate(self)
        if not self.methods:
            raise InputError("give at least one method", key="StudyConfig.methods", value=())

    @classmethod
    def quick(cls, workers: int = 1, **setup: Any) -> StudyConfig:
        """A few repetitions on a coarser grid: for tests and a first look; `setup`:
        the array, methods, sample rate or steering frequency, as for the constructor."""
        return cls(
            repetitions=3,
            snrs_db=(-10.0, 0.0, 10.0, 20.0),
            snapshots=(1, 5, 15),
            spacings_deg=(40, 30, 24, 20, 16, 14, 12, 10),
            grid_step_deg=0.5,
            cut_step_deg=0.5,
            workers=workers,
            **setup,
        )


@dataclass(frozen=True)
class PulseNumbers:
    """Figs. 3-4: the matched filter's range estimate and the echo's widths (m)."""

    range_estimate_m: float
    raw_extent_m: float
    width_3db_m: float
    rayleigh_width_m: float


@dataclass(frozen=True)
class Resolution:
    """Figs. 6/7 and 9/10, one position, swept value and method: mean and standard
    deviation over the repetitions of the angular (sr) and range (m) resolution.

    `failed`: repetitions that gave no number (an empty image), left out of the
    means.  `sub_cell`: repetitions whose -3 dB lobe was narrower than one grid step,
    measured again on a fine local grid.  Both NaN when read from a CSV written
    before they were counted."""

    angular_sr_mean: float
    range_m_mean: float
    angular_sr_std: float
    range_m_std: float
    failed: float = float("nan")
    sub_cell: float = float("nan")


@dataclass(frozen=True)
class Attenuation:
    """Fig. 11, one spacing and method: maximum attenuation between the two sources (dB),
    mean and standard deviation over the repetitions."""

    attenuation_db_mean: float
    attenuation_db_std: float


@dataclass(frozen=True)
class SourceCount:
    """Fig. 12, one number of sources and method: mean number of sources resolved,
    dynamic range (dB) of the mean spectrum, and that spectrum (normalised, over
    azimuth; None when read back from the CSV)."""

    resolved_mean: float
    dynamic_range_db: float
    mean_spectrum: np.ndarray | None = field(default=None, compare=False, repr=False)


Position = tuple[float, float, float]
"""(azimuth deg, elevation deg, range m) of a reflector."""
Sweep = dict[tuple[Position, Any, str], Resolution]
"""Figs. 6/7 and 9/10: (position, swept value, method) -> Resolution."""


@dataclass(frozen=True)
class StudyResults:
    """Everything :func:`run_study` computes (and :func:`load_results` reads back)."""

    config: StudyConfig
    frequency_hz: float
    fig3_4: PulseNumbers
    fig6_7: Sweep
    fig9_10: Sweep
    fig11: dict[tuple[float, str], Attenuation]
    fig12: dict[tuple[int, str], SourceCount]


def _columns(cls: type) -> list[str]:
    """The CSV columns of a statistics dataclass: its float fields, in order."""
    return [f.name for f in fields(cls) if f.name != "mean_spectrum"]


def _read_row(cls: type, row: dict[str, str]):
    """A statistics dataclass from a CSV row (its columns named by its fields; a
    column with a default may be missing, from a CSV written before it existed)."""
    defaults = {f.name for f in fields(cls) if f.default is not dataclasses.MISSING}
    return cls(
        **{
            name: float(row[name])
            for name in _columns(cls)
            if name not in defaults or row.get(name) not in (None, "")
        }
    )


def _seed(config: StudyConfig, *key: int) -> int:
    return int(np.random.SeedSequence([config.seed, *key]).generate_state(1)[0])


def _map(config: StudyConfig, fn: Callable, items: list) -> list:
    """``[fn(i) for i in items]``, in `config.workers` processes; Ctrl-C (as the
    command line records it, :mod:`processing.base.interrupt`) is honoured between
    items, in this process (the workers ignore it)."""
    if config.workers > 1 and len(items) > 1:
        chunk = max(1, len(items) // (4 * config.workers))
        pool = ProcessPoolExecutor(config.workers, initializer=interrupt.ignore_in_worker)
        done = False
        try:
            out = []
            for result in pool.map(fn, items, chunksize=chunk):
                interrupt.check()
                out.append(result)
            done = True
            return out
        finally:  # stopped: the queued trials are dropped, not waited for
            pool.shutdown(wait=done, cancel_futures=True)
    out = []
    for i in items:
        interrupt.check()
        out.append(fn(i))
    return out


def _write_csv(path: Path, header: list[str], rows: Iterable[list]) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def _savefig(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


# -- Figs. 3 and 4 -----------------------------------------------------------------


def fig3_4(config: StudyConfig, out: Path) -> PulseNumbers:
    """Spectrogram of the received signal and the matched-filter output, (30, 30, 1 m)."""
    fs = config.sample_rate_hz
    rec = simulate_trial(Trial(((30.0, 30.0, 1.0),), 20.0, _seed(config, 3)), config)
    x = rec.samples[0]
    mf = P.matched_filter(rec.samples, rec.waveform.sampled(fs))[0]
    rng_axis = rec.time_s() * C / 2
    i = int(np.argmax(np.abs(mf)))
    # widths are properties of the call: measured on the noise-free echo
    clean = simulate_trial(Trial(((30.0, 30.0, 1.0),), np.inf, 0), config)
    widths = _pulse_widths(P.matched_filter(clean.samples, rec.waveform.sampled(fs))[0], fs)
    raw_extent = rec.waveform.duration_s * C / 2
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.specgram(x, NFFT=256, Fs=fs, noverlap=240, cmap="viridis")
    ax.set_ylim(0, 100e3)
    ax.set_xlim(0.9 * 2 / C, 1.25 * 2 / C)
    ax.set_xlabel("time after emission (s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title("Fig. 3: received signal, SNR 20 dB, (30°, 30°, 1 m)")
    _savefig(fig, out / "fig03_spectrogram.png")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    sel = (rng_axis > 0.9) & (rng_axis < 1.15)
    ax.plot(rng_axis[sel], mf[sel] / np.abs(mf).max())
    ax.axvline(rng_axis[i], color="r", lw=0.8)
    ax.set_xlabel("range (m)")
    ax.set_ylabel("normalised matched-filter output")
    ax.set_title(f"Fig. 4: maximum at {rng_axis[i]:.4f} m")
    _savefig(fig, out / "fig04_matched_filter.png")
    plt.close(fig)
    _write_csv(
        out / "fig04_matched_filter.csv",
        ["range_m", "mf_normalised"],
        zip(rng_axis[sel], mf[sel] / np.abs(mf).max()),
    )
    return PulseNumbers(float(rng_axis[i]), float(raw_extent), *widths)


def _pulse_widths(mf: np.ndarray, fs: float = FS) -> tuple[float, float]:
    """-3 dB width and Rayleigh (first-null to first-null) width of the compressed
    echo's envelope (sampled at `fs` Hz), in metres of range, from an 8x band-limited
    interpolation."""
    from scipy.signal import hilbert, resample

    up = 8
    i = int(np.argmax(np.abs(mf)))
    seg = resample(mf[max(i - 200, 0) : i + 200], 400 * up)
    env = np.abs(hilbert(seg))
    j = int(np.argmax(env))
    above = np.flatnonzero(env >= env[j] * 10 ** (-3 / 20))
    d_env = np.diff(env)
    right = j + int(np.argmax(d_env[j:] > 0))
    left = j - int(np.argmax(d_env[:j][::-1] < 0))
    to_m = C / 2 / (fs * up)
    return float((above[-1] - above[0]) * to_m), float((right - left) * to_m)


# -- Figs. 6/7 and 9/10: resolution against SNR and against snapshots ----------------


def _resolution_sweep(config: StudyConfig, values, make_trial, key: int) -> Sweep:
    trials = [
        make_trial(p, v, rep, _seed(config, key, ip, iv, rep))
        for ip, p in enumerate(POSITIONS)
        for iv, v in enumerate(values)
        for rep in range(config.repetitions)
    ]
    trial = partial(resolution_trial, step=config.grid_step_deg, setup=config)
    results = _map(config, trial, trials)
    stats = {}
    it = iter(results)
    for p in POSITIONS:
        for v in values:
            reps = [next(it) for _ in range(config.repetitions)]
            for m in config.methods:
                arr = np.array([r[m] for r in reps])  # (reps, 3): sr, m, sub-cell
                failed = np.isnan(arr[:, 0])
                if failed.all():
                    stats[p, v, m] = Resolution(*[np.nan] * 4, float(failed.sum()), 0.0)
                    continue
                ok = arr[~failed]
                (sr_mean, rng_mean), (sr_std, rng_std) = ok[:, :2].mean(0), ok[:, :2].std(0)
                stats[p, v, m] = Resolution(
                    float(sr_mean),
                    float(rng_mean),
                    float(sr_std),
                    float(rng_std),
                    float(failed.sum()),
                    float(ok[:, 2].sum()),
                )
    return stats


def _methods(stats: dict) -> list[str]:
    """The methods of a statistics table keyed (..., method), in their first order."""
    return list(dict.fromkeys(key[-1] for key in stats))


def _plot_sweep(stats: Sweep, values, xlabel, what, ylabel, title, path, log=True):
    """`what`: 'angular_sr' or 'range_m'."""
    plt = _plt()
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
    any_clipped = False
    for ax, p in zip(axes, POSITIONS):
        for m in _methods(stats):
            mean = np.array([getattr(stats[p, v, m], f"{what}_mean") for v in values])
            std = np.array([getattr(stats[p, v, m], f"{what}_std") for v in values])
            low, clipped = _lower_bars(mean, std, log)
            line = ax.errorbar(values, mean, yerr=[low, std], label=m, capsize=2, marker="o", ms=3)
            if clipped.any():  # mean - std <= 0 has no place on a log axis: say so
                colour = line.lines[0].get_color()
                ax.plot(np.asarray(values)[clipped], (mean - low)[clipped], "v", color=colour, ms=4)
                any_clipped = True
        ax.set_title(f"({p[0]:.0f}°, {p[1]:.0f}°, {p[2]:.0f} m)")
        ax.set_xlabel(xlabel)
        if log:
            ax.set_yscale("log")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(ylabel)
    axes[-1].legend(fontsize=7)
    fig.suptitle(title)
    if any_clipped:
        fig.text(
            0.5, -0.04, "bars: mean ± std over the repetitions; ▾ where mean − std ≤ 0 "
            "(no place on a log axis): the lower bar stops at a tenth of the mean",
            ha="center", va="top", fontsize=8,
        )  # fmt: skip
    _savefig(fig, path)
    plt.close(fig)


def _lower_bars(mean: np.ndarray, std: np.ndarray, log: bool) -> tuple[np.ndarray, np.ndarray]:
    """Lower error bars (V,) of `mean` ± `std` and where they are clipped (V,) bool: on
    a log axis a bar reaching zero or below stops at a tenth of the mean."""
    clipped = log & (mean - std <= 0) & (mean > 0)
    return np.where(clipped, 0.9 * mean, std), clipped


def _sweep_csv(stats: Sweep, values, name, path):
    rows = [
        [p[0], p[1], v, m, *dataclasses.astuple(stats[p, v, m])]
        for p in POSITIONS
        for v in values
        for m in _methods(stats)
    ]
    _write_csv(path, ["azimuth_deg", "elevation_deg", name, "method", *_columns(Resolution)], rows)


def fig6_7(config: StudyConfig, out: Path) -> Sweep:
    stats = _resolution_sweep(
        config, config.snrs_db, lambda p, snr, rep, seed: Trial((p,), float(snr), seed), key=6
    )
    _sweep_csv(stats, config.snrs_db, "snr_db", out / "fig06_07_resolution_vs_snr.csv")
    _plot_sweep(
        stats,
        config.snrs_db,
        "SNR (dB)",
        "angular_sr",
        "angular resolution (sr)",
        "Fig. 6: angular resolution against SNR, one snapshot",
        out / "fig06_angular_vs_snr.png",
    )
    _plot_sweep(
        stats,
        config.snrs_db,
        "SNR (dB)",
        "range_m",
        "range resolution (m)",
        "Fig. 7: range resolution against SNR",
        out / "fig07_range_vs_snr.png",
        False,
    )
    return stats


def fig9_10(config: StudyConfig, out: Path) -> Sweep:
    stats = _resolution_sweep(
        config, config.snapshots, lambda p, k, rep, seed: Trial((p,), 3.0, seed, int(k)), key=9
    )
    _sweep_csv(stats, config.snapshots, "snapshots", out / "fig09_10_resolution_vs_snapshots.csv")
    _plot_sweep(
        stats,
        config.snapshots,
        "snapshots",
        "angular_sr",
        "angular resolution (sr)",
        "Fig. 9: angular resolution against snapshots, 3 dB SNR",
        out / "fig09_angular_vs_snapshots.png",
    )
    _plot_sweep(
        stats,
        config.snapshots,
        "snapshots",
        "range_m",
        "range resolution (m)",
        "Fig. 10: range resolution against snapshots",
        out / "fig10_range_vs_snapshots.png",
        False,
    )
    return stats


# -- Figs. 11 and 12: two sources, and up to five ------------------------------------


def fig11(config: StudyConfig, out: Path) -> dict[tuple[float, str], Attenuation]:
    """Maximum attenuation between two sources against their spacing, 10 dB SNR."""
    trials = [
        Trial(((-s / 2, 0.0, 1.0), (s / 2, 0.0, 1.0)), 10.0, _seed(config, 11, i, rep))
        for i, s in enumerate(config.spacings_deg)
        for rep in range(config.repetitions)
    ]
    cuts = _map(config, _cut(config), trials)
    az = np.deg2rad(np.arange(-90, 90 + config.cut_step_deg / 2, config.cut_step_deg))
    stats = {}
    it = iter(cuts)
    for s in config.spacings_deg:
        reps = [next(it) for _ in range(config.repetitions)]
        for m in config.methods:
            att = [P.max_attenuation(r[m], az, np.deg2rad(-s / 2), np.deg2rad(s / 2)) for r in reps]
            stats[s, m] = Attenuation(float(np.mean(att)), float(np.std(att)))
    _write_csv(
        out / "fig11_attenuation_vs_spacing.csv",
        ["spacing_deg", "method", *_columns(Attenuation)],
        [
            [s, m, *dataclasses.astuple(stats[s, m])]
            for s in config.spacings_deg
            for m in config.methods
        ],
    )
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for m in config.methods:
        ax.errorbar(
            config.spacings_deg,
            [stats[s, m].attenuation_db_mean for s in config.spacings_deg],
            yerr=[stats[s, m].attenuation_db_std for s in config.spacings_deg],
            label=m,
            marker="o",
            ms=3,
            capsize=2,
        )
    ax.axhline(3, color="k", ls="--", lw=0.8)
    ax.set_xlabel("spacing (°)")
    ax.set_ylabel("maximum attenuation (dB)")
    ax.invert_xaxis()
    ax.legend(fontsize=7)
    ax.set_title("Fig. 11: two sources at 1 m, 10 dB SNR")
    _savefig(fig, out / "fig11_attenuation_vs_spacing.png")
    plt.close(fig)
    return stats


def _cut(config: StudyConfig) -> Callable[[Trial], dict[str, np.ndarray]]:
    """:func:`azimuth_cut_trial` with the study's step and setup (picklable)."""
    return partial(azimuth_cut_trial, step=config.cut_step_deg, setup=config)


def resolved_count(cut: np.ndarray, az_rad: np.ndarray, sources_deg: list[float]) -> int:
    """Sources with their own peak: a local maximum within 5° of the true azimuth, at
    most 20 dB under the strongest, separated from each neighbour by a 3 dB dip."""
    p = cut / cut.max()
    src = np.deg2rad(np.asarray(sources_deg))
    found = []
    for a in src:
        near = np.flatnonzero(np.abs(az_rad - a) <= np.deg2rad(5))
        j = near[np.argmax(p[near])]
        is_max = (j == 0 or p[j] >= p[j - 1]) and (j == p.size - 1 or p[j] >= p[j + 1])
        found.append(is_max and p[j] >= 1e-2)
    ok = list(found)
    for i in range(len(src) - 1):
        if P.max_attenuation(cut, az_rad, src[i], src[i + 1]) < 3:
            ok[i] = ok[i + 1] = False
    return int(sum(ok))


def fig12(config: StudyConfig, out: Path) -> dict[tuple[int, str], SourceCount]:
    """Spectra for 1 to 5 sources 40° apart at 1 m, 10 dB SNR, summed over range."""
    az = np.deg2rad(np.arange(-90, 90 + config.cut_step_deg / 2, config.cut_step_deg))
    layouts = {n: [40.0 * (i - (n - 1) / 2) for i in range(n)] for n in range(1, 6)}
    trials = [
        Trial(tuple((a, 0.0, 1.0) for a in layouts[n]), 10.0, _seed(config, 12, n, rep))
        for n in layouts
        for rep in range(config.repetitions)
    ]
    cuts = _map(config, _cut(config), trials)
    result = {}
    it = iter(cuts)
    for n in layouts:
        reps = [next(it) for _ in range(config.repetitions)]
        for m in config.methods:
            mean = np.mean([r[m] / r[m].max() for r in reps], axis=0)
            counts = [resolved_count(r[m], az, layouts[n]) for r in reps]
            result[n, m] = SourceCount(
                float(np.mean(counts)), float(P.dynamic_range_db(mean)), mean
            )
    _write_csv(
        out / "fig12_resolved_sources.csv",
        ["n_sources", "method", *_columns(SourceCount)],
        [
            [n, m, result[n, m].resolved_mean, result[n, m].dynamic_range_db]
            for n in layouts
            for m in config.methods
        ],
    )
    plt = _plt()
    cols = len(config.methods)
    fig, axes = plt.subplots(
        5, cols, figsize=(3 * cols, 11), sharex=True, sharey=True, squeeze=False
    )
    for i, n in enumerate(layouts):
        for j, m in enumerate(config.methods):
            ax = axes[i, j]
            ax.plot(np.rad2deg(az), P.to_db(result[n, m].mean_spectrum, floor_db=-80), lw=0.9)
            for a in layouts[n]:
                ax.axvline(a, color="r", lw=0.6)
            if i == 0:
                ax.set_title(m)
            if j == 0:
                ax.set_ylabel(f"{n} source(s)\ndB")
            ax.set_ylim(-80, 3)
    for ax in axes[-1]:
        ax.set_xlabel("azimuth (°)")
    fig.suptitle("Fig. 12: spectra summed over range, averaged over repetitions")
    _savefig(fig, out / "fig12_multiple_sources.png")
    plt.close(fig)
    return result


#: what each experiment of :data:`EXPERIMENTS` makes (the progress lines say it)
TITLES = {
    "fig3_4": "Figs. 3-4 (signal and matched filter)",
    "fig6_7": "Figs. 6-7 (resolution against SNR)",
    "fig9_10": "Figs. 9-10 (resolution against snapshots)",
    "fig11": "Fig. 11 (two sources)",
    "fig12": "Fig. 12 (up to five sources)",
}
#: the experiments run_study runs, in order (the names its `progress` is called with)
EXPERIMENTS = tuple(TITLES)


def run_study(
    config: StudyConfig, out_dir: str | Path, progress: Callable[[str], None] | None = None
) -> StudyResults:
    """Run every experiment, writing CSVs and PNGs into `out_dir`; return the results."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda s: None)

    def run(name: str, fn: Callable):
        say(name)
        return fn(config, out)

    results = StudyResults(
        config=config,
        frequency_hz=config.frequency_hz,
        fig3_4=run("fig3_4", fig3_4),
        fig6_7=run("fig6_7", fig6_7),
        fig9_10=run("fig9_10", fig9_10),
        fig11=run("fig11", fig11),
        fig12=run("fig12", fig12),
    )
    _write_json(
        out / "study.json",
        {"config": dataclasses.asdict(config), "fig3_4": dataclasses.asdict(results.fig3_4)},
    )
    return results


def _write_json(path: Path, data: dict) -> None:
    write_text(path, json.dumps(data, indent=1))


def load_results(out_dir: str | Path) -> StudyResults:
    """The results of a finished run, read back from its CSV and JSON files (to rewrite
    the report without running the study again); :class:`InputError` naming the file
    when one is missing or malformed."""
    out = Path(out_dir)
    path = out / "study.json"
    try:
        meta = json.loads(path.read_text())
        config = StudyConfig(
            **{k: tuple(v) if isinstance(v, list) else v for k, v in meta["config"].items()}
        )
        pulse = PulseNumbers(**meta["fig3_4"])

        def table(name: str) -> list[dict[str, str]]:
            nonlocal path
            path = out / name
            with open(path, newline="") as f:
                return list(csv.DictReader(f))

        def sweep(name: str, key: str, cast: Callable) -> Sweep:
            return {
                (
                    (float(r["azimuth_deg"]), float(r["elevation_deg"]), 1.0),
                    cast(r[key]),
                    r["method"],
                ): _read_row(Resolution, r)
                for r in table(name)
            }

        results = StudyResults(
            config=config,
            frequency_hz=config.frequency_hz,
            fig3_4=pulse,
            fig6_7=sweep("fig06_07_resolution_vs_snr.csv", "snr_db", float),
            fig9_10=sweep("fig09_10_resolution_vs_snapshots.csv", "snapshots", int),
            fig11={
                (float(r["spacing_deg"]), r["method"]): _read_row(Attenuation, r)
                for r in table("fig11_attenuation_vs_spacing.csv")
            },
            fig12={
                (int(r["n_sources"]), r["method"]): _read_row(SourceCount, r)
                for r in table("fig12_resolved_sources.csv")
            },
        )
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror or exc})", file=path) from None
    except (ValueError, KeyError, TypeError) as exc:  # parsing the file's text
        if isinstance(exc, InputError):
            raise
        raise InputError(f"malformed study file ({exc!r})", file=path) from None
    return results
