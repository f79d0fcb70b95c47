"""The allocator's policy (acousim.allocator): freed blocks stay in the heap, so a
repeated pattern of large allocations reuses its pages instead of faulting fresh
ones in; run in a fresh interpreter (the policy is per process)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")

PATTERN = """
import resource, sys
import numpy as np
from acousim.allocator import keep_freed_memory
on = keep_freed_memory()
faults = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_minflt
keep = []
counts = []
for r in range(4):
    f = faults()
    for mb in (1, 3, 6, 12, 24, 2, 20, 5):  # MiB, touched, two alive at a time
        a = np.empty(mb << 17)
        a[:] = 1.0
        keep.append(a)
        if len(keep) > 2:
            keep.pop(0)
    counts.append(faults() - f)
print(on, *counts)
"""


def _run(env_extra: dict) -> list[str]:
    env = {**os.environ, **env_extra}
    out = subprocess.run(
        [sys.executable, "-c", PATTERN], capture_output=True, text=True, env=env, check=True
    )
    return out.stdout.split()


def test_freed_blocks_are_reused_without_page_faults():
    """73 MiB allocated per round (18,700 pages): after the first round, the same
    pattern faults in fewer than 100 pages (the policy keeps the freed blocks)."""
    on, first, *later = _run({"ACOUSIM_KEEP_FREED_MEMORY": "1"})
    if on != "True":
        pytest.skip("not glibc: the policy does not apply")
    assert int(first) > 1000  # the first round takes its pages from the system
    assert all(int(n) < 100 for n in later), later


def test_the_policy_can_be_declined():
    on, *_ = _run({"ACOUSIM_KEEP_FREED_MEMORY": "0"})
    assert on == "False"


SMALL_PAGES = """
from acousim.allocator import small_pages
from numpy._core.multiarray import _set_madvise_hugepage
print(small_pages(), _set_madvise_hugepage(True))  # the latter: the setting before
"""


def test_small_pages_turn_numpys_huge_page_advice_off():
    env = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    out = subprocess.run(
        [sys.executable, "-c", SMALL_PAGES], capture_output=True, text=True, env=env, check=True
    )
    assert out.stdout.split() == ["True", "False"]


def test_small_pages_leave_numpys_own_switch_alone():
    env = {**os.environ, "NUMPY_MADVISE_HUGEPAGE": "1"}
    out = subprocess.run(
        [sys.executable, "-c", SMALL_PAGES], capture_output=True, text=True, env=env, check=True
    )
    assert out.stdout.split() == ["False", "True"]


LIBRARY = """
import functools
from threadpoolctl import threadpool_info
import acousim.allocator as A
import processing as P
from acousim.scene import Scene, Sensor, PointItem
from acousim.simulator import Simulator
blas = lambda: sorted(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
before = blas()
scene = Scene(sensor=Sensor(array=P.preset("urtis_v1")), points=(PointItem((1.0, 0.0, 0.0)),))
sim = Simulator(scene)
sim.run()
print(A.keep_freed_memory.cache_info().currsize, before == blas())
from acousim.process import configure
configure()
print(A.keep_freed_memory.cache_info().currsize, set(blas()) <= {1})
"""


def test_a_simulator_leaves_the_process_alone_the_entry_point_sets_its_policy():
    """Constructing and running a Simulator neither sets the allocator's policy nor
    limits BLAS's threads; acousim.process.configure (the entry point's call) does
    both."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    env["OPENBLAS_NUM_THREADS"] = "2"
    out = subprocess.run(
        [sys.executable, "-c", LIBRARY], capture_output=True, text=True, env=env, check=True
    ).stdout.split()
    assert out == ["0", "True", "1", "True"]
