"""The first-order stage leaves out the edges whose elements cannot reach the floor
(:func:`acousim.trace.diffraction.first_order.edge_bound`), checked against the full computation:

* the bound is at least every edge's largest element (all its BTM elements computed,
  no edge left out), on random boxes and plates seen from random points, with random
  reflection factors and element steps, and on poses of the bundled corridor;
* the corridor's traced paths (every stage, the tracer's floor) are the same, bit
  for bit, with the bound and with every edge computed.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import acousim.trace.diffraction.first_order as first_order
from acousim.scene import load_scene
from acousim.scene.model import Diffraction
from acousim.simulator import Simulator
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions
from acousim.trace.world.edges import find_edges
from tests import REPO

CORRIDOR = REPO / "scenes" / "corridor.toml"
EDGE_BOUND = first_order.edge_bound


def _largest_and_bound(ctx: StageContext) -> tuple[np.ndarray, np.ndarray]:
    """Per oriented edge of ctx: its largest |amplitude| (every element computed)
    and its bound."""
    keep, wedge = ctx.geometry.edges.oriented(ctx.emitter, ctx.receiver)
    rows = np.flatnonzero(keep)
    el, local, _ = first_order.wedge_elements(ctx, wedge, rows, ctx.emitter)
    largest = np.zeros(rows.size)
    np.maximum.at(largest, local, np.abs(el.amplitude))
    return largest, EDGE_BOUND(ctx, wedge, rows, ctx.emitter)


def _random_objects(rng) -> trimesh.Trimesh:
    """Two boxes (2 cm to 2 m a side, turned at random) and a plate (1 to 50 cm)."""
    parts = []
    for _ in range(2):
        box = trimesh.creation.box(rng.uniform(0.02, 2.0, 3))
        box.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
        box.apply_translation(rng.uniform(-3, 3, 3))
        parts.append(box)
    h = rng.uniform(0.005, 0.25)
    plate = trimesh.Trimesh(
        [[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]], [[0, 1, 2], [0, 2, 3]]
    )
    plate.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
    plate.apply_translation(rng.uniform(-1, 1, 3))
    parts.append(plate)
    return trimesh.util.concatenate(parts)


@pytest.mark.parametrize("seed", range(12))
def test_the_bound_is_above_every_edges_largest_element(seed):
    rng = np.random.default_rng(seed)
    mesh = _random_objects(rng)
    geometry = DiffractingGeometry(find_edges(mesh), rng.uniform(0.2, 1.0, len(mesh.faces)))
    worst = 0.0
    for _ in range(4):
        emitter = rng.uniform(-4, 4, 3)
        # receiver next to the emitter (a sonar) or anywhere
        receiver = emitter + (
            rng.normal(0, 0.01, 3) if rng.random() < 0.5 else rng.uniform(-3, 3, 3)
        )
        step = float(rng.choice([1e-3, 2e-3, 5e-3]))
        options = DiffractionOptions(
            max_path_m=float(rng.uniform(4, 20)), settings=Diffraction(step_m=step, order=1)
        )
        largest, bound = _largest_and_bound(
            StageContext(geometry, None, emitter, receiver, options)
        )
        assert np.all(largest <= bound)
        worst = max(worst, float(np.max(largest / bound, initial=0.0)))
    assert worst > 0  # elements were computed


@pytest.fixture(scope="module")
def corridor():
    return Simulator(load_scene(CORRIDOR), threads=1)


def test_corridor_bound_holds_and_the_paths_are_the_same(corridor, monkeypatch):
    sim = corridor
    poses = [sim.scene.sensor.poses[i] for i in (3, 15, 27)]
    seen = []

    def checking(ctx, wedge, rows, source, known=None):
        largest, bound = _largest_and_bound(ctx)
        assert np.all(largest <= bound)
        # the floor leaves out some edges: the bound is of use
        seen.append((int(np.sum(bound < ctx.options.floor_level)), largest.size))
        return EDGE_BOUND(ctx, wedge, rows, source, known)

    monkeypatch.setattr(first_order, "edge_bound", checking)
    with_bound = []
    for p in poses:
        sim.tracer.forget()
        with_bound.append(sim.paths(p))
    assert all(skipped > 0 for skipped, _ in seen)
    monkeypatch.setattr(
        first_order,
        "edge_bound",
        lambda ctx, wedge, rows, source, known=None: np.full(rows.size, np.inf),
    )
    for p, a in zip(poses, with_bound):
        sim.tracer.forget()
        b = sim.paths(p)
        for name in (
            "anchor_m",
            "first_leg_m",
            "strength",
            "position_m",
            "order",
            "kind",
            "departure",
        ):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
