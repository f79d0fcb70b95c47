"""One way to write a file: a temporary name in the target folder, renamed when complete.

:func:`atomic_path` creates the temporary file exclusively (``tempfile.mkstemp``: an
unpredictable name, ``O_EXCL``, so a planted symlink is never followed), yields its
path for any writer (h5py, matplotlib, imageio, VTK), renames it over the target on
success and removes it on any exception, ``KeyboardInterrupt`` included. A reader
never sees a half-written file and an interrupted write leaves nothing behind.

A Ctrl-C recorded by :mod:`processing.base.interrupt` is honoured just before the rename
(SIGINT held back from the check to the rename), so an interrupted run never replaces
an existing file. Inside :func:`committed_together` every file is renamed at the end
of the block, all or none: an interrupted command that writes several files leaves
the previous set as it was.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path

from processing.base import interrupt

__all__ = [
    "atomic_path",
    "committed_together",
    "staged",
    "Stage",
    "write_bytes",
    "write_text",
    "TEMP_PREFIX",
]

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
        pending = _GROUP.get()
        if pending is not None:
            pending.append((tmp, path))  # renamed when the group ends
        else:
            _commit([(tmp, path)])
    except BaseException:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise


_GROUP: contextvars.ContextVar[list | None] = contextvars.ContextVar("atomic_group", default=None)


@contextlib.contextmanager
def committed_together() -> Iterator[None]:
    """Files written with :func:`atomic_path` inside the block are renamed into place
    together when it ends, none of them if it raises or Ctrl-C came (their temporaries
    are removed)."""
    pending: list[tuple[Path, Path]] = []
    token = _GROUP.set(pending)
    try:
        yield
        _GROUP.reset(token)
        token = None
        _commit(pending)
    except BaseException:
        for tmp, _ in pending:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise
    finally:
        if token is not None:
            _GROUP.reset(token)


class Stage:
    """A temporary folder (:attr:`folder`) where files are written whole, by this
    process or by forked workers, before :meth:`adopt` moves them to their targets as
    :func:`atomic_path` would have (with the enclosing :func:`committed_together`'s
    files, or at once)."""

    def __init__(self, folder: Path, group: list | None) -> None:
        self.folder, self._group = folder, group

    def adopt(self, staged: str | Path, path: str | Path) -> Path:
        """Move the complete file `staged` (in :attr:`folder`) to `path`: first to a
        temporary name beside `path`, then renamed when the enclosing group commits
        (or now, outside one). Returns `path`."""
        path = Path(path)
        folder = path.parent if str(path.parent) else Path(".")
        fd, name = tempfile.mkstemp(prefix=TEMP_PREFIX, suffix=f"-{path.name}", dir=folder)
        os.close(fd)
        tmp = Path(name)
        try:
            os.replace(staged, tmp)
            if self._group is not None:
                self._group.append((tmp, path))
            else:
                _commit([(tmp, path)])
        except BaseException:
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise
        return path


@contextlib.contextmanager
def staged(folder: str | Path) -> Iterator[Stage]:
    """A :class:`Stage`: a fresh temporary folder in `folder` (named with
    :data:`TEMP_PREFIX`), removed with whatever is left in it when the block ends
    (an error, Ctrl-C, a worker terminated mid-file). Inside the block a file written
    with :func:`atomic_path` is renamed as soon as it is complete, in this process and
    in a worker forked in the block (their files lie in the stage until adopted);
    :meth:`Stage.adopt` hands each to the enclosing :func:`committed_together`."""
    import shutil

    group = _GROUP.get()
    stage = Path(tempfile.mkdtemp(prefix=TEMP_PREFIX, dir=folder))
    token = _GROUP.set(None)
    try:
        yield Stage(stage, group)
    finally:
        _GROUP.reset(token)
        shutil.rmtree(stage, ignore_errors=True)


def _commit(moves: list[tuple[Path, Path]]) -> None:
    """Rename temporaries to their targets unless Ctrl-C came: SIGINT is held back
    from the check to the last rename, so a Ctrl-C is either before (nothing renamed,
    KeyboardInterrupt) or after (every file complete)."""
    mask = _block_sigint()
    try:
        interrupt.check()
        for tmp, path in moves:
            os.replace(tmp, path)
    finally:
        _restore(mask)


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
