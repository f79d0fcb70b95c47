"""The C allocator's policy for a simulating process: keep freed memory for reuse.

A pose allocates and frees tens of megabytes of arrays (impulse buffers, spectra,
gain sets).  glibc's malloc returns large freed blocks to the system and takes fresh
pages for the next ones; every fresh page costs a page fault (about 2.5 us per 4 KiB
page on the 2-core machine of ``BENCHMARKS.md``), some 15 MB per corridor pose.
Kept in the heap (blocks up to 32 MiB, the heap's top trimmed beyond 1 GiB), the
same drive runs in 0.79 (frozen), 0.86 (in motion) and 0.93 (in motion, with
diffraction) of the time (paired runs).  The cost: the process keeps its peak
memory until it exits.

:func:`keep_freed_memory` sets that policy once per process (glibc's ``mallopt``;
elsewhere, or with the environment variable ``ACOUSIM_KEEP_FREED_MEMORY=0``, it
does nothing).  :func:`acousim.process.configure` calls it, at the entry point.

:func:`small_pages` puts numpy's large arrays on ordinary 4 KiB pages: numpy asks
the kernel for transparent huge pages on every array of 4 MiB or more, and on the
2-core machine of ``BENCHMARKS.md`` (huge pages and their defragmentation on
``madvise``) they cost more system time than they save: ``acousim image
--no-3d --no-animation`` of a 60-pose corridor (its arrays of tens of MB) spent
3.0 s of system time instead of 4.6 s without them (3 paired runs).  The imaging
commands call it at their entry.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os
import sys

__all__ = ["keep_freed_memory", "small_pages", "MMAP_THRESHOLD_BYTES", "TRIM_THRESHOLD_BYTES"]

log = logging.getLogger(__name__)

#: blocks up to this size come from the heap (glibc's largest allowed value)
MMAP_THRESHOLD_BYTES = 32 << 20
#: the heap's free top is given back to the system only beyond this
TRIM_THRESHOLD_BYTES = 1 << 30
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's malloc.h


@functools.lru_cache(maxsize=1)
def keep_freed_memory() -> bool:
    """Set the policy of the module docstring (once); whether it is in force."""
    if os.environ.get("ACOUSIM_KEEP_FREED_MEMORY", "1") == "0":
        log.debug("ACOUSIM_KEEP_FREED_MEMORY=0: the allocator's policy left as it is")
        return False
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.gnu_get_libc_version  # glibc, not musl  # noqa: B018
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    ok = mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
    ok &= mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1
    log.debug("freed memory kept for reuse (glibc mallopt): %s", ok)
    return bool(ok)


@functools.lru_cache(maxsize=1)
def small_pages() -> bool:
    """Stop numpy from asking for transparent huge pages for its large arrays (the
    module docstring), once per process; whether it is in force.  Left as it is when
    the environment sets ``NUMPY_MADVISE_HUGEPAGE`` (numpy's own switch, read when
    numpy is imported) or numpy lacks the switch."""
    if "NUMPY_MADVISE_HUGEPAGE" in os.environ:
        return os.environ["NUMPY_MADVISE_HUGEPAGE"] == "0"
    try:
        from numpy._core.multiarray import _set_madvise_hugepage
    except ImportError:  # pragma: no cover - a numpy without the switch
        return False
    _set_madvise_hugepage(False)
    log.debug("numpy's arrays on 4 KiB pages (no transparent huge pages)")
    return True
