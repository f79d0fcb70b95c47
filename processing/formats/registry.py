"""Which format a recording file is in, and who reads it: one line a format.

Our own HDF5 format (:mod:`processing.formats.native`) is the default; every other
format is a module listed in :data:`FORMATS` that provides three functions:

- ``claims(path) -> bool``: whether the file is in this format (cheap: its header);
- ``read(path, *, call, max_bytes, index) -> list[Recording]``: all its recordings, or
  only recording `index`, every field checked (``call``: the emitted call for a file
  that does not say it; ``max_bytes``: the largest sample block read);
- ``count(path) -> int``: how many recordings ``read`` returns.

Adding a format is one module and one line here; :func:`processing.formats.native.load_recordings`
and its siblings ask :func:`reader_of` and never name a format.  Modules are imported
when a file is first asked about, so ``import processing`` stays light.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

#: name -> the module that reads it (in the order they are asked)
FORMATS: dict[str, str] = {
    "chirp": "processing.formats.chirp",
}


def reader_of(path: str | Path) -> ModuleType | None:
    """The module of the registered format that claims `path`, or None (our own format)."""
    for module in FORMATS.values():
        reader = importlib.import_module(module)
        if reader.claims(Path(path)):
            return reader
    return None
