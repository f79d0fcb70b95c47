"""TracedPaths.select (which gathers with np.take) against indexing each array by
hand: a mask, indices (negative ones among them), an empty selection and a
slice give the same arrays, shapes and dtypes; a mask of the wrong length is an
error."""

from __future__ import annotations

import numpy as np
import pytest

from acousim.trace.paths import TracedPaths


def _paths(n: int) -> TracedPaths:
    rng = np.random.default_rng(2)
    return TracedPaths(
        rng.normal(size=(n, 3)),
        rng.random(n),
        rng.normal(size=n),
        rng.normal(size=(n, 3)),
        rng.integers(0, 3, n),
        rng.integers(0, 5, n),
        rng.normal(size=(n, 3)),
        rng.integers(0, 2, (n, 2)),
    )


@pytest.mark.parametrize(
    "keep",
    [
        np.array([True, False, True, True, False, False, True]),
        np.array([4, -1, 0, 0]),
        np.zeros(0, int),
        np.zeros(7, bool),
        slice(2, 5),
    ],
)
def test_select_is_indexing(keep):
    p = _paths(7)
    got = p.select(keep)
    by_hand = {
        "anchor_m": p.anchor_m[keep],
        "first_leg_m": p.first_leg_m[keep],
        "strength": p.strength[keep],
        "position_m": p.position_m[keep],
        "order": p.order[keep],
        "kind": p.kind[keep],
        "departure": p.departure[keep],
        "interactions": p.interactions[keep],
    }
    for name, want in by_hand.items():
        have = getattr(got, name)
        assert have.dtype == want.dtype and have.shape == want.shape, name
        np.testing.assert_array_equal(have, want)


def test_select_rejects_a_mask_of_another_length():
    with pytest.raises(IndexError):
        _paths(7).select(np.ones(6, bool))
