"""A trajectory's comparisons summed up (:func:`acousim.compare.comparison.compare` per pose):
one row per pose and the medians over every matched echo, written as JSON."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from processing.base.atomic import write_text

__all__ = ["TrajectorySummary", "summarize", "write_summary"]


@dataclass(frozen=True)
class TrajectorySummary:
    """One row per pose (dicts of numbers, one column per method and count) and the
    medians over every matched echo."""

    rows: tuple[dict, ...]
    poses: int
    mean_envelope_correlation: float
    matched_echoes: int
    median_abs_d_range_m: float | None
    median_abs_d_azimuth_deg: float | None

    def to_dict(self) -> dict:
        return {
            "rows": list(self.rows),
            "summary": {
                "poses": self.poses,
                "mean_envelope_correlation": self.mean_envelope_correlation,
                "matched_echoes": self.matched_echoes,
                "median_abs_d_range_m": self.median_abs_d_range_m,
                "median_abs_d_azimuth_deg": self.median_abs_d_azimuth_deg,
            },
        }


def summarize(reports: Sequence) -> TrajectorySummary:
    """One line per pose of a trajectory and a summary over all of them (`reports`:
    :class:`acousim.compare.comparison.Comparison` per pose)."""
    rows, d_range, d_az, corr = [], [], [], []
    for i, r in enumerate(reports):
        row = {
            "pose": i,
            "gain": r.alignment.gain,
            "emission_shift_samples": r.alignment.emission_shift_samples,
            "mean_envelope_correlation": r.mean_envelope_correlation,
        }
        for m, img in r.images.items():
            row[f"{m}_matched"] = len(img.matched)
            row[f"{m}_only_real"] = len(img.only_real)
            row[f"{m}_only_sim"] = len(img.only_sim)
            row[f"{m}_side_lobes_real"] = len(img.side_lobes_real)
            d_range += [abs(p.d_range_m) for p in img.matched]
            d_az += [abs(p.d_azimuth_deg) for p in img.matched]
        corr.append(r.mean_envelope_correlation)
        rows.append(row)
    return TrajectorySummary(
        rows=tuple(rows),
        poses=len(reports),
        mean_envelope_correlation=float(np.mean(corr)) if corr else 0.0,
        matched_echoes=len(d_range),
        median_abs_d_range_m=float(np.median(d_range)) if d_range else None,
        median_abs_d_azimuth_deg=float(np.median(d_az)) if d_az else None,
    )


def write_summary(summary: TrajectorySummary, out_dir: str | Path) -> Path:
    """``summary.json`` in `out_dir`, written atomically."""
    return write_text(Path(out_dir) / "summary.json", json.dumps(summary.to_dict(), indent=1))
