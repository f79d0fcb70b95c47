"""What a comparison measured (:class:`Comparison`: its ``to_dict()`` is what
``comparison.json`` holds) and what its picture draws (:class:`ComparisonArrays`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

import processing as P
from acousim.compare.alignment import Alignment
from acousim.compare.comparable import Span
from acousim.compare.echo_table import MethodComparison

__all__ = ["Comparison", "ComparisonArrays"]


@dataclass(frozen=True)
class Comparison:
    """Everything :func:`acousim.compare.comparison.compare` measured.
    `level_difference_db` (B,) is 10 log10(real / simulated) per `range_bin_m` range
    bin after alignment and gain.  `span` is what was compared (the common span of
    recordings of different lengths; None: not said)."""

    alignment: Alignment
    envelope_correlation: tuple[float, ...]
    range_bin_m: float
    level_difference_db: tuple[float, ...]
    images: dict[str, MethodComparison]
    span: Span | None = None

    @property
    def mean_envelope_correlation(self) -> float:
        return float(np.mean(self.envelope_correlation))

    def to_dict(self) -> dict:
        return {
            "alignment": asdict(self.alignment),
            "channels": {
                "envelope_correlation": list(self.envelope_correlation),
                "mean_envelope_correlation": self.mean_envelope_correlation,
            },
            "range_profile": {
                "range_bin_m": self.range_bin_m,
                "level_difference_db": list(self.level_difference_db),
                "note": "10 log10(real / simulated) per range bin, after alignment and gain",
            },
            "images": {m: r.to_dict() for m, r in self.images.items()},
            "span": None if self.span is None else self.span.to_dict(),
        }


@dataclass(frozen=True, eq=False)
class ComparisonArrays:
    """What the picture draws: range-bin edges (B + 1,) in m, the two range profiles
    (B,) (mean envelope power) and the images of each method."""

    edges_m: np.ndarray
    profile_real: np.ndarray
    profile_sim: np.ndarray
    images_real: dict[str, P.Image]
    images_sim: dict[str, P.Image]
