"""Simulated versus real recordings of the same sensor: aligned, imaged alike, their echoes
matched (:mod:`.comparison`, a module a step: :mod:`.comparable`, :mod:`.alignment`,
:mod:`.levels`, :mod:`.peaks`, :mod:`.lobes`, :mod:`.echoes`, :mod:`.echo_table`,
:mod:`.report`, :mod:`.figure`; what was fitted and predicted, :mod:`.account`); the real
recordings read (:mod:`.inputs`); a trajectory's comparisons summed up (:mod:`.summary`)."""

import importlib
import importlib.util


def __getattr__(name: str) -> object:
    """The names of :mod:`acousim.compare.comparison` (this package was that one module before the
    re-layout by concept: ``from acousim.compare import ...`` keeps working)."""
    if importlib.util.find_spec(f"{__name__}.{name}") is not None:
        return importlib.import_module(f"{__name__}.{name}")  # a module of the package
    return getattr(importlib.import_module("acousim.compare.comparison"), name)
