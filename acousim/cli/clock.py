"""The command's clock: started first thing in main(), before the imports a command
needs (the processing package, numpy, scipy: seconds on a busy machine), so that the
time a command reports is its wall time from its start. Light: standard library only."""

from __future__ import annotations

import time

_clock = time.perf_counter  # the one clock of start() and elapsed() (a test may set it)
_started: float | None = None


def start() -> None:
    """Note when the command started (main() calls it first)."""
    global _started
    _started = _clock()


def now() -> float:
    """The clock's reading, s (for spans within the command)."""
    return _clock()


def elapsed() -> float:
    """Seconds since :func:`start`, wall time (since this call's first use if none)."""
    if _started is None:
        start()
    return _clock() - _started


def since_start() -> str:
    """The command's wall time since :func:`start` as its result line says it:
    "9.5 s from the start"."""
    return f"{elapsed():.1f} s from the start"


def from_start() -> str:
    """What a command's result line ends with: "(9.5 s from the start)", the one
    wording of every command (:func:`since_start`)."""
    return f"({since_start()})"
