"""Optional compiled kernels: one loader for every numba module of the project.

A kernel module (``_*kernel.py``) imports numba at its top; numba is optional (the
``fast`` extra), so a caller asks :func:`compiled` for the module and falls back to
its numpy path when it gets None.  The import (and numba's compilation cache) is
paid once per process.
"""

from __future__ import annotations

import importlib
from functools import cache
from types import ModuleType

__all__ = ["compiled"]


@cache
def compiled(module: str) -> ModuleType | None:
    """The kernel module `module` (a dotted name), or None when numba is not
    installed."""
    try:
        return importlib.import_module(module)
    except ImportError:  # numba is optional (the 'fast' extra)
        return None
