"""The bounded, thread-safe cache objects own (acousim.core.cache): least recently
used dropped first, never more than its size, one value per key across threads."""

import threading

import pytest

from acousim.core.cache import LruCache


def test_least_recently_used_is_dropped_and_a_hit_refreshes():
    cache = LruCache(3)
    calls = []

    def value(k):
        return cache.get(k, lambda: calls.append(k) or k * 10)

    for k in (1, 2, 3):
        assert value(k) == k * 10
    assert value(1) == 10  # a hit: 1 is now the most recent
    assert value(4) == 40  # drops 2, the least recently used
    assert len(cache) == 3
    assert value(3) == 30 and value(1) == 10  # still held
    assert value(2) == 20  # computed again
    assert calls == [1, 2, 3, 4, 2]


def test_threads_share_it_within_its_bound():
    cache = LruCache(8)
    errors = []

    def work(seed):
        for i in range(500):
            k = (seed * 7 + i) % 20
            if cache.get(k, lambda k=k: ("v", k)) != ("v", k):
                errors.append(k)
            if len(cache) > 8:
                errors.append("over")

    threads = [threading.Thread(target=work, args=(s,)) for s in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == [] and len(cache) == 8


def test_size_must_be_positive():
    with pytest.raises(ValueError):
        LruCache(0)
