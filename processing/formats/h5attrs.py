"""HDF5 attributes as the file readers meet them: one place that turns a value h5py
returns into text, whatever a hand-edited or foreign file put there (an array, a
number, bytes that are not UTF-8), so that every reader answers a malformed attribute
with its one-line error (naming the file and the key) instead of a traceback."""

from __future__ import annotations

__all__ = ["attribute_text"]


def attribute_text(value) -> str | None:
    """An attribute's value as text: a str, or bytes decoded as UTF-8 (undecodable
    bytes replaced); None for anything else (absent, an array, a number), which the
    caller reports as a wrong value. Never raises."""
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    return str(value) if isinstance(value, str) else None
