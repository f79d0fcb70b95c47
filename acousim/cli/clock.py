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
