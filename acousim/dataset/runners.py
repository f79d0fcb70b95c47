"""Where a dataset's shards are computed: local processes or a Dask cluster, each
stopping cleanly on Ctrl-C.

Local workers ignore SIGINT (a terminal sends it to the whole process group; a worker
that raised it printed its own traceback and broke the pool) and leave it to the main
process, which polls :mod:`processing.base.interrupt` while it waits, then stops the
workers and removes the temporary files of the shards they were writing. Finished
shards stay, whole, for a resumed run.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

from acousim.dataset.safety import watch_parent
from acousim.process import configure
from processing.base import interrupt
from processing.base.atomic import TEMP_PREFIX

__all__ = ["run_pool", "run_dask", "POLL_S"]

#: how often the main process looks for Ctrl-C while its workers compute (s)
POLL_S = 0.1


def _worker_init(parent_pid: int) -> None:
    """Pool worker initializer: Ctrl-C is the main process's, exit when the main
    process is gone, the process's policy (:func:`acousim.process.configure`)."""

    interrupt.ignore_in_worker()
    watch_parent(parent_pid)
    configure()


def run_pool(job: Callable, jobs: list, workers: int, out: Path, step: Callable[[], None]) -> None:
    """``job(j)`` for every j of `jobs` on `workers` local processes; `step()` after
    each. Ctrl-C (or any error) stops the workers (the shards they were computing are
    redone on resume, their temporary files in `out` removed) and the jobs not
    started."""
    import multiprocessing

    pool = multiprocessing.Pool(workers, initializer=_worker_init, initargs=(os.getpid(),))
    try:
        results = pool.imap_unordered(job, jobs)
        for _ in jobs:
            while True:
                interrupt.check()
                try:
                    results.next(timeout=POLL_S)  # a worker's error is raised here
                    break
                except multiprocessing.TimeoutError:
                    continue
            step()
        pool.close()
    except BaseException:
        pool.terminate()
        pool.join()
        for stale in out.glob(f"{TEMP_PREFIX}*"):
            stale.unlink(missing_ok=True)
        raise
    pool.join()


def run_dask(job: Callable, jobs: list, scheduler: str, step: Callable[[], None]) -> None:
    """``job(j)`` for every j of `jobs` on the Dask cluster at `scheduler`; `step()`
    after each. Ctrl-C cancels the jobs not finished (a running shard completes whole
    or not at all: its file is renamed only when complete) and is raised here."""
    from dask.distributed import Client, as_completed

    with Client(scheduler, timeout="10s") as client:
        futures = client.map(job, jobs, pure=False)
        finished = as_completed(futures)
        try:
            while not finished.is_empty():
                interrupt.check()
                if not finished.has_ready():
                    time.sleep(POLL_S)  # a poll for Ctrl-C, not a synchronisation
                    continue
                for _ in finished.next_batch(block=False):
                    step()
            client.gather(futures)  # a shard's error is raised here
        except BaseException:
            client.cancel(futures)
            raise
