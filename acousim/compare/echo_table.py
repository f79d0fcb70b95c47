"""One imaging method's echo table (steps 4 and 5 of :mod:`acousim.compare.comparison`):
the peaks of the real and the simulated image paired one to one
(:func:`acousim.compare.peaks.match_peaks`), each pair kept as a matched echo or
rejected (:mod:`acousim.compare.echoes`), the unpaired peaks near a stronger one told
as side lobes (:mod:`acousim.compare.lobes`), and the rest listed as only in the
real image or only in the simulation."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import processing as P
from acousim.compare.echoes import (
    MIN_ECHO_ABOVE_FLOOR_DB,
    MatchedEcho,
    RejectedPair,
    reject_reason,
    traced_kinds,
)
from acousim.compare.lobes import SideLobe, side_lobes
from acousim.compare.peaks import Peak, image_peaks, match_peaks, peak_array

__all__ = ["MethodComparison", "method_comparison"]


@dataclass(frozen=True)
class MethodComparison:
    """The peaks of one method's two images: matched echoes, side lobes, the rest."""

    method: str
    matched: tuple[MatchedEcho, ...]
    only_real: tuple[Peak, ...]
    only_sim: tuple[Peak, ...]
    side_lobes_real: tuple[SideLobe, ...]
    side_lobes_sim: tuple[SideLobe, ...]
    range_bin_m: float
    rejected: tuple[RejectedPair, ...] = ()
    sim_has_truth: bool = True
    real_max_above_floor_db: float = float("nan")
    only_real_above_floor: int = 0

    def to_dict(self) -> dict:
        return {
            "matched": [m.to_dict() for m in self.matched],
            "rejected_pairs": [r.to_dict() for r in self.rejected],
            "sim_has_truth": self.sim_has_truth,
            "min_echo_above_noise_floor_db": MIN_ECHO_ABOVE_FLOOR_DB,
            "real_max_above_noise_floor_db": self.real_max_above_floor_db,
            "only_real_above_noise_floor": self.only_real_above_floor,
            "only_real": [asdict(p) for p in self.only_real],
            "only_sim": [asdict(p) for p in self.only_sim],
            "side_lobes_real": [s.to_dict() for s in self.side_lobes_real],
            "side_lobes_sim": [s.to_dict() for s in self.side_lobes_sim],
            "range_bin_m": self.range_bin_m,
        }


def method_comparison(
    method: str,
    real: tuple[P.Recording, P.Image],
    sim: tuple[P.Recording, P.Image],
    *,
    above: Callable[[float], float],
    threshold_db: float,
    extent_m: float,
    window: int,
) -> MethodComparison:
    """The peaks (within `threshold_db` of each image's maximum) of `method`'s images
    compared: `real`, `sim` (recording, image) (the simulation aligned);
    `above(range_m)`: the real profile's margin over its noise floor there (dB);
    `extent_m`: one STFT window in range (m), `window` in samples."""
    (rec_r, img_r), (rec_s, img_s) = real, sim
    c = rec_r.speed_of_sound_m_s
    found_s = img_s.peaks(threshold_db)  # once: the peaks and their traced kinds
    a, b = image_peaks(img_r.peaks(threshold_db)), image_peaks(found_s)
    pairs, only_r, only_s = match_peaks(peak_array(a), peak_array(b))
    f = img_r.frequency_hz
    lobes_r, only_r = side_lobes(a, only_r, extent_m, rec_r.array, f, c)
    lobes_s, only_s = side_lobes(b, only_s, extent_m, rec_s.array, f, c)
    kinds = traced_kinds(rec_s, img_s, found_s, window)
    has_truth = rec_s.truth is not None
    found = [MatchedEcho(a[i], b[j], above(a[i].range_m), kinds[j]) for i, j in pairs]
    why = [reject_reason(e.real_above_floor_db, e.sim_truth_kind, has_truth) for e in found]
    return MethodComparison(
        method=method,
        matched=tuple(e for e, r in zip(found, why) if not r),
        rejected=tuple(RejectedPair(e, r) for e, r in zip(found, why) if r),
        sim_has_truth=has_truth,
        real_max_above_floor_db=max((above(p.range_m) for p in a), default=float("nan")),
        only_real_above_floor=sum(above(a[i].range_m) >= MIN_ECHO_ABOVE_FLOOR_DB for i in only_r),
        only_real=tuple(a[i] for i in only_r),
        only_sim=tuple(b[j] for j in only_s),
        side_lobes_real=tuple(lobes_r),
        side_lobes_sim=tuple(lobes_s),
        range_bin_m=img_r.bin_range_m,
    )
