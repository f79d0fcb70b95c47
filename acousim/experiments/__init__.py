"""The paper's simulation study (section IV), reproduced."""

from acousim.experiments.paper_study import (
    Attenuation,
    PulseNumbers,
    Resolution,
    SourceCount,
    StudyConfig,
    StudyResults,
    load_results,
    run_study,
)

__all__ = [
    "Attenuation",
    "PulseNumbers",
    "Resolution",
    "SourceCount",
    "StudyConfig",
    "StudyResults",
    "load_results",
    "run_study",
]
