"""The shortest and the longest path over a pair of edges
(:func:`acousim.trace.diffraction.pair_geometry.shortest_paths` and ``_farthest``)
against references written here: the compiled bisection, which stops once a
halving leaves its interval unchanged, against all 60 halvings in a plain loop
(the same point bit for bit) and against the least of the path over a fine grid
of both edges; the longest path against the largest over every pair of ends
written out one by one."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from acousim.trace.diffraction.pair_geometry import _edge_table, _farthest, shortest_paths
from tests.acousim.trace.diffraction.test_bound_kernel import _random_pairs

SOURCE = np.array([0.1, -0.3, 0.2])
RECEIVER = np.array([0.4, 0.5, -0.1])


def _path(pairs, k: int, z1: np.ndarray, z2: np.ndarray) -> np.ndarray:
    """The path S -> edge 1 at z1 -> edge 2 at z2 -> R of pair k (grids of z), m."""
    ax1 = (pairs.end1[k] - pairs.start1[k]) / np.linalg.norm(pairs.end1[k] - pairs.start1[k])
    ax2 = (pairs.end2[k] - pairs.start2[k]) / np.linalg.norm(pairs.end2[k] - pairs.start2[k])
    x1 = pairs.start1[k] + z1[..., None] * ax1
    x2 = pairs.start2[k] + z2[..., None] * ax2
    return (
        np.linalg.norm(x1 - SOURCE, axis=-1)
        + np.linalg.norm(x2 - x1, axis=-1)
        + np.linalg.norm(RECEIVER - x2, axis=-1)
    )


def test_shortest_path_is_that_of_sixty_halvings_and_the_least_path():
    kernel = pytest.importorskip("acousim.trace.diffraction.pair_kernel")
    pairs = _random_pairs(np.random.default_rng(5), 40)
    z, p = shortest_paths(pairs, SOURCE, RECEIVER)
    geo = _edge_table(pairs)
    for k in range(len(pairs)):
        g = geo[k]
        edge = (SOURCE, RECEIVER, g[0:3], g[3:6], g[7:10], g[10:13], g[13])
        lo, hi = 0.0, g[6]
        for _ in range(60):  # every halving, none skipped
            mid = 0.5 * (lo + hi)
            if kernel._profile(mid, edge)[1] > 0:
                hi = mid
            else:
                lo = mid
        assert z[k] == 0.5 * (lo + hi)
        # the least path over a grid of both edges: no shorter than the one found
        z1 = np.linspace(0, g[6], 401)[:, None]
        z2 = np.linspace(0, g[13], 401)[None, :]
        grid = _path(pairs, k, z1, z2)
        assert p[k] <= grid.min() + 1e-9
        # and within a grid step's change of it (the path's slope is at most 2 in each)
        assert p[k] >= grid.min() - 2 * (g[6] + g[13]) / 400


def test_farthest_is_the_longest_path_over_the_ends():
    pairs = _random_pairs(np.random.default_rng(6), 30)
    got = _farthest(pairs, SOURCE, RECEIVER)
    for k in range(len(pairs)):
        ends1, ends2 = (pairs.start1[k], pairs.end1[k]), (pairs.start2[k], pairs.end2[k])
        best = 0.0
        for a, b in itertools.product(ends1, ends2):
            way = np.linalg.norm(a - SOURCE) + np.linalg.norm(a - b) + np.linalg.norm(RECEIVER - b)
            best = max(best, way)
        assert got[k] == pytest.approx(best, rel=1e-14)
    # and no path over the edges is longer (the path is convex in (z1, z2))
    for k in range(0, len(pairs), 5):
        z1 = np.linspace(0, np.linalg.norm(pairs.end1[k] - pairs.start1[k]), 51)[:, None]
        z2 = np.linspace(0, np.linalg.norm(pairs.end2[k] - pairs.start2[k]), 51)[None, :]
        assert _path(pairs, k, z1, z2).max() <= got[k] * (1 + 1e-12)
