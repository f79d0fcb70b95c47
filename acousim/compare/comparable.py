"""Whether two recordings can be compared (:func:`acousim.compare.comparison.compare`):
the same array, sample rate, length and call; the message names what differs."""

from __future__ import annotations

import numpy as np

import processing as P
from processing.base.errors import InputError

__all__ = ["CALL_RTOL", "ComparisonError", "check_comparable", "same_call"]


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
    arrays, sample rates, lengths or calls."""
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
    if not same_call(real.waveform, sim.waveform):
        diffs.append(f"calls ({real.waveform.to_dict()} vs {sim.waveform.to_dict()})")
    if diffs:
        raise ComparisonError("the recordings differ in " + "; ".join(diffs))
