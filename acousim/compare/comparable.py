"""Whether two recordings can be compared (:func:`acousim.compare.comparison.compare`):
the same array, sample rate and call; the message names what differs.  Recordings of
different lengths (a real sensor's frame and a simulation's) are compared over their
common span, the first samples of the shorter (:func:`common_span`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import processing as P
from processing.base.errors import InputError

__all__ = [
    "CALL_RTOL",
    "ComparisonError",
    "Span",
    "check_comparable",
    "common_span",
    "same_call",
]


class ComparisonError(InputError):
    """The two recordings cannot be compared; the message names what differs."""


CALL_RTOL = 1e-3
"""Two calls are the same when of one kind with frequencies and durations within this
(relative) and tapers within 0.01: a call fitted to a CHIRP file's transmitter
samples (:func:`processing.sensor.calls.fit_sweep`) is the preset within 1e-6. Their
amplitudes are a gain, which the alignment estimates."""


def same_call(a: P.Waveform, b: P.Waveform) -> bool:
    """Whether two calls are the same within :data:`CALL_RTOL`."""
    pairs = [(a.f_start_hz, b.f_start_hz), (a.f_end_hz, b.f_end_hz), (a.duration_s, b.duration_s)]
    return (
        a.kind == b.kind
        and all(abs(x - y) <= CALL_RTOL * abs(y) for x, y in pairs)
        and abs(a.taper - b.taper) <= 0.01
    )


def check_comparable(real: P.Recording, sim: P.Recording) -> None:
    """Raise :class:`ComparisonError` naming every way `real` and `sim` differ: their
    arrays, sample rates or calls.  Their lengths may differ (:func:`common_span`)."""
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
    late = _late_emissions(real, sim)
    if late:
        diffs.append(f"emissions ({late})")
    if not same_call(real.waveform, sim.waveform):
        diffs.append(f"calls ({real.waveform.to_dict()} vs {sim.waveform.to_dict()})")
    if diffs:
        raise ComparisonError("the recordings differ in " + "; ".join(diffs))


def _late_emissions(real: P.Recording, sim: P.Recording) -> str:
    """Which emissions fall at or after the end of the common span (the shorter
    recording's length), with their samples, as the refusal says it; "" for none."""
    n = min(real.n_samples, sim.n_samples)
    late = [
        f"{k} at sample {r.emission_index}"
        for k, r in (("real", real), ("sim", sim))
        if r.emission_index >= n
    ]
    if not late:
        return ""
    return f"{', '.join(late)}, after the common span's {n} samples: nothing to compare"


@dataclass(frozen=True)
class Span:
    """What was compared: the first `samples` samples of both recordings (the shorter's
    length), of `real_samples` and `sim_samples`; `range_m` (m) is the range of the
    last compared sample after the real recording's emission."""

    samples: int
    real_samples: int
    sim_samples: int
    range_m: float

    @property
    def trimmed(self) -> bool:
        """Whether the recordings differ in length (one was cut to the other's)."""
        return self.real_samples != self.sim_samples

    def describe(self) -> str:
        """One line for the report: the common span, and the two lengths if they differ."""
        line = f"compared over the first {self.samples} samples ({self.range_m:.2f} m)"
        if self.trimmed:
            line += (
                f": the real recording has {self.real_samples}, the simulated one "
                f"{self.sim_samples}"
            )
        return line

    def to_dict(self) -> dict:
        return {
            "samples": self.samples,
            "range_m": self.range_m,
            "real_samples": self.real_samples,
            "sim_samples": self.sim_samples,
            "note": "both recordings are compared over their first `samples` samples "
            "(the shorter's length); range_m is the last one's range",
        }


def common_span(real: P.Recording, sim: P.Recording) -> tuple[P.Recording, P.Recording, Span]:
    """`real` and `sim` cut to the shorter's length (T samples each) and the
    :class:`Span` that says so; a recording already that long is returned as it is.
    Raises :class:`ComparisonError` when an emission falls outside the common span."""
    n = min(real.n_samples, sim.n_samples)
    late = _late_emissions(real, sim)
    if late:
        raise ComparisonError(f"the recordings differ in emissions ({late})")
    cut = [
        rec if rec.n_samples == n else rec.with_samples(rec.samples[..., :n]) for rec in (real, sim)
    ]
    rng = (n - 1 - real.emission_index) / real.sample_rate_hz * real.speed_of_sound_m_s / 2
    return cut[0], cut[1], Span(n, real.n_samples, sim.n_samples, float(rng))
