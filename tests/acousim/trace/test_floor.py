"""The energy floor's two rules (acousim/trace/floor.py), checked against the full
path set: the paths a floored trace leaves out are found by comparing it with a
trace without a floor, and their energy at the array centre is summed here."""

from __future__ import annotations

import numpy as np
import pytest

import acousim.trace.tracer as tracer_module
from acousim.scene import parse_scene
from acousim.trace import KIND
from acousim.trace.floor import diffraction_candidates, dropped_by_sum
from acousim.trace.tracer import Tracer
from tests.oracles.scenes import first_pose, rigid_scene, square_faces, trace_first_pose, turn_z

NO_FLOOR = -300.0


def _energy(paths, receiver: np.ndarray) -> np.ndarray:
    """(N,) squared pressure gain of every path at `receiver`: strength over the
    distance from its last anchor (the 1/r spreading of its last leg)."""
    last = np.linalg.norm(paths.anchor_m - receiver, axis=1)
    return (paths.strength / last) ** 2


def _keys(paths) -> list[tuple]:
    """One hashable key per path: its kind, anchor, first leg and strength."""
    rows = np.column_stack([paths.kind, paths.anchor_m, paths.first_leg_m, paths.strength])
    return [tuple(r) for r in np.round(rows, 12).tolist()]


def _dropped_db(full, kept, receiver: np.ndarray) -> float:
    """The summed energy of the paths of `full` missing from `kept`, dB re the
    strongest echo of `full`; every path of `kept` must be one of `full`'s."""
    have = set(_keys(kept))
    assert have <= set(_keys(full)), "a floored trace found a path the full one did not"
    gone = np.array([k not in have for k in _keys(full)])
    e = _energy(full, receiver)
    top = e[full.kind != KIND["direct"]].max()
    return 10 * np.log10(max(e[gone].sum(), 1e-300) / top)


def _crowd(tmp_path, floor_db: float, rule: str, weak: int = 2000):
    """A strong point 1 m ahead and `weak` points 2-3 m ahead, each 70 dB under it
    at the array centre (their sum: 37 dB under it)."""
    rng = np.random.default_rng(3)
    r = rng.uniform(2.0, 3.0, weak)
    az, el = rng.uniform(-0.4, 0.4, weak), rng.uniform(-0.3, 0.3, weak)
    pos = (
        np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]) * r[:, None]
    )
    points = [{"position_m": [1.0, 0.0, 0.0], "strength": 1.0}]
    points += [
        {"position_m": p.tolist(), "strength": float(s)} for p, s in zip(pos, r**2 * 10**-3.5)
    ]
    scene = parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False},
            "simulation": {"energy_floor_db": floor_db, "energy_floor_rule": rule},
            "points": points,
        },
        base_dir=tmp_path,
    )
    return trace_first_pose(scene)


def test_many_weak_paths_that_sum_to_a_strong_echo_are_kept_by_the_sum_rule(tmp_path):
    full, _, receiver = _crowd(tmp_path, NO_FLOOR, "path")
    assert len(full) == 2001
    per_path, _, _ = _crowd(tmp_path, -60.0, "path")
    summed, _, _ = _crowd(tmp_path, -60.0, "sum")
    # each weak point is under -60 dB: the per-path floor drops them all, whose sum
    # is 37 dB under the strong echo
    assert len(per_path) == 1
    assert _dropped_db(full, per_path, receiver) == pytest.approx(-37, abs=1.5)
    # the summed floor drops at most -60 dB of energy: a handful of them
    assert _dropped_db(full, summed, receiver) <= -60.0
    assert len(summed) >= 1990


@pytest.mark.parametrize("floor_db", [-30.0, -50.0, -70.0])
def test_the_sum_rule_with_early_pruning_drops_at_most_the_floor_of_energy(
    tmp_path, monkeypatch, floor_db
):
    """A cube facing the sensor: its face's specular echo, then first-order and
    edge-to-edge diffraction, whose stage prunes early under the floor (the echo
    found before it its reference); what the floored trace lacks against the full
    one sums to at most the floor (and the per-path rule, at the same level, drops
    more)."""
    quads = square_faces("cube", 0.3, turn_z(0.0), [1.2, 0.1, 0.05])
    sim = {"rays": 4000, "bounces": 1}

    def traced(level: float, rule: str):
        settings = {**sim, "energy_floor_db": level, "energy_floor_rule": rule}
        return trace_first_pose(rigid_scene(tmp_path, quads, settings))[0]

    full = traced(NO_FLOOR, "path")
    _, _, receiver = first_pose(rigid_scene(tmp_path, quads, sim))
    assert (full.kind == KIND["diffraction"]).sum() > 1000  # many weak elements
    stage = tracer_module.edge_diffraction
    found = []

    def spy(*args):
        out = stage(*args)
        found.append((args[-1].floor_level, len(out)))
        return out

    monkeypatch.setattr(tracer_module, "edge_diffraction", spy)
    summed = traced(floor_db, "sum")
    monkeypatch.undo()
    per_path = traced(floor_db, "path")
    assert _dropped_db(full, summed, receiver) <= floor_db
    assert len(summed) >= len(per_path)
    assert _dropped_db(full, per_path, receiver) > floor_db
    ((level, elements),) = found
    assert level > 0
    # the count the early pruning's budget is shared by bounds the stage's paths
    tracer = Tracer(rigid_scene(tmp_path, quads, sim))
    bound = diffraction_candidates(tracer.edges, tracer.settings.diffraction)
    assert (full.kind == KIND["diffraction"]).sum() <= bound
    if floor_db == -30.0:  # the stage left candidates out before finding them
        assert elements < (full.kind == KIND["diffraction"]).sum() / 2


def test_dropped_by_sum_drops_the_weakest_while_their_sum_fits():
    """Against a plain loop over the energies sorted weakest first."""
    rng = np.random.default_rng(5)
    for n in (0, 1, 7, 300):
        e = rng.exponential(size=n) ** 3
        e[: n // 3] = e[n // 3 : 2 * (n // 3)]  # ties
        for budget in (-1.0, 0.0, 0.01, 1.0, 1e9):
            want = np.zeros(n, bool)
            total = 0.0
            for i in sorted(range(n), key=lambda i: (e[i], i)):
                if total + e[i] > budget:
                    break
                total += e[i]
                want[i] = True
            np.testing.assert_array_equal(dropped_by_sum(e, budget), want)
