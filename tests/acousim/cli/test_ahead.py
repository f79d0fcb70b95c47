"""Work made ahead in a second process (acousim.cli.ahead): the same items, in
order, as made here; what the worker raised is raised here, with the worker's
traceback; the worker does not outlive the block."""

import os

import numpy as np
import pytest

from acousim.cli.ahead import ahead_in_a_process


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


def _block(k):
    """Item k: a large array (out of band), a strided view (in band) and the pid."""
    big = np.arange(3_000_000, dtype=np.float64) * (k + 1)  # 24 MB
    return {"k": k, "pid": os.getpid(), "big": big, "strided": big[::7][:1000]}


def test_two_processes_share_the_items_and_hand_them_out_in_order():
    from acousim.cli.ahead import shared_by_two_processes

    got = list(shared_by_two_processes(_block, 5))
    assert [g["k"] for g in got] == list(range(5))
    for g in got:  # every byte arrives: the values are those made
        k = g["k"]
        np.testing.assert_array_equal(g["big"], np.arange(3_000_000.0) * (k + 1))
        np.testing.assert_array_equal(g["strided"], (np.arange(1000) * 7.0) * (k + 1))
        assert g["big"].flags.writeable
    if (os.cpu_count() or 1) > 1:  # the odd items made in the worker, the even here
        assert {g["pid"] for g in got[0::2]} == {os.getpid()}
        assert os.getpid() not in {g["pid"] for g in got[1::2]}
