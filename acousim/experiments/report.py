"""``docs/REPRODUCTION.md``: the paper's headline numbers beside ours, generated."""

from __future__ import annotations

import datetime
import os
from pathlib import Path

import numpy as np

from acousim.experiments.paper_study import POSITIONS, StudyResults, Sweep
from processing.base.atomic import write_text

SMOOTHED = ("capon-fbss", "music-fss", "music-fbss")
SMOOTHED9_NOTE = (
    "Largest mean over positions and snapshots. MUSIC-FBSS and MUSIC-FSS stay "
    "far below the bound; Capon-FBSS at (60°, 60°), where the aperture is halved, "
    "is the one that can exceed it: its −0.5 noise-floor load is our reading of "
    "the paper's b = −0.5, whose scale the paper leaves open."
)


def _mean(stats: Sweep, p, v, m, index):
    """Mean angular (index 0, sr) or range (index 1, m) resolution."""
    r = stats[p, v, m]
    return r.angular_sr_mean if index == 0 else r.range_m_mean


def _context(results: StudyResults):
    """The study's results and settings the headline rows read."""
    cfg = results.config
    snrs, snaps = cfg.snrs_db, cfg.snapshots
    return (
        cfg,
        results.fig3_4,
        results.fig6_7,
        results.fig9_10,
        results.fig11,
        results.fig12,
        *POSITIONS,
        snrs,
        snaps,
        [v for v in snrs if v >= 0],
    )


def headline(results: StudyResults) -> list[tuple[str, str, str, str]]:
    """Rows (claim, paper, ours, why they differ or agree)."""
    parts = (_fig4_rows, _fig6_7_rows, _fig6_7_failing_rows, _fig9_10_rows, _fig11_12_rows)

    return [row for part in parts for row in part(results)]


def _fig4_rows(results: StudyResults) -> list:
    """Fig. 4: the range estimate and the echo width."""
    cfg, f34, s67, s910, f11, f12, p0, p30, p60, snrs, snaps, hi_snr = _context(results)
    rows = []
    rows.append(
        (
            "Fig. 4: matched-filter range estimate, reflector at (30°, 30°, 1 m)",
            "1.003 m",
            f"{f34.range_estimate_m:.4f} m",
            "Our estimate is half the emitter→reflector→microphone path for microphone 0, at "
            "a corner of the array (emitter at the centre): (1 + 1.0165)/2 = 1.0082 m, "
            "which the matched filter's largest sample, on a grid of c/(2 fs) = 0.34 mm, "
            "finds within half a step. The paper does not say which microphone or where "
            "its emitter is; the centre microphone would give 1.000 m.",
        )
    )
    rows.append(
        (
            "Fig. 4: echo width before → after the matched filter",
            "≈20 cm → ≈6 mm",
            f"{f34.raw_extent_m * 100:.1f} cm → {f34.rayleigh_width_m * 1e3:.1f} mm "
            f"(−3 dB: {f34.width_3db_m * 1e3:.1f} mm)",
            "Before: the 1 ms call spans c·T/2. After: first null to first null of the "
            "compressed envelope, 2/B·c/2 for B = 65 kHz; the paper's 'Rayleigh width'.",
        )
    )
    return rows


def _fig6_7_rows(results: StudyResults) -> list:
    """Figs. 6-7: angular resolution by method and SNR."""
    cfg, f34, s67, s910, f11, f12, p0, p30, p60, snrs, snaps, hi_snr = _context(results)
    rows = []
    das0 = np.mean([_mean(s67, p0, v, "das", 0) for v in hi_snr])
    das60 = np.mean([_mean(s67, p60, v, "das", 0) for v in hi_snr])
    rows.append(
        (
            "Fig. 6: DAS angular resolution, (0°, 0°) → (60°, 60°)",
            "≈0.04 → ≈0.12 sr",
            f"{das0:.3f} → {das60:.3f} sr",
            "Mean over SNR ≥ 0 dB (DAS does not depend on SNR). Agrees.",
        )
    )
    worst_smoothed = max(
        _mean(s67, p, v, m, 0) for p in POSITIONS for v in snrs if v >= -10 for m in SMOOTHED
    )
    rows.append(
        (
            "Fig. 6: smoothed methods, worst case for SNR ≥ −10 dB",
            "≈0.025 sr",
            f"{worst_smoothed:.4f} sr",
            "Largest mean over positions, SNR ≥ −10 dB and Capon-FBSS, MUSIC-FSS, MUSIC-FBSS.",
        )
    )
    music_low = max(_mean(s67, p, snrs[0], "music", 0) for p in POSITIONS)
    music_hi = max(_mean(s67, p, v, "music", 0) for p in POSITIONS for v in hi_snr)
    rows.append(
        (
            "Fig. 6: plain MUSIC, lowest SNR → SNR ≥ 0 dB (worst position)",
            "up to ≈0.3 sr, stable above 0 dB",
            f"{music_low:.3f} → at most {music_hi:.4f} sr",
            f"At {snrs[0]:.0f} dB single-snapshot MUSIC (rank-1 covariance) follows the noisy "
            "snapshot, so its lobe wanders and widens; above 0 dB it is stable.",
        )
    )
    return rows


def _snr_span(snrs: list[float]) -> str:
    """SNRs (dB) as a report's words: "-10 dB" for one value, "-20 to -10 dB" for
    several."""
    lo, hi = f"{min(snrs):.0f}", f"{max(snrs):.0f}"
    return f"{lo} dB" if lo == hi else f"{lo} to {hi} dB"


def _fig6_7_failing_rows(results: StudyResults) -> list:
    """Figs. 6-7: where MUSIC fails."""
    cfg, f34, s67, s910, f11, f12, p0, p30, p60, snrs, snaps, hi_snr = _context(results)
    rows = []
    failing = [(p, v) for p in POSITIONS for v in snrs if _mean(s67, p, v, "music", 0) > 0.1]
    rng67 = max(
        _mean(s67, p, v, m, 1)
        for p in POSITIONS
        for v in snrs
        for m in s67_methods(s67)
        if not (m == "music" and (p, v) in failing)
    )
    worst_fail = max((_mean(s67, p, v, "music", 1) for p, v in failing), default=0.0)
    lost = (
        f" Plain MUSIC at {_snr_span([v for _, v in failing])} is left out: its −3 dB lobe "
        "exceeds 0.1 sr there (it has lost the reflector in "
        "the noise) and its image maximum can fall in a gated noise bin, giving up to "
        f"{worst_fail * 100:.0f} cm."
        if failing
        else ""
    )
    rows.append(
        (
            "Fig. 7: range resolution, largest mean",
            "within ≈6 cm",
            f"{rng67 * 100:.1f} cm",
            "Bounded by the 256-sample STFT window and the half-energy gate (a 3 dB gate on "
            "a 3 dB metric): the paper's own explanation for Fig. 10." + lost,
        )
    )
    return rows


def _fig9_10_rows(results: StudyResults) -> list:
    """Figs. 9-10: snapshots and smoothing."""
    cfg, f34, s67, s910, f11, f12, p0, p30, p60, snrs, snaps, hi_snr = _context(results)
    rows = []
    sm9 = max(_mean(s910, p, k, m, 0) for p in POSITIONS for k in snaps for m in SMOOTHED)
    rows.append(
        (
            "Fig. 9 (3 dB): smoothed methods, largest mean",
            "< 0.0016 sr",
            f"{sm9:.4f} sr",
            SMOOTHED9_NOTE,
        )
    )
    rows.append(
        (
            "Fig. 9: DAS at (0°, 0°) and (60°, 60°)",
            "≈0.025 and ≈0.125 sr",
            f"{np.mean([_mean(s910, p0, k, 'das', 0) for k in snaps]):.3f} and "
            f"{np.mean([_mean(s910, p60, k, 'das', 0) for k in snaps]):.3f} sr",
            "(60°, 60°) agrees. At (0°, 0°) the paper's Fig. 9 value (0.025) is lower than its "
            "own Fig. 6 value (0.04) for the same DAS, which does not depend on SNR or on "
            "snapshots; ours matches Fig. 6.",
        )
    )
    k1, k5 = snaps[0], min(snaps, key=lambda k: abs(k - 5))
    rows.append(
        (
            f"Fig. 9: plain MUSIC at (60°, 60°), {k1} → {k5} snapshots",
            "0.003 → 0.001 sr",
            f"{_mean(s910, p60, k1, 'music', 0):.4f} → {_mean(s910, p60, k5, 'music', 0):.4f} sr",
            "Same trend: more snapshots raise the rank of the covariance. Our lobes are wider "
            "at one snapshot; the paper's SNR reference (which samples carry P_s) is not "
            "stated, and ours counts only the call's duration.",
        )
    )
    rng910 = max(
        _mean(s910, p, k, m, 1) for p in POSITIONS for k in snaps for m in s67_methods(s910)
    )
    rows.append(
        (
            "Fig. 10: range resolution, largest mean",
            "≤ ≈7 cm, independent of snapshots",
            f"{rng910 * 100:.1f} cm",
            "Same bound as Fig. 7.",
        )
    )
    return rows


def _fig11_12_rows(results: StudyResults) -> list:
    """Figs. 11-12: two reflectors, attenuation and spacing."""
    cfg, f34, s67, s910, f11, f12, p0, p30, p60, snrs, snaps, hi_snr = _context(results)
    rows = []
    spac = cfg.spacings_deg

    def last_above(m, level):
        ok = [s for s in spac if f11[s, m].attenuation_db_mean > level]
        # the smallest spacing such that every larger spacing also stays above `level`
        best = None
        for s in sorted(spac, reverse=True):
            if f11[s, m].attenuation_db_mean > level:
                best = s
            else:
                break
        return best if ok else None

    rows.append(
        (
            "Fig. 11: smoothed methods keep > 10 dB down to",
            "14°",
            ", ".join(f"{m} {last_above(m, 10)}°" for m in SMOOTHED),
            "Smallest spacing above which the mean dip stays over 10 dB.",
        )
    )
    rows.append(
        (
            "Fig. 11: DAS separates (> 3 dB) down to",
            "24°",
            f"{last_above('das', 3)}°",
            "The −3 dB beamwidth of 8 × 5 mm at 31.25 kHz is about 23°.",
        )
    )
    music_max = max(f11[s, "music"].attenuation_db_mean for s in spac)
    rows.append(
        (
            "Fig. 11: plain MUSIC, best dip; under 3 dB from",
            "≈8 dB; 25°",
            f"{music_max:.1f} dB; {_first_below(f11, spac, 'music')}°",
            "Coherent echoes make the single-snapshot covariance rank 1: plain MUSIC then "
            "sees one merged direction. The paper's 8 dB suggests its MUSIC saw some "
            "decorrelation (e.g. a noise-subspace rule applied per microphone); ours is the "
            "textbook estimator.",
        )
    )
    rows.append(
        (
            "Fig. 12: coherent sources resolved at one range (Capon-FBSS, MUSIC-FBSS), 4 → 5",
            "4 resolved → not 5",
            f"{f12[4, 'capon-fbss'].resolved_mean:.1f}, {f12[4, 'music-fbss'].resolved_mean:.1f}"
            f" → {f12[5, 'capon-fbss'].resolved_mean:.1f}, "
            f"{f12[5, 'music-fbss'].resolved_mean:.1f}",
            "Mean number of sources with their own peak and a 3 dB dip to each neighbour. "
            "A row of the 8 × 8 array holds four 5 × 5 subarrays: agrees.",
        )
    )
    return rows


def s67_methods(stats: Sweep) -> list[str]:
    return sorted({k[2] for k in stats})


def _first_below(f11, spac, m):
    for s in sorted(spac, reverse=True):
        if f11[s, m].attenuation_db_mean < 3:
            return s
    return None


#: the report's readings of the paper (how we read what it leaves open)
_READINGS = [
    "## Readings of the paper",
    "",
    "- **SNR (eq. 2)**: signal power = noise-free energy averaged over microphones, "
    "divided by the call length in samples, i.e. the echo's mean power while one call "
    "lasts; white Gaussian noise, independent per microphone and snapshot.",
    "- **Steering sign**: with an exp(−jωt) STFT, eq. 7 as printed images the mirror "
    "direction; we steer with exp(+jk u·p) (pinned by a test).",
    "- **Capon loading**: the paper's b = −0.5 has no scale of its own; we load by "
    "−0.5 times the smallest eigenvalue after a white-noise floor of 1e−3·tr(R)/L, "
    "which keeps R_b positive definite at any signal scale.",
    "- **Angular resolution**: the −3 dB region connected to the image maximum, on its "
    "range slice, weighted by cos(elevation). **Range resolution**: the −3 dB extent "
    "of the per-slice maxima over the kept range bins.",
    "- **Figs. 11–12**: spectra at elevation 0 summed over the kept range bins; the "
    "attenuation is the lower of the two source peaks over the deepest point between "
    "them.",
    "",
]
#: the figures, in the paper's order
_FIGURES = [
    ("fig03_spectrogram.png", "Fig. 3"),
    ("fig04_matched_filter.png", "Fig. 4"),
    ("fig06_angular_vs_snr.png", "Fig. 6"),
    ("fig07_range_vs_snr.png", "Fig. 7"),
    ("fig09_angular_vs_snapshots.png", "Fig. 9"),
    ("fig10_range_vs_snapshots.png", "Fig. 10"),
    ("fig11_attenuation_vs_spacing.png", "Fig. 11"),
    ("fig12_multiple_sources.png", "Fig. 12"),
]


def write_report(
    results: StudyResults, path: str | Path, figures_dir: str | Path, command: str
) -> Path:
    path = Path(path)
    figs = os.path.relpath(Path(figures_dir), path.parent)
    cfg = results.config
    lines = [
        "# Reproduction of the paper's simulation study",
        "",
        f"Generated by `{command}` on {datetime.date.today().isoformat()}; do not edit by "
        "hand. Paper: *High-Resolution Ultrasound Sensing for Robotics using Dense "
        "Microphone Arrays*, section IV.",
        "",
        f"Settings: 8 × 8 URA at 5 mm, linear chirp 20 → 85 kHz in 1 ms at 500 kHz, "
        f"c = 343 m/s, spreading 1/(2r), steering at {results.frequency_hz / 1e3:.2f} kHz, "
        f"STFT window 256 / overlap 240, half-energy gate, 5 × 5 subarrays, "
        f"{cfg.repetitions} repetitions, grid step {cfg.grid_step_deg}° "
        f"(cuts {cfg.cut_step_deg}°).",
        "",
        "## Headline numbers",
        "",
        "| claim | paper | ours | why |",
        "|---|---|---|---|",
    ]
    lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in headline(results)]
    lines += [
        "",
        *_READINGS,
        "## Figures",
        "",
    ]
    for name, title in _FIGURES:
        lines += [f"### {title}", "", f"![{title}]({figs}/{name})", ""]
    lines += ["CSV files with every number are beside the figures.", ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, "\n".join(lines))
    return path
