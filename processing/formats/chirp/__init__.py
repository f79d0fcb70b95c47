"""CHIRP files: Cosys-Lab's HDF5 format for in-air sonar datasets, written
(:mod:`.write`) and read (:mod:`.read`); the group and attribute names both share
(:mod:`.names`).  Registered in :mod:`processing.formats.registry` as ``chirp``: it
provides ``claims``, ``read`` and ``count``."""

from processing.formats.chirp import names
from processing.formats.chirp.names import ChirpFileError
from processing.formats.chirp.read import count_chirp, is_chirp, read_chirp
from processing.formats.chirp.write import DEFAULT_PERIOD_S, FORMAT_VERSION, write_chirp

__all__ = [
    "ChirpFileError",
    "DEFAULT_PERIOD_S",
    "FORMAT_VERSION",
    "write_chirp",
    "read_chirp",
    "is_chirp",
    "count_chirp",
    "claims",
    "read",
    "count",
]

claims = is_chirp
count = count_chirp


def read(path, *, call=None, max_bytes, index=None):
    """The recordings of a CHIRP file (all, or only recording `index`): the registry's
    reader (:func:`read_chirp`)."""
    return read_chirp(path, call=call, max_bytes=max_bytes, index=index)


def __getattr__(name: str) -> object:
    """The layout's group names (``ACOUSTIC``, ``OURS``, ...: :mod:`.names`), as the
    former ``processing.chirp`` module gave them."""
    try:
        return getattr(names, name)
    except AttributeError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
