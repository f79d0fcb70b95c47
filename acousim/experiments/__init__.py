"""The paper's simulation study (section IV), reproduced."""

from .paper_study import StudyConfig, run_study

__all__ = ["StudyConfig", "run_study"]
