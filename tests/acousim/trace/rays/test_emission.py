"""The rays of one emission shared by several receivers (acousim.trace.rays.emission):
a shot cut to a shorter budget against rays followed with that budget (the
reference: following them again, independently of the cut), and traces of a rig's
pairs of sensors with the rays shared against the same traces each shooting its own."""

import dataclasses

import numpy as np
import pytest

from acousim.bundled import find_scene
from acousim.rig import RigSimulator
from acousim.scene import load_scene
from acousim.trace.rays.emission import Emission, cut
from acousim.trace.rays.shoot import Hits, cone_directions, follow
from acousim.trace.tracer import Tracer


@pytest.fixture(scope="module")
def corridor():
    scene = load_scene(find_scene("corridor"))
    return scene, Tracer(scene, threads=1)


def _same_hits(a: Hits, b: Hits) -> None:
    for f in dataclasses.fields(Hits):
        x, y = getattr(a, f.name), getattr(b, f.name)
        assert x.shape == y.shape and np.array_equal(x, y), f.name


@pytest.mark.parametrize("budget_m", [1.0, 2.5, 4.0, 7.3, 9.5])
def test_cut_is_the_shot_followed_with_the_shorter_budget(corridor, budget_m):
    scene, tracer = corridor
    pose = scene.sensor.poses[20]
    emitter = pose.to_world(scene.sensor.array.emitter_m)
    dirs = cone_directions(3000, pose.rotation[:, 0], np.pi / 2)
    args = (tracer.world, tracer.caster, emitter, dirs, 1e-3, 3)
    full = follow(*args, 12.0, legs=True)
    alone = follow(*args, budget_m)
    got = cut(full, budget_m)
    assert 0 < len(got.hits) < len(full.hits)
    _same_hits(got.hits, alone.hits)
    assert got.sequences == alone.sequences
    assert got.rays == alone.rays


def test_an_emission_follows_each_batch_once(corridor):
    scene, tracer = corridor
    pose = scene.sensor.poses[55]
    emitter = pose.to_world(scene.sensor.array.emitter_m)
    dirs = cone_directions(500, pose.rotation[:, 0], 1.0)
    em = Emission(tracer.world, tracer.caster, emitter, bounces=2, max_path_m=12.0)
    shots = [em.shot(dirs, 1e-3, bounces=2, max_path_m=m) for m in (12.0, 3.0, 12.0)]
    assert em.followed == 1
    _same_hits(shots[1].hits, follow(tracer.world, tracer.caster, emitter, dirs, 1e-3, 2, 3.0).hits)
    assert shots[2] is shots[0]


def _traced(tracer, pose, array, max_path_m=None):
    paths, rays = tracer.traced(pose, array, max_path_m)
    return paths, rays


@pytest.mark.parametrize("rays", [None, 2500])
def test_shared_rays_give_each_sonar_the_paths_of_its_own_trace(monkeypatch, rays):
    """A firing of the corridor rig heard by its own sonar and by two others (one
    within its window's budget, one in full): the traces with the rays shared are
    those of separate tracers, path for path (the automatic budget, and a fixed
    number of rays)."""
    scene = load_scene(find_scene("corridor_rig"))
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, rays=rays))
    rig = RigSimulator(scene, threads=1)
    f = rig.measurements[41]
    j = f.sonar
    k1, k2 = (j + 1) % 4, (j + 3) % 4
    asks = [(None, None), (scene.rig.pair_array(j, k1), 3.7), (scene.rig.pair_array(j, k2), None)]
    shared = Tracer(rig.pair(j, j).scene, threads=1)
    shared.share_emissions()
    emissions = []
    monkeypatch.setattr(
        "acousim.trace.rays.emission.Emission.__init__",
        _counting(emissions, Emission.__init__),
    )
    batches = []
    for array, max_path in asks:
        alone = Tracer(rig.pair(j, j).scene, threads=1)
        a, rays_a = _traced(alone, f.pose, array, max_path)
        b, rays_b = _traced(shared, f.pose, array, max_path)
        assert rays_a == rays_b and len(a) == len(b) > 0
        # the automatic budget: 1000, 1000, 2000, 4000, ... rays; a fixed one: one batch
        batches.append(1 if rays else (rays_b // 1000).bit_length())
        for field in dataclasses.fields(a):
            assert np.array_equal(getattr(a, field.name), getattr(b, field.name)), field.name
    shared_one = [e for e in emissions if e.followed]
    assert len(shared_one) == 1  # the three traces' rays: one emission's batches
    assert shared_one[0].followed == max(batches)


def _counting(made: list, init):
    def counted(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append(self)

    return counted
