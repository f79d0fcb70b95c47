"""Timing helper shared by the benchmark sections."""

from __future__ import annotations

import resource
import time
from collections.abc import Callable

import numpy as np


def run_times(fn: Callable[[], object], repeat: int = 5, warmup: int = 1) -> np.ndarray:
    """Wall times (repeat,) of `repeat` calls, seconds (after `warmup` calls)."""
    for _ in range(warmup):
        fn()
    out = np.empty(repeat)
    for i in range(repeat):
        t0 = time.perf_counter()
        fn()
        out[i] = time.perf_counter() - t0
    return out


def best_time(fn: Callable[[], object], repeat: int = 5, warmup: int = 1) -> float:
    """Best wall time of `repeat` calls, seconds (after `warmup` calls)."""
    return float(run_times(fn, repeat, warmup).min())


def cpu_seconds() -> float:
    """CPU seconds of this process and of its children that have ended
    (``Simulator.run``'s forked worker, which ends after the run returns: waited for
    here): differences of it time a run's whole work."""
    from acousim.core.forked import wait_for_workers

    wait_for_workers()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime
