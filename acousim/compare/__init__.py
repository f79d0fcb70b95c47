"""Simulated versus real recordings of the same sensor: aligned, imaged alike, their echoes
matched (:mod:`.comparison`); the real recordings read (:mod:`.inputs`); a trajectory's
comparisons summed up (:mod:`.summary`)."""

import importlib


def __getattr__(name: str) -> object:
    """The names of :mod:`acousim.compare.comparison` (this package was that one module before the
    re-layout by concept: ``from acousim.compare import ...`` keeps working)."""
    return getattr(importlib.import_module("acousim.compare.comparison"), name)
