"""Process-wide policy for a simulating process, set once at its entry point.

A library object never changes the process: the command line (``acousim``, its
simulating commands: :func:`acousim.cli.common.preload_simulation`), the
benchmarks, the dataset's worker processes and the tests call :func:`configure` at
their start; a script that wants the same bytes and speed calls it too.

* **BLAS on one thread** (threadpoolctl): the simulator's matrix products are small
  (tens to thousands of rows); a second BLAS thread gains nothing on them, spins
  against :meth:`acousim.Simulator.run`'s own second thread (the next pose prepared
  while this one renders) and changes the summation order, so the last bits of a
  recording would depend on the host's thread settings.
* **Freed memory kept for reuse** (glibc's allocator, :mod:`acousim.allocator`):
  0.79-0.93 of the time per pose, at the cost of keeping the peak memory.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

from acousim.allocator import keep_freed_memory
from processing.base.settings import setting, validate

__all__ = ["configure", "BLAS_THREADS", "Workers"]

log = logging.getLogger(__name__)

#: BLAS threads of a simulating process
BLAS_THREADS = 1


@dataclass(frozen=True)
class Workers:
    """How many local processes a command that fans out (``acousim dataset``,
    ``acousim reproduce``) runs."""

    workers: int = setting(2, "", 1, 1024, "local processes")

    def __post_init__(self) -> None:
        validate(self)


@functools.lru_cache(maxsize=1)
def configure() -> None:
    """Set the policy of the module docstring (once per process; later calls do
    nothing)."""
    import os

    import numpy  # noqa: F401  (its BLAS loaded, for threadpoolctl to find)
    from threadpoolctl import threadpool_limits

    # libraries loaded later (scipy's own BLAS) read their thread count from these
    for name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
        os.environ[name] = str(BLAS_THREADS)
    threadpool_limits(limits=BLAS_THREADS, user_api="blas")
    kept = keep_freed_memory()
    log.debug("process configured: BLAS on %d thread, freed memory kept: %s", BLAS_THREADS, kept)
