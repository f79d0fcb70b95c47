"""A trace asked only for the paths at least so long (Tracer.traced(min_path_m=...):
a rig's call heard late in another sonar's window): the diffraction stage leaves out
edges and pairs of edges whose every path is shorter, unless one could be the
strongest echo.  The paths that reach that length are those of the full trace (the
reference: the same pose traced in full, then the paths that reach the length
picked from it), and the stage does less."""

import numpy as np
import pytest

from acousim.bundled import find_scene
from acousim.rig import RigSimulator
from acousim.scene import load_scene
from acousim.trace.paths import KIND, reaching
from acousim.trace.tracer import Tracer


@pytest.fixture(scope="module")
def rig():
    return RigSimulator(load_scene(find_scene("corridor_rig")), threads=1)


@pytest.mark.parametrize("firing, min_path_m", [(40, 7.6), (43, 5.0), (45, 9.5)])
def test_the_paths_long_enough_are_those_of_the_full_trace(rig, firing, min_path_m):
    f = rig.measurements[firing]
    j, k = f.sonar, (f.sonar + 1) % len(rig.rig.sonars)
    array = rig.rig.pair_array(j, k)
    mics = f.pose.to_world(array.positions_m)
    full_tracer = Tracer(rig.pair(j, j).scene, threads=1)
    short_tracer = Tracer(rig.pair(j, j).scene, threads=1)
    full, _ = full_tracer.traced(f.pose, array)
    asked, _ = short_tracer.traced(f.pose, array, min_path_m=min_path_m)
    a = full.select(reaching(full, mics, min_path_m))
    b = asked.select(reaching(asked, mics, min_path_m))
    assert len(a) == len(b) > 0
    for name in ("anchor_m", "first_leg_m", "strength", "kind", "order"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    # the shorter diffraction paths were not all integrated
    diffraction = KIND["diffraction"]
    assert (asked.kind == diffraction).sum() < (full.kind == diffraction).sum()


def test_the_short_bins_of_weak_pairs_are_not_integrated(rig, monkeypatch):
    """Of a pair of edges with paths long enough, the bins of paths too short are
    left out where the pair cannot be the strongest echo: fewer edge-to-edge paths,
    the same ones that reach the length (the reference: the pairs' every bin)."""
    from acousim.trace.diffraction import edge_to_edge

    f = rig.measurements[40]
    j, k = f.sonar, (f.sonar + 1) % len(rig.rig.sonars)
    array = rig.rig.pair_array(j, k)
    mics = f.pose.to_world(array.positions_m)
    min_path_m = 7.6
    asked, _ = Tracer(rig.pair(j, j).scene, threads=1).traced(f.pose, array, min_path_m=min_path_m)
    monkeypatch.setattr(edge_to_edge, "_reaching_bins", lambda ctx, floor, sel, bound, w: sel)
    every_bin, _ = Tracer(rig.pair(j, j).scene, threads=1).traced(
        f.pose, array, min_path_m=min_path_m
    )
    a = every_bin.select(reaching(every_bin, mics, min_path_m))
    b = asked.select(reaching(asked, mics, min_path_m))
    for name in ("anchor_m", "first_leg_m", "strength", "kind", "order"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name

    def pairs(p):
        return int(((p.kind == KIND["diffraction"]) & (p.order == 2)).sum())

    assert pairs(b) > 0
    assert pairs(asked) < pairs(every_bin)
