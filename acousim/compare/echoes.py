"""When two paired peaks are an echo both recordings have
(:func:`acousim.compare.comparison.compare`): a :class:`MatchedEcho`, or a
:class:`RejectedPair` that says why not.

Two images' peaks are paired by position alone; a pair is a *matched echo* only when

* the real peak is an echo, not noise: the real range profile (mean envelope power
  over the microphones per range bin) at its range stands at least
  :data:`MIN_ECHO_ABOVE_FLOOR_DB` above the profile's noise floor
  (:func:`acousim.compare.account.noise_floor`, the number the command prints);
* the simulated peak is a traced path, not a side lobe: the simulated recording's
  ground truth puts one in the peak's resolution cell (the peak table's
  ``truth_kind``, :func:`acousim.imaging.run.peak_table`, as ``peaks.csv`` has it).
  A simulation without ground truth is taken as it is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

import processing as P
from acousim.compare.account import noise_floor
from acousim.compare.peaks import Peak

__all__ = [
    "MIN_ECHO_ABOVE_FLOOR_DB",
    "MatchedEcho",
    "RejectedPair",
    "above_floor",
    "traced_kinds",
    "reject_reason",
]

#: a real peak is an echo when the real range profile at its range stands at least
#: this far above the profile's noise floor (dB)
MIN_ECHO_ABOVE_FLOOR_DB = 10.0


def above_floor(
    edges: np.ndarray, profile: np.ndarray, extent_m: float
) -> Callable[[float], float]:
    """A function of a range (m): how far (dB) the range profile (B,) (linear power;
    bin `edges` (B + 1,), m) stands above its noise floor there, at its strongest bin
    within half of `extent_m` (the STFT window, m; at least one bin) of that range."""
    floor = noise_floor(profile)
    centres = (edges[1:] + edges[:-1]) / 2
    reach = max(extent_m / 2, float(edges[1] - edges[0]))

    def above(range_m: float) -> float:
        near = np.abs(centres - range_m) <= reach
        top = float(np.max(profile[near])) if np.any(near) else 0.0
        return float(10 * np.log10((top + 1e-300) / (floor + 1e-300)))

    return above


def traced_kinds(rec: P.Recording, image: P.Image, peaks: P.Peaks, window: int) -> tuple[str, ...]:
    """Per peak of `peaks` (``image.peaks(...)`` of `rec`, found once by the caller) the
    kind of traced path in its resolution cell ("" none, or no ground truth; `window`:
    the STFT window the image was made with, samples): the peak table's
    ``truth_kind`` (:func:`acousim.imaging.run.peak_table`), without the rest of it."""
    if rec.truth is None:
        return ("",) * len(peaks)
    from acousim.imaging.matching import image_resolution, match_peaks

    match = match_peaks(rec, peaks, image_resolution(rec, image, window))
    return tuple(str(kind) for kind in match.kind)


def reject_reason(real_above_floor_db: float, sim_truth_kind: str, has_truth: bool) -> str:
    """Why a pair is not a matched echo ("" when it is): ``"real under the noise
    floor"`` or ``"simulated peak not traced"``."""
    if not real_above_floor_db >= MIN_ECHO_ABOVE_FLOOR_DB:
        return "real under the noise floor"
    if has_truth and not sim_truth_kind:
        return "simulated peak not traced"
    return ""


@dataclass(frozen=True)
class MatchedEcho:
    """A peak of the real image paired with one of the simulated image: an echo both
    have.  `real_above_floor_db`: how far the real range profile at the real peak's
    range stands above its noise floor (dB); `sim_truth_kind`: the traced path the
    simulated peak shows (its peak table's ``truth_kind``; "" when the simulation
    has no ground truth to check it against)."""

    real: Peak
    sim: Peak
    real_above_floor_db: float = float("nan")
    sim_truth_kind: str = ""

    @property
    def d_range_m(self) -> float:
        return self.sim.range_m - self.real.range_m

    @property
    def d_azimuth_deg(self) -> float:
        return self.sim.azimuth_deg - self.real.azimuth_deg

    @property
    def d_elevation_deg(self) -> float:
        return self.sim.elevation_deg - self.real.elevation_deg

    @property
    def d_level_db(self) -> float:
        return self.sim.level_db - self.real.level_db

    def to_dict(self) -> dict:
        return {
            "real": asdict(self.real),
            "sim": asdict(self.sim),
            "d_range_m": self.d_range_m,
            "d_azimuth_deg": self.d_azimuth_deg,
            "d_elevation_deg": self.d_elevation_deg,
            "d_level_db": self.d_level_db,
            "real_above_noise_floor_db": self.real_above_floor_db,
            "sim_truth_kind": self.sim_truth_kind,
        }


@dataclass(frozen=True)
class RejectedPair:
    """Two peaks close enough to pair that are not an echo both have: `reason`
    (:func:`reject_reason`)."""

    pair: MatchedEcho
    reason: str

    def to_dict(self) -> dict:
        return {**self.pair.to_dict(), "reason": self.reason}
