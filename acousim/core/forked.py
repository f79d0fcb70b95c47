"""Work made in a second, forked process while this one does other work.

``Simulator.run`` makes its recordings in two processes, each taking the next pose
not yet taken (:func:`shared_by_two_processes`); ``acousim image`` reads and images
its recordings the same way, then draws its pictures, and with ``--images-h5``
writes images.h5 (the label maps, the compression) in a forked worker meanwhile
(:func:`ahead_in_a_process`): on the 2 cores of a laptop the work overlaps.  A
forked worker has its parent's memory as it was (its caches, its compiled kernels)
but none of its threads: what it runs must start its own (:func:`can_fork` says
when forking is allowed at all).  A worker's items come back
through a socket pair, drained by a thread of this process as they come, and are
handed out in order.  An item's numpy arrays travel out of band (pickle protocol 5):
those of :data:`SHARED_BYTES` or more as in-memory files (Linux's memfd, mapped
here, never read through the socket), the others with the pickle in one
``recv_into`` that waits for all its bytes: the reader thread takes the interpreter
a few times a message, not once per 64 kB as a pipe's reader would (which, beside a
busy main thread, waits up to the switch interval, 5 ms, each time).

The worker ignores Ctrl-C (the command's to handle, see
:func:`processing.base.interrupt.ignore_in_worker`) and is terminated when the block
ends, whatever ended it.  Where ``fork`` is not available or not safe (not Linux),
or on one CPU, the items are made in this process when asked (the same items).
"""

from __future__ import annotations

import contextlib
import itertools
import mmap
import os
import pickle
import queue
import socket
import struct
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from typing import Any

from processing.base import interrupt

__all__ = [
    "ahead_in_a_process",
    "can_fork",
    "shared_by_two_processes",
    "shared_if_worth_it",
    "wait_for_workers",
    "SHARED_FROM_S",
]

#: :func:`shared_if_worth_it` forks a worker only when the items would take at least
#: this long in one process (s): a fork costs 30-60 ms (the shoebox's run of 16 poses
#: of 5 ms, 0.4-2 GB processes: the copies of the pages both processes then write),
#: more than two processes save on a short run
SHARED_FROM_S = 0.5


@contextlib.contextmanager
def ahead_in_a_process(make: Callable[[], Iterator[Any]]) -> Iterator[Iterator[Any]]:
    """Start making the items of ``make()`` (an iterator of picklable items) in a
    forked process; yields an iterator over them, in order, each as soon as it is
    made; what the worker raised is raised when its item is asked for (the same
    exception, its traceback there as a note; a RuntimeError if it does not pickle)."""
    if not _can_fork():
        yield make()
        return
    with _worker(make) as items:
        yield _handed_out(items)


def _can_fork() -> bool:
    import multiprocessing as mp

    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (
        sys.platform.startswith("linux")  # macOS lists fork; its system libraries are not safe
        and "fork" in mp.get_all_start_methods()
        and (cpus or 1) >= 2
        and not mp.current_process().daemon  # a pool's worker may have no children
    )


def can_fork() -> bool:
    """Whether :func:`shared_by_two_processes` would fork a worker here now: on Linux
    (``fork`` exists elsewhere too, but macOS's system libraries are not safe in a
    forked child), this process may use two CPUs or more, it may have children (it is not
    a daemonic worker of a process pool), and numba's GNU OpenMP layer has not run
    in it (see :func:`shared_by_two_processes`)."""
    return _can_fork() and not _gnu_openmp_started()


@contextlib.contextmanager
def _worker(make: Callable[[], Iterator[Any]]) -> Iterator[queue.Queue]:
    """A forked worker sending the items of ``make()``; yields the queue its messages
    arrive in (drained from the socket by a thread); the worker ends with the block."""
    import multiprocessing as mp

    receive, send = socket.socketpair()
    for sock, option in ((send, socket.SO_SNDBUF), (receive, socket.SO_RCVBUF)):
        # room for an image or two in the kernel: the worker goes on while this
        # process's reader thread waits for the interpreter (the system caps it)
        sock.setsockopt(socket.SOL_SOCKET, option, SOCKET_BUFFER_BYTES)
    worker = mp.get_context("fork").Process(
        target=_send_all, args=(make, send, receive), daemon=True
    )
    worker.start()
    send.close()  # the worker's end: the socket closes when the worker ends
    items: queue.Queue = queue.Queue()
    ended = threading.Event()  # the worker sent its end: it exits on its own
    reader = threading.Thread(target=_receive_all, args=(receive, items, ended), daemon=True)
    reader.start()
    try:
        yield items
    finally:
        if ended.is_set():  # reaped meanwhile: its memory's teardown takes 20-30 ms
            reader.join()
            receive.close()
            _reap_later(worker)
        else:
            if worker.is_alive():
                worker.terminate()
            worker.join()
            reader.join()
            receive.close()


#: the threads reaping workers that sent their last item (:func:`_reap_later`)
_REAPING: set[threading.Thread] = set()
#: a worker that sent its end and has not exited within this (s) is terminated
REAP_WITHIN_S = 5.0


def _reap_later(worker) -> None:
    """`worker` (a process that sent its end) joined in a thread: this process goes
    on while the system tears down the worker's memory (20-30 ms of a 350 MB
    simulator), the run's wall time no longer waiting on it."""

    def reap() -> None:
        worker.join(REAP_WITHIN_S)
        if worker.is_alive():  # stuck on its way out: ended as before
            worker.terminate()
            worker.join()
        _REAPING.discard(thread)

    thread = threading.Thread(target=reap, daemon=True, name="acousim-reap")
    _REAPING.add(thread)
    thread.start()


def wait_for_workers() -> None:
    """Wait until every worker that has sent its last item has ended: its CPU time is
    then counted in ``resource.getrusage(RUSAGE_CHILDREN)`` (benchmarks read it)."""
    for thread in list(_REAPING):
        thread.join()


def shared_by_two_processes(
    make: Callable[[int], Any],
    n: int,
    *,
    first: Callable[[], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[Any]:
    """``[make(0), ..., make(n - 1)]``, made by this process and a forked worker
    together, each taking the next item not yet taken (a counter in shared memory):
    the work of a command's two cores, for items that hold no state between them.

    first : called here once the worker has started, before this process takes its
        first item (what only this process needs, e.g. imports: the worker takes more
        items meanwhile).
    progress : called here ``(items made, n)`` as items are made, here or there.

    Ctrl-C is honoured between items (:func:`processing.base.interrupt.check`); what
    the worker raised is raised here.  Without ``fork``, on one CPU, or once numba's
    OpenMP layer has run in this process (GNU OpenMP is not fork-safe: numba
    terminates a forked child that runs a parallel kernel, such as a broadband
    image's), every item is made here."""
    out: list[Any] = [None] * n
    count = _Count(n, progress)
    if not can_fork():
        if first is not None:
            first()
        for k in range(n):
            interrupt.check()
            out[k] = make(k)
            count()
        return out
    import multiprocessing as mp

    taken = mp.get_context("fork").Value("q", 0)  # the next item nobody has taken

    def take() -> int:
        with taken.get_lock():
            k = taken.value
            taken.value = k + 1
        return k

    def theirs() -> Iterator[tuple[int, Any]]:
        while (k := take()) < n:
            yield k, make(k)

    with _worker(theirs) as items:
        if first is not None:
            first()
        while (k := take()) < n:
            interrupt.check()
            out[k] = make(k)
            count()
            for j, item in _arrived(items):
                out[j] = item
                count()
        for j, item in _handed_out(items):
            out[j] = item
            count()
    return out


def shared_if_worth_it(
    make: Callable[[int], Any],
    n: int,
    *,
    alone: Callable[[list[int], Callable[[int, int], None] | None], list[Any]],
    pace_s: float | None = None,
    always: bool = False,
    before_fork: Callable[[], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[Any]:
    """``[make(0), ..., make(n - 1)]`` in two processes when that is worth a fork:

    1. the pace: `pace_s` (s an item in this process), or if None item 0 made here
       first and timed;
    2. the items left would take less than :data:`SHARED_FROM_S` at that pace (and
       not `always`): ``alone(ks, progress)`` makes the items ks here (the caller's
       own way, e.g. threads), returning them in order;
    3. else `before_fork` (what the worker must find done, e.g. an acceleration
       structure built), then :func:`shared_by_two_processes`.

    `progress` as there, counting every item."""
    made = []
    if pace_s is None:
        interrupt.check()
        t = time.perf_counter()
        made.append(make(0))
        pace_s = time.perf_counter() - t
        if progress:
            progress(1, n)
    rest = list(range(len(made), n))
    later = None if progress is None else lambda k, _: progress(k + len(made), n)
    if not always and pace_s * len(rest) < SHARED_FROM_S:
        return [*made, *alone(rest, later)]
    if before_fork is not None:
        before_fork()
    return [*made, *shared_by_two_processes(lambda k: make(rest[k]), len(rest), progress=later)]


def _gnu_openmp_started() -> bool:
    """Whether numba's OpenMP threading layer has started in this process (numba
    is only looked at, not imported)."""
    numba = sys.modules.get("numba")
    if numba is None:
        return False
    try:
        return numba.threading_layer() == "omp"
    except ValueError:  # no parallel kernel has run: no layer chosen yet
        return False


class _Count:
    """Items made so far, reported to a progress callback."""

    def __init__(self, n: int, progress: Callable[[int, int], None] | None) -> None:
        self.n, self.done, self.progress = n, 0, progress

    def __call__(self) -> None:
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.n)


def _send_all(make: Callable[[], Iterator[Any]], send, theirs) -> None:
    """The worker: every item sent, then the end (or the error)."""
    theirs.close()
    interrupt.ignore_in_worker()
    try:
        for item in make():
            _send(send, ("item", item))
        _send(send, ("end", None))
    except BaseException as exc:  # noqa: BLE001 (sent to the command, which raises it)
        text = traceback.format_exc()
        with contextlib.suppress(OSError):  # the command gone: nobody to tell
            try:
                _send(send, ("error", (exc, text)))
            except Exception:  # noqa: BLE001 (an exception that does not pickle)
                _send(send, ("error", (None, text)))
    finally:
        send.close()


_LENGTH = struct.Struct("<Q")
#: each out-of-band buffer starts at a multiple of this many bytes of the message
_ALIGN = 64
#: a buffer this large or larger travels as an in-memory file (where Linux has them)
SHARED_BYTES = 1 << 16
#: at most this many of a message's buffers travel as files (the rest in the stream)
_MAX_FILES = 64
#: the socket pair's buffers asked for (Linux caps them at net.core.wmem_max and
#: rmem_max, 4 MB here, and doubles them)
SOCKET_BUFFER_BYTES = 4 << 20


def _send(sock: socket.socket, message: Any) -> None:
    """One message: its framing (the pickle's length, its buffers' sizes and which
    travel as files), then in one run of bytes each other out-of-band buffer (a
    contiguous array's bytes) as it lies, padded to :data:`_ALIGN` bytes, and the
    pickle.  A buffer of :data:`SHARED_BYTES` or more (a recording's samples)
    travels as an in-memory file (Linux's memfd) whose descriptor goes with the
    framing: written once here, mapped there, never read through the socket."""
    buffers: list[pickle.PickleBuffer] = []
    body = pickle.dumps(message, protocol=5, buffer_callback=buffers.append)
    raws = [b.raw() for b in buffers]
    big = [hasattr(os, "memfd_create") and r.nbytes >= SHARED_BYTES for r in raws]
    big = [b and k < _MAX_FILES for b, k in zip(big, itertools.accumulate(big, initial=0))]
    files = [_in_memory_file(r) for r, b in zip(raws, big) if b]
    frame = pickle.dumps((len(body), [r.nbytes for r in raws], big))
    head = _LENGTH.pack(len(frame)) + frame
    try:
        sent = socket.send_fds(sock, [head], files) if files else 0
        sock.sendall(head[sent:])
    finally:
        for fd in files:
            os.close(fd)
    for raw, b in zip(raws, big):
        if not b:
            sock.sendall(raw)
            if raw.nbytes % _ALIGN:
                sock.sendall(bytes(_ALIGN - raw.nbytes % _ALIGN))
    sock.sendall(body)


def _in_memory_file(raw: memoryview) -> int:
    """A new in-memory file holding `raw`'s bytes: its descriptor."""
    fd = os.memfd_create("acousim-item", os.MFD_CLOEXEC)
    view, done = raw.cast("B"), 0
    while done < view.nbytes:
        done += os.write(fd, view[done:])
    return fd


def _receive(sock: socket.socket) -> Any:
    """One message of :func:`_send` (EOFError: the worker's end closed): the files'
    buffers mapped, the others and the pickle taken in one receive (the reader
    thread takes the interpreter's lock a few times a message, not once a buffer:
    beside a busy main thread each take waits up to the switch interval), the
    arrays kept in place (aligned)."""
    length, files = _head(sock)
    size, sizes, big = pickle.loads(_exactly(sock, length))
    inline = [n for n, b in zip(sizes, big) if not b]
    padded = [-(-n // _ALIGN) * _ALIGN for n in inline]
    data = memoryview(_exactly(sock, sum(padded) + size))
    offsets = iter(itertools.accumulate(padded, initial=0))
    mapped = iter(files)
    buffers = []
    for n, b in zip(sizes, big):
        if b:
            fd = next(mapped)
            buffers.append(mmap.mmap(fd, n))
            os.close(fd)
        else:
            o = next(offsets)
            buffers.append(data[o : o + n])
    return pickle.loads(data[sum(padded) :], buffers=buffers)


def _head(sock: socket.socket) -> tuple[int, list[int]]:
    """A message's first bytes, the framing's length, and the descriptors sent with them."""
    got, files = b"", []
    while len(got) < _LENGTH.size:
        part, fds, _, _ = socket.recv_fds(sock, _LENGTH.size - len(got), _MAX_FILES)
        if not part:
            for fd in fds:
                os.close(fd)
            raise EOFError("the worker's end closed")
        got, files = got + part, files + list(fds)
    return _LENGTH.unpack(got)[0], files


def _exactly(sock: socket.socket, n: int) -> bytearray:
    """`n` bytes from `sock`, each call waiting for all it can take (MSG_WAITALL)."""
    buf = bytearray(n)
    view, got = memoryview(buf), 0
    while got < n:
        k = sock.recv_into(view[got:], n - got, socket.MSG_WAITALL)
        if k == 0:
            raise EOFError("the worker's end closed")
        got += k
    return buf


def _receive_all(receive, items: queue.Queue, ended: threading.Event) -> None:
    """The reader thread: what the worker sends, queued until the end (`ended` set)
    or an error."""
    while True:
        try:
            message = _receive(receive)
        except (EOFError, OSError):
            items.put(("error", (None, "the worker process ended before its last item")))
            return
        if message[0] == "end":
            ended.set()
        items.put(message)
        if message[0] != "item":
            return


def _handed_out(items: queue.Queue) -> Iterator[Any]:
    """The items in order; Ctrl-C honoured while waiting for the next."""
    while True:
        try:
            message = items.get(timeout=0.2)
        except queue.Empty:
            interrupt.check()
            continue
        if not _is_item(message):
            return
        yield message[1]


def _arrived(items: queue.Queue) -> Iterator[Any]:
    """The items that have arrived, without waiting (the end, if it came, is put
    back for :func:`_handed_out`)."""
    while True:
        try:
            message = items.get_nowait()
        except queue.Empty:
            return
        if not _is_item(message):
            items.put(message)
            return
        yield message[1]


def _is_item(message: tuple) -> bool:
    """Whether a worker's message is an item (False: the end); its error raised here
    (the same exception, the worker's traceback as a note)."""
    kind, value = message
    if kind == "error":
        exc, text = value
        if exc is None:
            raise RuntimeError(f"work made in a second process failed:\n{text}")
        exc.add_note(f"(raised in a second process:)\n{text}")
        raise exc
    return kind == "item"
