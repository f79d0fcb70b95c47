"""One way to write a file: a temporary name in the target folder, renamed when complete.

:func:`atomic_path` creates the temporary file exclusively (``tempfile.mkstemp``: an
unpredictable name, ``O_EXCL``, so a planted symlink is never followed), yields its
path for any writer (h5py, matplotlib, imageio, VTK), renames it over the target on
success and removes it on any exception, ``KeyboardInterrupt`` included. A reader
never sees a half-written file and an interrupted write leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_path", "write_bytes", "write_text", "TEMP_PREFIX"]

TEMP_PREFIX = ".acousim-tmp-"
"""Prefix of every temporary file (``.acousim-tmp-<random>-<name>``)."""


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a fresh temporary path beside `path`; rename it to `path` on success.

    The temporary file keeps `path`'s suffix (writers that choose a format by
    extension still work) and exists, empty, when the block starts; a writer may
    replace it. On an exception (or Ctrl-C) it is removed and the target is untouched.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    tmp = None
    mask = _block_sigint()  # Ctrl-C is held back until the temporary's name is recorded
    try:
        try:
            fd, name = tempfile.mkstemp(prefix=TEMP_PREFIX, suffix=f"-{path.name}", dir=folder)
            tmp = Path(name)
            os.close(fd)
        finally:
            _restore(mask)  # a held-back Ctrl-C is raised here, inside the outer try
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; a written file gets the usual mode
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise


def _block_sigint():
    """Block SIGINT in this thread where the platform can; returns the previous mask."""
    if hasattr(signal, "pthread_sigmask"):
        return signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    return None


def _restore(mask) -> None:
    if mask is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write `data` to `path` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write `text` to `path` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return Path(path)
