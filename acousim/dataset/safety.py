"""Keeping a dataset folder sound while it is written: one writer (a lock), no
orphaned workers, no silent wait on an unreachable scheduler, file hashes."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import socket
import threading
import time
from pathlib import Path

from processing.base.errors import InputError

__all__ = ["LOCK", "locked", "watch_parent", "check_scheduler", "sha256_file"]

LOCK = ".acousim-dataset.lock"
"""The lock file a generator holds (``flock``) in its output folder."""


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@contextlib.contextmanager
def locked(out: Path):
    """Hold the folder's lock (``flock``: released when the process ends, however)."""
    fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(
                "another acousim dataset generator is writing this folder; wait for it "
                "or use another --out",
                file=out,
            ) from None
        _LOCK_FDS.add(fd)
        yield
    finally:
        _LOCK_FDS.discard(fd)
        os.close(fd)


#: lock descriptors held by this process: a forked pool worker closes its copies
#: (watch_parent), so that only the generator itself holds the folder's lock
_LOCK_FDS: set[int] = set()


def watch_parent(parent_pid: int) -> None:
    """Pool worker initializer: exit as soon as the main process is gone (a killed
    main process must not leave workers computing for minutes). Also closes the
    worker's inherited copy of the folder lock, which would otherwise outlive a killed
    main process for as long as the worker does."""
    for fd in list(_LOCK_FDS):
        with contextlib.suppress(OSError):
            os.close(fd)
    _LOCK_FDS.clear()
    with contextlib.suppress(Exception):  # Linux: the kernel signals us at once
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    start_ppid = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(0.5)
            try:
                os.kill(parent_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            if os.getppid() != start_ppid:
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="watch-parent").start()


def check_scheduler(address: str, timeout_s: float = 5.0) -> None:
    """Fail at once, with the address, when nothing listens at a tcp:// (or host:port)
    address (Dask's Client would wait 30 s and raise a bare OSError); other protocols
    are left to Dask."""
    from urllib.parse import urlsplit

    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme != "tcp":
        return  # tls://, ucx://, ...: left to Dask
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if not host or not port:
        raise InputError("expected tcp://HOST:PORT", key="--scheduler", value=address)
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except OSError as exc:
        raise InputError(
            f"no Dask scheduler reachable there ({exc.strerror or exc})",
            key="--scheduler",
            value=address,
        ) from None
