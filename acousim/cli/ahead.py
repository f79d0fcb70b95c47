"""Work made ahead in a second process while the command does other work.

``acousim image`` makes its label maps (pure numpy, a fifth of a second per corridor
recording) in a forked process while it draws the stills and the animation, then
writes images.h5 with them: on the 2 cores of a laptop the two overlap.  The items
come back through a pipe, drained by a thread of this process as they come (so the
worker never waits for the reader), and are handed out in order.

The worker ignores Ctrl-C (the command's to handle, see
:func:`processing.base.interrupt.ignore_in_worker`) and is terminated when the block
ends, whatever ended it.  Where ``fork`` is not available, or on one CPU, the items
are made in this process when asked (the same items).
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import traceback
from collections.abc import Callable, Iterator
from typing import Any

from processing.base import interrupt

__all__ = ["ahead_in_a_process"]


@contextlib.contextmanager
def ahead_in_a_process(make: Callable[[], Iterator[Any]]) -> Iterator[Iterator[Any]]:
    """Start making the items of ``make()`` (an iterator of picklable items) in a
    forked process; yields an iterator over them, in order, each as soon as it is
    made (a RuntimeError with the worker's traceback if it failed)."""
    import multiprocessing as mp

    if "fork" not in mp.get_all_start_methods() or (os.cpu_count() or 1) < 2:
        yield make()
        return
    ctx = mp.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)
    worker = ctx.Process(target=_send_all, args=(make, send), daemon=True)
    worker.start()
    send.close()  # the worker's end: the pipe closes when the worker ends
    items: queue.Queue = queue.Queue()
    reader = threading.Thread(target=_receive_all, args=(receive, items), daemon=True)
    reader.start()
    try:
        yield _handed_out(items)
    finally:
        if worker.is_alive():
            worker.terminate()
        worker.join()
        reader.join()
        receive.close()


def _send_all(make: Callable[[], Iterator[Any]], send) -> None:
    """The worker: every item sent, then the end (or the error)."""
    interrupt.ignore_in_worker()
    try:
        for item in make():
            send.send(("item", item))
        send.send(("end", None))
    except BaseException:  # noqa: BLE001 (reported to the command, which raises it)
        with contextlib.suppress(OSError):  # the command gone: nobody to tell
            send.send(("error", traceback.format_exc()))
    finally:
        send.close()


def _receive_all(receive, items: queue.Queue) -> None:
    """The reader thread: what the worker sends, queued until the end or an error."""
    while True:
        try:
            message = receive.recv()
        except (EOFError, OSError):
            items.put(("error", "the worker process ended before its last item"))
            return
        items.put(message)
        if message[0] != "item":
            return


def _handed_out(items: queue.Queue) -> Iterator[Any]:
    """The items in order; Ctrl-C honoured while waiting for the next."""
    while True:
        try:
            kind, value = items.get(timeout=0.2)
        except queue.Empty:
            interrupt.check()
            continue
        if kind == "end":
            return
        if kind == "error":
            raise RuntimeError(f"work made in a second process failed:\n{value}")
        yield value
