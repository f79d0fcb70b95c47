"""Simulated versus real recordings of the same sensor: aligned, imaged alike, their echoes
matched (:mod:`.comparison`); the real recordings read (:mod:`.inputs`); a trajectory's
comparisons summed up (:mod:`.summary`)."""

from acousim.compare.comparison import (
    Alignment,
    Comparison,
    ComparisonArrays,
    ComparisonError,
    MatchedEcho,
    MethodComparison,
    Peak,
    SideLobe,
    align,
    check_comparable,
    compare,
    envelope,
    write_comparison,
)

__all__ = [
    "ComparisonError",
    "check_comparable",
    "align",
    "envelope",
    "compare",
    "write_comparison",
    "Peak",
    "MatchedEcho",
    "SideLobe",
    "MethodComparison",
    "Alignment",
    "Comparison",
    "ComparisonArrays",
]
