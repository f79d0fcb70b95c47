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

from processing.base.api import check_keywords  # noqa: E402

check_keywords(globals(), __all__)  # a misspelled keyword: the scene file's answer
