"""Work made ahead in a second process (acousim.core.forked): the same items, in
order, as made here; what the worker raised is raised here, with the worker's
traceback; the worker does not outlive the block."""

import os

import numpy as np
import pytest

from acousim.core.forked import ahead_in_a_process

#: run before any parallel kernel in its worker (tests/conftest.py): these fork
pytestmark = pytest.mark.forks


def _squares(n):
    for k in range(n):
        yield {"k": k, "pid": os.getpid(), "a": np.arange(1000) * k}


def test_the_items_come_in_order_from_another_process():
    with ahead_in_a_process(lambda: _squares(20)) as items:
        got = list(items)
    assert [g["k"] for g in got] == list(range(20))
    for g in got:
        np.testing.assert_array_equal(g["a"], np.arange(1000) * g["k"])
    if (os.cpu_count() or 1) > 1:  # made elsewhere (on one CPU: here, when asked)
        assert {g["pid"] for g in got} != {os.getpid()}


def _fails():
    yield 1
    raise ValueError("bad item 2")


def test_a_failure_in_the_worker_is_raised_here_with_its_cause():
    with ahead_in_a_process(_fails) as items:
        assert next(items) == 1
        with pytest.raises(ValueError, match="bad item 2") as raised:
            next(items)  # the worker's own exception, its traceback there as a note
    if (os.cpu_count() or 1) > 1:
        assert any("_fails" in note for note in raised.value.__notes__)


def _forever():
    k = 0
    while True:
        yield k
        k += 1


def test_leaving_the_block_early_ends_the_worker():
    import multiprocessing as mp

    with ahead_in_a_process(_forever) as items:
        assert next(items) == 0
    assert not [p for p in mp.active_children() if p.is_alive()]


def _with_a_worker() -> bool:
    """Whether shared_by_two_processes forks a worker in this process now: not on
    one CPU, nor once numba's GNU OpenMP pool has run here (an earlier test's
    broadband image)."""
    from acousim.core import forked as ahead

    return ahead.can_fork()


def _block(k):
    """Item k: a large array (out of band), a strided view (in band) and the pid."""
    big = np.arange(3_000_000, dtype=np.float64) * (k + 1)  # 24 MB
    return {"k": k, "pid": os.getpid(), "big": big, "strided": big[::7][:1000]}


def test_two_processes_share_the_items_and_hand_them_out_in_order():
    """Each item is made once, by this process or the worker, and every byte of its
    arrays arrives; `first` runs here while the worker takes items (here it waits
    for the worker's word that it made one), and the progress counts every item."""
    from acousim.core.forked import shared_by_two_processes

    said_r, said_w = os.pipe()  # the worker says when it has made an item
    here = os.getpid()

    def make(k):
        item = _block(k)
        if os.getpid() != here:
            os.write(said_w, b"k")
        return item

    counted = []
    forked = _with_a_worker()
    got = shared_by_two_processes(
        make,
        7,
        first=(lambda: os.read(said_r, 1)) if forked else None,
        progress=lambda d, n: counted.append((d, n)),
    )
    os.close(said_r)
    os.close(said_w)
    assert [g["k"] for g in got] == list(range(7))
    for g in got:  # every byte arrives: the values are those made
        k = g["k"]
        np.testing.assert_array_equal(g["big"], np.arange(3_000_000.0) * (k + 1))
        np.testing.assert_array_equal(g["strided"], (np.arange(1000) * 7.0) * (k + 1))
        assert g["big"].flags.writeable
    assert counted == [(d, 7) for d in range(1, 8)]
    if forked:  # the worker made some (first waited for one)
        assert any(g["pid"] != here for g in got)


def test_the_run_returns_while_the_worker_exits_and_is_reaped_then():
    """A worker that sent its last item ends on its own, reaped in a thread: the call
    returns before the worker has exited (here it cannot exit until told: a thread of
    its own waits for this process's word), and :func:`wait_for_workers` returns once
    it has, leaving no child."""
    import multiprocessing as mp
    import select
    import threading

    from acousim.core.forked import shared_by_two_processes, wait_for_workers

    if not _with_a_worker():
        pytest.skip("no worker here (one CPU, or numba's GNU OpenMP pool ran)")
    go_r, go_w = os.pipe()
    said_r, said_w = os.pipe()
    here = os.getpid()

    def make(k):
        if os.getpid() != here:
            os.write(said_w, b"k")
            if not any(t.name == "wait-for-go" for t in threading.enumerate()):
                # (at most 60 s: a run that waited for its worker's exit fails, not hangs)
                threading.Thread(
                    target=select.select, args=([go_r], [], [], 60.0), name="wait-for-go"
                ).start()
        return k * k

    got = shared_by_two_processes(make, 6, first=lambda: os.read(said_r, 1))
    assert got == [k * k for k in range(6)]
    assert [p for p in mp.active_children() if p.is_alive()]  # still on its way out
    os.write(go_w, b"g")
    wait_for_workers()
    assert not [p for p in mp.active_children() if p.is_alive()]
    for fd in (go_r, go_w, said_r, said_w):
        os.close(fd)


def test_an_item_that_fails_in_the_worker_fails_the_whole():
    from acousim.core.forked import shared_by_two_processes

    if not _with_a_worker():
        pytest.skip("no worker here (one CPU, or numba's GNU OpenMP pool ran)")
    said_r, said_w = os.pipe()
    here = os.getpid()

    def make(k):
        if os.getpid() != here:
            os.write(said_w, b"k")
            raise ValueError(f"the worker's item {k}")
        return k

    with pytest.raises(ValueError, match="the worker's item") as raised:
        shared_by_two_processes(make, 50, first=lambda: os.read(said_r, 1))
    os.close(said_r)
    os.close(said_w)
    assert any("make" in note for note in raised.value.__notes__)


def test_after_a_parallel_kernel_ran_here_every_item_is_made_here():
    """numba terminates a child forked from a process whose GNU OpenMP pool has run
    when the child runs a parallel kernel: once that pool has run here, the items
    (each running one) are all made here, and right."""
    import subprocess
    import sys
    from pathlib import Path

    code = (
        "import os, numpy as np, numba\n"
        "from numba import njit, prange\n"
        "from acousim.core.forked import shared_by_two_processes\n"
        "@njit(parallel=True)\n"
        "def total(x):\n"
        "    s = 0.0\n"
        "    for i in prange(x.size):\n"
        "        s += x[i]\n"
        "    return s\n"
        "total(np.ones(1000))\n"
        "here = os.getpid()\n"
        "got = shared_by_two_processes(lambda k: (total(np.full(100, k)), os.getpid()), 6)\n"
        "assert [v for v, _ in got] == [100.0 * k for k in range(6)], got\n"
        "print(numba.threading_layer(), {p == here for _, p in got})\n"
    )
    root = Path(__file__).resolve().parents[3]
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=root, timeout=300
    )
    assert done.returncode == 0, done.stderr
    layer, made_here = done.stdout.split(maxsplit=1)
    if layer == "omp":  # GNU OpenMP: no worker
        assert made_here.strip() == "{True}"
