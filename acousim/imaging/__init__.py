"""Imaging recordings and writing what ``acousim image`` writes: images, peaks matched to the
traced reflectors (:mod:`.matching`), the pictures (:mod:`.run`), the output folder's
bookkeeping (:mod:`.outputs`)."""

import importlib
import importlib.util


def __getattr__(name: str) -> object:
    """The names of :mod:`acousim.imaging.run` (this package was that one module before the
    re-layout by concept: ``from acousim.imaging import ...`` keeps working)."""
    if importlib.util.find_spec(f"{__name__}.{name}") is not None:
        return importlib.import_module(f"{__name__}.{name}")  # a module of the package
    return getattr(importlib.import_module("acousim.imaging.run"), name)
