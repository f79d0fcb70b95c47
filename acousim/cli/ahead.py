"""Work made ahead in a second process while the command does other work.

``acousim image`` writes images.h5 and peaks.csv (the label maps, the compression:
numpy, scipy, zlib) in a forked process while it draws the stills and the
animation: on the 2 cores of a laptop the two overlap.  The worker's items (there:
its progress) come back through a pipe, drained by a thread of this process as they
come (so the worker never waits for the reader), and are handed out in order.

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
    made; what the worker raised is raised when its item is asked for (the same
    exception, its traceback there as a note; a RuntimeError if it does not pickle)."""
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
    except BaseException as exc:  # noqa: BLE001 (sent to the command, which raises it)
        text = traceback.format_exc()
        with contextlib.suppress(OSError):  # the command gone: nobody to tell
            try:
                send.send(("error", (exc, text)))
            except Exception:  # noqa: BLE001 (an exception that does not pickle)
                send.send(("error", (None, text)))
    finally:
        send.close()


def _receive_all(receive, items: queue.Queue) -> None:
    """The reader thread: what the worker sends, queued until the end or an error."""
    while True:
        try:
            message = receive.recv()
        except (EOFError, OSError):
            items.put(("error", (None, "the worker process ended before its last item")))
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
            exc, text = value
            if exc is None:
                raise RuntimeError(f"work made in a second process failed:\n{text}")
            exc.add_note(f"(raised in a second process:)\n{text}")
            raise exc
        yield value
