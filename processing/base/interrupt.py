"""Ctrl-C as a request that the work honours at its next checkpoint.

Raising ``KeyboardInterrupt`` from inside a signal handler cannot be made safe: the
exception lands wherever the interpreter happens to be, for instance in a
weak-reference callback that the garbage collector runs, where Python prints
"Exception ignored" and carries on (a run that went on to the end and replaced its
output after the user had asked it to stop). So the command line installs
:func:`handler` for SIGINT (process-wide state: only the command line does, at its
entry, see :func:`installed`); the handler only records the request. The work calls
:func:`check` at its checkpoints (between poses, images, shards, measurements,
picture frames, and before any output file is renamed into place, see
:mod:`processing.base.atomic`), which raises ``KeyboardInterrupt`` there, where every
``finally`` and ``except`` is ready for it.

Without the handler (a library user's process) Python's default handler raises
``KeyboardInterrupt`` as usual and :func:`check` costs one global read.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = ["handler", "requested", "check", "consume", "reset", "installed", "ignore_in_worker"]

_requested = False


def handler(signum, frame) -> None:  # noqa: ARG001 (a signal handler's signature)
    """SIGINT handler: record the request, nothing else (it never raises)."""
    global _requested
    _requested = True


def requested() -> bool:
    """True once Ctrl-C came (and was not consumed)."""
    return _requested


def check() -> None:
    """A checkpoint: raise ``KeyboardInterrupt`` if Ctrl-C came."""
    if _requested:
        raise KeyboardInterrupt


def consume() -> bool:
    """Whether Ctrl-C came, clearing the request (for work that stops on the first
    Ctrl-C and then still saves what it kept, as ``acousim record``)."""
    global _requested
    was, _requested = _requested, False
    return was


def reset() -> None:
    """Forget any earlier request."""
    global _requested
    _requested = False


@contextlib.contextmanager
def installed() -> Iterator[None]:
    """Install :func:`handler` for SIGINT for the block (main thread only; elsewhere
    nothing changes), restoring the previous handler after it."""
    reset()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def ignore_in_worker() -> None:
    """Pool worker initializer: Ctrl-C is the main process's to handle (a terminal
    sends it to the whole process group; a worker that raised it would print its own
    traceback and break the pool)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    reset()
