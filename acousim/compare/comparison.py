"""Simulated versus real: align two recordings of the same sensor and say how far
apart they are, at every stage of the pipeline (:func:`compare`, one module a step).

1. Alignment (:mod:`.alignment`): the time of emission from the direct emitter ->
   microphone path (the lag that best aligns the first milliseconds of the two
   matched-filter outputs, refined to a fraction of a sample), then one overall gain
   by least squares on the matched-filter envelopes after the direct path (the
   echoes).  Without a direct path in the simulation, the whole recording sets the
   lag.  Both are reported, never hidden.  Recordings of different lengths are
   compared over the first samples of the shorter (the report's ``span``).
2. Per channel (:mod:`.levels`): matched-filter envelopes (zero-padded Hilbert
   transform), their correlation and their level difference in dB along range.
3. Range profiles (mean envelope power over channels, :mod:`.levels`).
4. Images of the same methods; their peaks matched one to one
   (:mod:`.peaks`, :func:`scipy.optimize.linear_sum_assignment`), with the range,
   azimuth, elevation and level differences of each matched echo (:mod:`.echoes`,
   :mod:`.echo_table`).
5. Unmatched peaks within one STFT window in range of a stronger peak of the same
   image are that echo's side lobes (the window spreads one echo over the range
   bins it overlaps, and the array's beam pattern puts lobes beside it in angle):
   reported as side lobes with the array's own response there, not as echoes
   only one side has (:mod:`.lobes`).  What is left is listed as only in the
   real image or only in the simulation.

The results are typed (:class:`~.report.Comparison`,
:class:`~acousim.compare.summary.TrajectorySummary`); their ``to_dict()`` is what
``comparison.json`` and ``summary.json`` hold; :func:`write_comparison` writes the
report and its picture (:mod:`.figure`).  Whether two recordings can be compared
is :mod:`.comparable`; loading what the command line is given and pairing each real
recording with its simulation, :mod:`acousim.compare.inputs`.  The names this module
held before its steps had modules of their own stay importable from here (the
``name as name`` imports).
"""

from __future__ import annotations

import json
from pathlib import Path

import processing as P
from acousim.compare.account import floor_start as floor_start
from acousim.compare.account import noise_floor
from acousim.compare.alignment import DIRECT_WINDOW_S as DIRECT_WINDOW_S
from acousim.compare.alignment import (
    Alignment,
    align,
    align_envelopes,
    aligned_recording,
    envelope,
    matched_filter_output,
)
from acousim.compare.comparable import CALL_RTOL as CALL_RTOL
from acousim.compare.comparable import ComparisonError, check_comparable, common_span
from acousim.compare.comparable import same_call as same_call
from acousim.compare.echo_table import MethodComparison, method_comparison
from acousim.compare.echoes import (
    MIN_ECHO_ABOVE_FLOOR_DB,
    MatchedEcho,
    RejectedPair,
    above_floor,
)
from acousim.compare.echoes import reject_reason as reject_reason
from acousim.compare.echoes import traced_kinds as traced_kinds
from acousim.compare.figure import COMPARISON_RANGE_DB as COMPARISON_RANGE_DB
from acousim.compare.figure import comparison_figure
from acousim.compare.levels import envelope_correlation, range_profiles
from acousim.compare.lobes import SideLobe
from acousim.compare.lobes import array_response_db as array_response_db
from acousim.compare.lobes import side_lobes as side_lobes
from acousim.compare.peaks import MatchTolerance as MatchTolerance
from acousim.compare.peaks import Peak
from acousim.compare.peaks import match_peaks as match_peaks
from acousim.compare.report import Comparison, ComparisonArrays
from processing.base.atomic import atomic_path, write_text

__all__ = [
    "ComparisonError",
    "check_comparable",
    "align",
    "envelope",
    "compare",
    "write_comparison",
    "comparison_figure",
    "noise_floor",
    "Peak",
    "MatchedEcho",
    "RejectedPair",
    "MIN_ECHO_ABOVE_FLOOR_DB",
    "SideLobe",
    "MethodComparison",
    "Alignment",
    "Comparison",
    "ComparisonArrays",
]


def compare(
    real: P.Recording,
    sim: P.Recording,
    methods=("das",),
    settings: P.ProcessingSettings | None = None,
    threshold_db: float = -12.0,
    range_bin_m: float = 0.05,
) -> tuple[Comparison, ComparisonArrays]:
    """Compare two recordings (the steps of the module docstring) over their common
    span (:func:`~acousim.compare.comparable.common_span`: the first samples of the
    shorter, said in the report's ``span``).  Returns what was measured and what the
    picture draws."""
    check_comparable(real, sim)
    real, sim, span = common_span(real, sim)
    for rec in (real, sim):  # before the matched filters: an InputError, not a MemoryError
        P.check_memory(rec, methods, settings)
    env = align_envelopes(real, matched_filter_output(real), matched_filter_output(sim))
    fs, c = real.sample_rate_hz, real.speed_of_sound_m_s
    aligned = aligned_recording(sim, env.alignment)
    rng = real.time_s() * c / 2
    profiles = range_profiles(rng, env.real, env.sim, range_bin_m)
    settings = settings or P.ProcessingSettings(
        energy_fraction=0.3,
        range_limits_m=(0.3, float(rng[-1])),
        grid=P.Grid.degrees((-90, 90), (-60, 60), 2),
    )
    # one echo spreads over the range bins of every STFT window that overlaps it
    extent_m = settings.window / fs * c / 2
    images_r = P.acoustic_images(real, methods, settings)
    images_s = P.acoustic_images(aligned, methods, settings)
    above = above_floor(profiles.edges_m, profiles.real, extent_m)
    per_method = {
        m: method_comparison(
            m,
            (real, images_r[m]),
            (aligned, images_s[m]),
            above=above,
            threshold_db=threshold_db,
            extent_m=extent_m,
            window=settings.window,
        )
        for m in methods
    }
    report = Comparison(
        alignment=env.alignment,
        envelope_correlation=envelope_correlation(env.real, env.sim),
        range_bin_m=range_bin_m,
        level_difference_db=tuple(profiles.level_difference_db.tolist()),
        images=per_method,
        span=span,
    )
    arrays = ComparisonArrays(profiles.edges_m, profiles.real, profiles.sim, images_r, images_s)
    return report, arrays


def write_comparison(
    report: Comparison, arrays: ComparisonArrays, out_dir: str | Path
) -> list[Path]:
    """The JSON report and a side-by-side picture (:func:`comparison_figure`), written
    atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    js = write_text(out / "comparison.json", json.dumps(report.to_dict(), indent=1))
    fig = comparison_figure(report, arrays)
    png = out / "comparison.png"
    with atomic_path(png) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
    return [js, png]
