"""The one loader of the optional compiled kernels (numba, the 'fast' extra).

Every kernel has a numpy twin that gives the same numbers; without numba the twin
runs.  ``optional_kernel("processing.imaging.doa_kernel", "floor_invert")`` is the compiled
function, or None when numba is not installed; the import (and numba's compilation
cache) is looked up once per kernel.
"""

from __future__ import annotations

import importlib
from functools import cache

__all__ = ["optional_kernel"]


@cache  # one entry per kernel: a handful
def optional_kernel(module: str, name: str | None = None):
    """The object `name` of the kernel module `module` (absolute; the module itself
    without `name`), or None when numba is missing."""
    try:
        found = importlib.import_module(module)
    except ImportError as exc:
        if exc.name != "numba" and not str(exc.name or "").startswith("numba."):
            raise  # a broken kernel module is a bug, not a missing extra
        return None
    return found if name is None else getattr(found, name)
