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
