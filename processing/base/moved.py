"""Modules that moved keep their old import names for one version, with a warning.

The re-layout by concept (CHANGELOG, 0.x) moved modules into folders
(``processing.doa`` -> ``processing.imaging.doa``).  A script that imports an old
name still works: :func:`alias_modules` registers an import hook that answers the old
name with the new module itself (the same object, so ``isinstance`` and monkeypatching
see one module) and raises a :class:`DeprecationWarning` naming the new one.  The hook
only answers the names it was given; it changes nothing else of the import system.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
from collections.abc import Mapping

from processing.base.api import warn_deprecated


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Answers old module names with the modules they moved to."""

    def __init__(self, moved: Mapping[str, str]) -> None:
        self.moved = dict(moved)

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in self.moved:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        new = self.moved[spec.name]
        warn_deprecated(
            f"module {spec.name!r} moved to {new!r}; the old name goes in the next version"
        )
        return importlib.import_module(new)

    def exec_module(self, module) -> None:
        """The new module is already executed: nothing to run."""


def alias_modules(moved: Mapping[str, str]) -> None:
    """Let each old module name (key) import as its new module (value), warning once."""
    if not any(isinstance(f, _MovedFinder) and f.moved == dict(moved) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder(moved))


def moved_spec(fullname: str, moved: Mapping[str, str]):
    """The module spec that answers old name `fullname` from the table `moved` (for a
    package whose own import must stay light: it asks here only when an old name is
    imported)."""
    return _MovedFinder(moved).find_spec(fullname)
