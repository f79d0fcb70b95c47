"""Imaging recordings and writing what ``acousim image`` writes: images, peaks matched to the
traced reflectors (:mod:`.matching`), the pictures (:mod:`.run`), the output folder's
bookkeeping (:mod:`.outputs`)."""

import importlib


def __getattr__(name: str) -> object:
    """The names of :mod:`acousim.imaging.run` (this package was that one module before the
    re-layout by concept: ``from acousim.imaging import ...`` keeps working)."""
    return getattr(importlib.import_module("acousim.imaging.run"), name)
