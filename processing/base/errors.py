"""One error type for bad input: a file, key, argument or value a user can fix.

Validation and loading raise :class:`InputError` (or a subclass) with the place
(file, key or argument) and the offending value; the command line catches this one
type in ``main()`` and prints it as a one-line error. Any other exception is a bug
and keeps its traceback.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["InputError", "UnitsWarning", "did_you_mean", "unknown_choice", "refuse_non_finite"]


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


class UnitsWarning(UserWarning):
    """A value that is legal but more likely in other units than the ones asked for
    (radians given as degrees, millimetres as metres); the message says what was
    probably meant."""


def _short(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def did_you_mean(value: str, choices: Iterable[str]) -> str | None:
    """The choice closest to a mistyped `value` (difflib, ratio >= 0.6; the
    case-insensitive match first), or None."""
    options = [str(c) for c in choices]
    text = str(value)
    for c in options:
        if c.lower() == text.lower():
            return c
    close = difflib.get_close_matches(text, options, n=1)
    if not close:  # 'capon_fbss' for 'capon-fbss': compare with separators unified
        unify = {c.replace("_", "-").lower(): c for c in options}
        close = [
            unify[c] for c in difflib.get_close_matches(text.replace("_", "-").lower(), unify, n=1)
        ]
    return close[0] if close else None


def unknown_choice(what: str, value: str, choices: Iterable[str], *, listed: int = 8) -> str:
    """The reason for an unknown name, without the name itself (the error shows the
    value once): "unknown scene; did you mean 'corridor'?" when one is close, else the
    choices when there are at most `listed`, else their number."""
    options = sorted(str(c) for c in choices)
    close = did_you_mean(value, options)
    if close is not None:
        return f"unknown {what}; did you mean {close!r}?"
    if len(options) <= listed:
        return f"unknown {what}; choose one of {', '.join(options)}"
    return (
        f"unknown {what}; none of the {len(options)} is close (e.g. {', '.join(options[:4])}, ...)"
    )


def refuse_non_finite(x: np.ndarray, key: str = "samples") -> None:
    """An InputError naming `key`, the count and the first non-finite sample of
    signals `x` (..., M, T) (its channel, sample and, for (K, M, T), measurement);
    nothing when every sample is finite (one pass without a copy; a sum that
    overflows is checked sample by sample)."""
    if x.size == 0 or np.isfinite(x.sum()):
        return
    bad = ~np.isfinite(x)
    if not bad.any():
        return
    where = np.argwhere(bad)[0]
    at = f"sample {int(where[-1])}"
    if x.ndim >= 2:
        at = f"channel {int(where[-2])}, {at}"
    if x.ndim == 3:
        at += f", measurement {int(where[0])}"
    elif x.ndim > 3:
        at += f", index {tuple(int(i) for i in where[:-2])}"
    raise InputError(
        f"{int(bad.sum())} non-finite sample(s); first at {at}",
        key=key,
        value=x[tuple(where)].item(),
    )
