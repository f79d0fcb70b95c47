"""What a comparison fitted and what it predicted (:func:`acousim.compare.comparison.compare`).

The alignment fits two numbers to the pair itself: the emission time (a shift of the
simulation) and one gain (least squares on the envelopes after the direct path).
A scene placed on an echo of the real recording (``ertis_sample``'s plate is put
where the sample's clear echo is) agrees with it on that echo by construction: that
echo's range, angle and, with the gain, its level test nothing (said only when the
comparison has a matched echo: a real peak above the noise floor where the
simulation traced a path). What the placement
and the fit did not touch is the test: the other echoes, the noise floor and the
side lobes. :func:`account` gathers those numbers; :meth:`FitAccount.lines` says them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FitAccount", "MethodAccount", "account", "floor_start", "noise_floor", "noise_floor_db"]

#: the noise floor is read over this last fraction of the range profile's bins
FLOOR_FRACTION = 0.25


@dataclass(frozen=True)
class MethodAccount:
    """One imaging method: the strongest matched echo (the one a placed scene fits by
    construction) and what the fit did not touch. Ranges in m, levels in dB, counts."""

    method: str
    strongest_range_m: float | None
    other_matched: int
    other_median_abs_d_range_m: float | None
    other_median_abs_d_level_db: float | None
    only_real: int
    only_sim: int
    side_lobes_real: int
    side_lobes_sim: int
    side_lobe_excess_real_db: float | None
    side_lobe_excess_sim_db: float | None


@dataclass(frozen=True)
class FitAccount:
    """The fitted numbers (shift in samples, gain real/sim) and the predicted ones:
    noise floors in dB re the strongest bin of the real range profile, read as the
    median over `floor_from_m`..`floor_to_m`; per method a :class:`MethodAccount`."""

    shift_samples: float
    gain: float
    floor_real_db: float
    floor_sim_db: float
    floor_from_m: float
    floor_to_m: float
    methods: tuple[MethodAccount, ...]

    def lines(self) -> list[str]:
        """The account as the command line prints it."""
        out = [
            f"fitted to this pair: the emission time (shift {self.shift_samples:.2f} samples) "
            f"and one gain ({self.gain:.3g}, on the envelopes after the direct path); every "
            "simulated level is scaled by that gain",
        ]
        placed = [m for m in self.methods if m.strongest_range_m is not None]
        if placed:  # only where the scene has an echo the recording has too
            out.append(
                "if the scene was placed on an echo of this recording (as ertis_sample's "
                "plate is), it agrees on that echo by construction (the strongest matched "
                f"one, {placed[0].strongest_range_m:.3f} m: range, angle and, with the gain, "
                "level): that echo tests nothing"
            )
        out += [
            "predicted, not fitted:",
            f"  noise floor (median {self.floor_from_m:.2f}-{self.floor_to_m:.2f} m, dB re "
            f"the real profile's strongest bin): real {self.floor_real_db:.1f} dB, simulated "
            f"{self.floor_sim_db:.1f} dB ({self.floor_real_db - self.floor_sim_db:+.1f} dB)",
        ]
        for m in self.methods:
            out.append(f"  {m.method}: {_others(m)}; {_lobes(m)}")
        return out


def _others(m: MethodAccount) -> str:
    if m.strongest_range_m is None:
        head = "no matched echo"
    else:
        head = f"besides the strongest matched echo ({m.strongest_range_m:.3f} m)"
    if m.other_matched:
        head += (
            f" {m.other_matched} other matched echo(es) (median |d_range| "
            f"{m.other_median_abs_d_range_m * 100:.1f} cm, median |d_level| "
            f"{m.other_median_abs_d_level_db:.1f} dB)"
        )
    elif m.strongest_range_m is not None:
        head += " no other matched echo"
    return f"{head}, {m.only_real} only in the real image, {m.only_sim} only in the simulation"


def _lobes(m: MethodAccount) -> str:
    def excess(v: float | None) -> str:
        return "" if v is None else f", median {v:+.1f} dB re the array's beam pattern"

    return (
        f"side lobes: {m.side_lobes_real} real{excess(m.side_lobe_excess_real_db)}, "
        f"{m.side_lobes_sim} simulated{excess(m.side_lobe_excess_sim_db)}"
    )


def floor_start(n_bins: int) -> int:
    """The first of a range profile's bins (of `n_bins`) its noise floor is read over:
    its last FLOOR_FRACTION (at least one bin)."""
    return min(int(n_bins * (1 - FLOOR_FRACTION)), max(n_bins - 1, 0))


def noise_floor(profile: np.ndarray) -> float:
    """A range profile's (B,) noise floor, in its own units (linear power): the median
    of its last FLOOR_FRACTION of bins, beyond the echoes of a scene placed ahead (the
    one definition: the command's account and the picture's lines); 0 when empty."""
    profile = np.asarray(profile, float)
    return float(np.median(profile[floor_start(len(profile)) :])) if profile.size else 0.0


def noise_floor_db(profile: np.ndarray, reference: float) -> float:
    """:func:`noise_floor` of a range profile (B,) (linear power) in dB re `reference`
    (linear power)."""
    return float(10 * np.log10(noise_floor(profile) / reference + 1e-30))


def _excess(lobes) -> float | None:
    """Median of (side lobe's level re its parent) minus the beam pattern there, dB."""
    if not lobes:
        return None
    return float(np.median([s.peak.level_db - s.of.level_db - s.array_response_db for s in lobes]))


def _method(name: str, r) -> MethodAccount:
    matched = sorted(r.matched, key=lambda p: p.real.level_db, reverse=True)
    others = matched[1:]
    return MethodAccount(
        method=name,
        strongest_range_m=matched[0].real.range_m if matched else None,
        other_matched=len(others),
        other_median_abs_d_range_m=(
            float(np.median([abs(p.d_range_m) for p in others])) if others else None
        ),
        other_median_abs_d_level_db=(
            float(np.median([abs(p.d_level_db) for p in others])) if others else None
        ),
        only_real=len(r.only_real),
        only_sim=len(r.only_sim),
        side_lobes_real=len(r.side_lobes_real),
        side_lobes_sim=len(r.side_lobes_sim),
        side_lobe_excess_real_db=_excess(r.side_lobes_real),
        side_lobe_excess_sim_db=_excess(r.side_lobes_sim),
    )


def account(report, arrays) -> FitAccount:
    """The :class:`FitAccount` of a comparison (`report`, `arrays`: what
    :func:`acousim.compare.comparison.compare` returned)."""
    edges, real, sim = arrays.edges_m, arrays.profile_real, arrays.profile_sim
    reference = float(np.max(real)) or 1.0
    start = floor_start(len(real))
    return FitAccount(
        shift_samples=report.alignment.emission_shift_samples,
        gain=report.alignment.gain,
        floor_real_db=noise_floor_db(real, reference),
        floor_sim_db=noise_floor_db(sim, reference),
        floor_from_m=float(edges[start]),
        floor_to_m=float(edges[-1]),
        methods=tuple(_method(m, r) for m, r in report.images.items()),
    )
