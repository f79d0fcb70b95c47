"""One error type for bad input: a file, key, argument or value a user can fix.

Validation and loading raise :class:`InputError` (or a subclass) with the place
(file, key or argument) and the offending value; the command line catches this one
type in ``main()`` and prints it as a one-line error. Any other exception is a bug
and keeps its traceback.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["InputError"]


class InputError(ValueError):
    """Bad input from a user: the message names the file, key or argument and the value.

    Parameters
    ----------
    message : str
        What is wrong and, where useful, what would be accepted.
    file : path, optional
        The file the input came from.
    key : str, optional
        The key (``"sensor.pose.yaw_deg"``), HDF5 field or command-line argument
        (``"--step"``).
    value : any, optional
        The offending value (shown with ``repr``).
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        key: str | None = None,
        value: Any = ...,
    ) -> None:
        self.file = None if file is None else str(file)
        self.key = key
        self.value = value
        self.reason = message
        parts = []
        if self.file is not None:
            parts.append(self.file)
        if key is not None:
            parts.append(key if value is ... else f"{key} = {_short(value)}")
        elif value is not ...:
            parts.append(_short(value))
        super().__init__(": ".join([*parts, message]) if parts else message)


def _short(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
