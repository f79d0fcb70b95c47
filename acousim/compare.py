"""Simulated versus real: align two recordings of the same sensor and say how far
apart they are, at every stage of the pipeline.

1. Alignment: the time of emission from the direct emitter -> microphone path (the
   lag that best aligns the first milliseconds of the two matched-filter outputs,
   refined to a fraction of a sample), then one overall gain by least squares on
   the matched-filter envelopes after the direct path (the echoes).  Without a
   direct path in the simulation, the whole recording sets the lag.  Both are
   reported, never hidden.
2. Per channel: matched-filter envelopes, their correlation and their level
   difference in dB along range.
3. Range profiles (mean envelope power over channels).
4. Images of the same methods; their peaks matched one to one
   (:func:`scipy.optimize.linear_sum_assignment`), with the range, azimuth,
   elevation and level differences of each matched echo and the echoes only one
   side has.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.signal import hilbert

import processing as P

__all__ = [
    "ComparisonError",
    "check_comparable",
    "align",
    "compare",
    "summarize",
    "write_comparison",
]

DIRECT_WINDOW_S = 1.0e-3  # beyond the call: the direct path's part used for alignment


class ComparisonError(ValueError):
    """The two recordings cannot be compared; the message names what differs."""


def check_comparable(real: P.Recording, sim: P.Recording) -> None:
    diffs = []
    if real.array.n_mics != sim.array.n_mics or not np.allclose(
        real.array.positions_m, sim.array.positions_m, atol=1e-6
    ):
        diffs.append(
            f"arrays ({real.array.name}, {real.array.n_mics} mics vs "
            f"{sim.array.name}, {sim.array.n_mics} mics)"
        )
    if real.sample_rate_hz != sim.sample_rate_hz:
        diffs.append(f"sample rates ({real.sample_rate_hz:g} vs {sim.sample_rate_hz:g} Hz)")
    if real.n_samples != sim.n_samples:
        diffs.append(f"lengths ({real.n_samples} vs {sim.n_samples} samples)")
    if real.waveform != sim.waveform:
        diffs.append(f"calls ({real.waveform.to_dict()} vs {sim.waveform.to_dict()})")
    if diffs:
        raise ComparisonError("the recordings differ in " + "; ".join(diffs))


def _mf(rec: P.Recording) -> np.ndarray:
    x = rec.samples if rec.samples.ndim == 2 else rec.samples.mean(axis=0)
    return P.matched_filter(x, rec.waveform.sampled(rec.sample_rate_hz))


def _shift(x: np.ndarray, samples: float) -> np.ndarray:
    """Delay x (..., T) by a fractional number of samples (FFT phase shift)."""
    n = x.shape[-1]
    f = np.fft.rfftfreq(2 * n)
    X = np.fft.rfft(x, 2 * n, axis=-1) * np.exp(-2j * np.pi * f * samples)
    return np.fft.irfft(X, 2 * n, axis=-1)[..., :n]


def align(real: P.Recording, sim: P.Recording, max_lag_s: float = 0.5e-3) -> tuple[float, float]:
    """(shift in samples to apply to `sim`, gain real/sim)."""
    return _align(real, _mf(real), _mf(sim), max_lag_s)[:2]


def _align(real: P.Recording, mf_r: np.ndarray, mf_s: np.ndarray, max_lag_s: float = 0.5e-3):
    """Lag, gain and the two matched-filter envelopes (the simulated one shifted by the
    lag, before the gain), from matched-filter outputs computed once by the caller."""
    fs = real.sample_rate_hz
    win = int((real.waveform.duration_s + DIRECT_WINDOW_S) * fs)
    # the direct path sets the time of emission; a simulation without one (or with
    # almost none) is aligned on the whole recording instead
    early = np.sum(mf_s[:, :win] ** 2) >= 0.01 * np.sum(mf_s**2)
    span = win if early else mf_s.shape[-1]
    a, b = mf_r[:, :span], mf_s[:, :span]
    max_lag = int(max_lag_s * fs)
    n = 2 * span
    xc = np.fft.irfft(np.fft.rfft(a, n) * np.conj(np.fft.rfft(b, n)), n).sum(axis=0)
    lags = np.concatenate([np.arange(0, max_lag + 1), np.arange(-max_lag, 0)])
    vals = np.concatenate([xc[: max_lag + 1], xc[n - max_lag :]])
    k = int(np.argmax(vals))
    lag = float(lags[k])
    # parabolic refinement
    left = vals[k - 1]  # vals runs over lags 0..max, -max..-1: index -1 is lag -1
    right = vals[(k + 1) % len(vals)]
    den = left - 2 * vals[k] + right
    if den < 0:
        lag += 0.5 * (left - right) / den
    # the gain: least squares on the matched-filter envelopes after the direct path
    # (the echoes): envelopes do not depend on the carrier's phase, and the direct
    # path of a real sensor is often clipped and would set the gain alone.  The
    # matched filter commutes with the delay, so its output is shifted, not recomputed.
    env_s = np.abs(hilbert(_shift(mf_s, lag), axis=-1))
    env_r = np.abs(hilbert(mf_r, axis=-1))
    denom = float(np.sum(env_s[:, win:] ** 2))
    gain = float(np.sum(env_r[:, win:] * env_s[:, win:]) / denom) if denom > 0 else 0.0
    return lag, gain, env_r, env_s


@dataclass(frozen=True)
class MatchTolerance:
    range_m: float = 0.3
    angle_deg: float = 15.0


def _peaks_table(img: P.Image, threshold_db: float) -> np.ndarray:
    pk = img.peaks(threshold_db)
    return np.column_stack(
        [pk.range_m, np.rad2deg(pk.azimuth_rad), np.rad2deg(pk.elevation_rad), pk.level_db]
    )


def match_peaks(
    a: np.ndarray, b: np.ndarray, tol: MatchTolerance = MatchTolerance()
) -> tuple[list[tuple[int, int]], list[int], list[int]]:
    """One-to-one matching of peak tables (range, az, el, level): pairs, only-a, only-b."""
    if len(a) == 0 or len(b) == 0:
        return [], list(range(len(a))), list(range(len(b)))
    cost = (
        np.abs(a[:, None, 0] - b[None, :, 0]) / tol.range_m
        + np.hypot(a[:, None, 1] - b[None, :, 1], a[:, None, 2] - b[None, :, 2]) / tol.angle_deg
    )
    ia, ib = linear_sum_assignment(cost)
    pairs = [(int(i), int(j)) for i, j in zip(ia, ib) if cost[i, j] <= 2.0]
    ma = {i for i, _ in pairs}
    mb = {j for _, j in pairs}
    return (
        pairs,
        [i for i in range(len(a)) if i not in ma],
        [j for j in range(len(b)) if j not in mb],
    )


def compare(
    real: P.Recording,
    sim: P.Recording,
    methods=("das",),
    settings: P.ProcessingSettings | None = None,
    threshold_db: float = -12.0,
    range_bin_m: float = 0.05,
) -> tuple[dict, dict]:
    """Compare two recordings.  Returns (report dict, arrays for the picture)."""
    check_comparable(real, sim)
    lag, gain, env_r, env_s = _align(real, _mf(real), _mf(sim))
    env_s = gain * env_s
    fs, c = real.sample_rate_hz, real.speed_of_sound_m_s
    aligned = sim.with_samples(
        gain * _shift(sim.samples if sim.samples.ndim == 2 else sim.samples.mean(0), lag)
    )
    corr = [
        float(np.corrcoef(er, es)[0, 1]) if er.std() > 0 and es.std() > 0 else 0.0
        for er, es in zip(env_r, env_s)
    ]
    rng = real.time_s() * c / 2
    edges = np.arange(0, rng[-1] + range_bin_m, range_bin_m)
    idx = np.clip(np.digitize(rng, edges) - 1, 0, len(edges) - 2)
    prof_r = np.bincount(idx, (env_r**2).mean(axis=0), len(edges) - 1)
    prof_s = np.bincount(idx, (env_s**2).mean(axis=0), len(edges) - 1)
    tiny = 1e-30
    level_db = 10 * np.log10((prof_r + tiny) / (prof_s + tiny))
    settings = settings or P.ProcessingSettings(
        energy_fraction=0.3,
        range_limits_m=(0.3, float(rng[-1])),
        grid=P.Grid.degrees((-90, 90), (-60, 60), 2),
    )
    images_r = P.acoustic_images(real, methods, settings)
    images_s = P.acoustic_images(aligned, methods, settings)
    per_method = {}
    for m in methods:
        a, b = _peaks_table(images_r[m], threshold_db), _peaks_table(images_s[m], threshold_db)
        pairs, only_r, only_s = match_peaks(a, b)
        per_method[m] = {
            "matched": [
                {
                    "real": dict(
                        zip(("range_m", "azimuth_deg", "elevation_deg", "level_db"), a[i].tolist())
                    ),
                    "sim": dict(
                        zip(("range_m", "azimuth_deg", "elevation_deg", "level_db"), b[j].tolist())
                    ),
                    "d_range_m": float(b[j, 0] - a[i, 0]),
                    "d_azimuth_deg": float(b[j, 1] - a[i, 1]),
                    "d_elevation_deg": float(b[j, 2] - a[i, 2]),
                    "d_level_db": float(b[j, 3] - a[i, 3]),
                }
                for i, j in pairs
            ],
            "only_real": [
                dict(zip(("range_m", "azimuth_deg", "elevation_deg", "level_db"), a[i].tolist()))
                for i in only_r
            ],
            "only_sim": [
                dict(zip(("range_m", "azimuth_deg", "elevation_deg", "level_db"), b[j].tolist()))
                for j in only_s
            ],
            "range_bin_m": images_r[m].bin_range_m,
        }
    report = {
        "alignment": {"emission_shift_samples": lag, "emission_shift_s": lag / fs, "gain": gain},
        "channels": {
            "envelope_correlation": corr,
            "mean_envelope_correlation": float(np.mean(corr)),
        },
        "range_profile": {
            "range_bin_m": range_bin_m,
            "level_difference_db": level_db.tolist(),
            "note": "10 log10(real / simulated) per range bin, after alignment and gain",
        },
        "images": per_method,
    }
    arrays = {
        "edges": edges,
        "prof_r": prof_r,
        "prof_s": prof_s,
        "images_r": images_r,
        "images_s": images_s,
    }
    return report, arrays


def write_comparison(report: dict, arrays: dict, out_dir: str | Path) -> list[Path]:
    """The JSON report and a side-by-side picture, written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acousim.viz.fan import draw_fan

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    js = out / "comparison.json"
    tmp = js.with_suffix(".json.part")
    tmp.write_text(json.dumps(report, indent=1))
    os.replace(tmp, js)
    methods = list(arrays["images_r"])
    fig, axes = plt.subplots(len(methods), 3, figsize=(14, 4 * len(methods)), squeeze=False)
    centres = (arrays["edges"][1:] + arrays["edges"][:-1]) / 2
    for row, m in zip(axes, methods):
        ir, is_ = arrays["images_r"][m], arrays["images_s"][m]
        top = max([float(im.range_m.max()) for im in (ir, is_) if im.range_m.size] or [1.0])
        for ax, img, name in ((row[0], ir, "real"), (row[1], is_, "simulated")):
            draw_fan(ax, img, top * 1.05, 30.0)
            ax.set_title(f"{name}, {m}")
        for k, pair in enumerate(report["images"][m]["matched"]):
            for ax, side in ((row[0], "real"), (row[1], "sim")):
                p = pair[side]
                a = np.deg2rad(p["azimuth_deg"])
                ax.plot(
                    p["range_m"] * np.sin(a),
                    p["range_m"] * np.cos(a),
                    "o",
                    mfc="none",
                    mec="cyan",
                    ms=10,
                )
                ax.annotate(
                    str(k),
                    (p["range_m"] * np.sin(a), p["range_m"] * np.cos(a)),
                    color="cyan",
                    fontsize=8,
                )
        ax = row[2]
        ax.plot(centres, 10 * np.log10(arrays["prof_r"] + 1e-30), label="real")
        ax.plot(centres, 10 * np.log10(arrays["prof_s"] + 1e-30), label="simulated (aligned)")
        ax.set_xlabel("range (m)")
        ax.set_ylabel("mean envelope power (dB)")
        ax.legend()
        ax.set_title(
            f"range profiles; gain {report['alignment']['gain']:.3g}, "
            f"shift {report['alignment']['emission_shift_samples']:.2f} samples"
        )
    png = out / "comparison.png"
    tmpp = png.with_name(".comparison.part.png")
    fig.savefig(tmpp, dpi=100, bbox_inches="tight")
    plt.close(fig)
    os.replace(tmpp, png)
    return [js, png]


def summarize(reports: list[dict]) -> dict:
    """One line per pose of a trajectory and a summary over all of them."""
    rows, d_range, d_az, corr = [], [], [], []
    for i, r in enumerate(reports):
        row = {
            "pose": i,
            "gain": r["alignment"]["gain"],
            "emission_shift_samples": r["alignment"]["emission_shift_samples"],
            "mean_envelope_correlation": r["channels"]["mean_envelope_correlation"],
        }
        for m, img in r["images"].items():
            row[f"{m}_matched"] = len(img["matched"])
            row[f"{m}_only_real"] = len(img["only_real"])
            row[f"{m}_only_sim"] = len(img["only_sim"])
            d_range += [abs(p["d_range_m"]) for p in img["matched"]]
            d_az += [abs(p["d_azimuth_deg"]) for p in img["matched"]]
        corr.append(row["mean_envelope_correlation"])
        rows.append(row)
    return {
        "rows": rows,
        "summary": {
            "poses": len(reports),
            "mean_envelope_correlation": float(np.mean(corr)) if corr else 0.0,
            "matched_echoes": len(d_range),
            "median_abs_d_range_m": float(np.median(d_range)) if d_range else None,
            "median_abs_d_azimuth_deg": float(np.median(d_az)) if d_az else None,
        },
    }
