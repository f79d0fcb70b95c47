"""Simulator.run makes its poses in two processes (this one and a forked worker),
or in one, preparing the next pose and tracing the one after in threads of their
own while it renders; the edge-to-edge kernel shares its pairs among the tracer's
threads: none may change a result.  The reference is the same pose simulated
alone, one stage after the other (``simulate_pose``), and the kernel on one
thread."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from acousim.scene import load_scene
from acousim.scene.model import Diffraction
from acousim.simulator import Simulator
from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions, diffract
from acousim.trace.world.edges import find_edges
from acousim.trace.world.embree import RayCaster
from tests import REPO
from tests.acousim.trace.diffraction.test_edge_to_edge import plane_ids
from tests.acousim.trace.diffraction.test_pair_selection import EMITTER, RECEIVER, room_objects

#: run before any parallel kernel in its worker (tests/conftest.py): these fork
pytestmark = pytest.mark.forks

SCENES = REPO / "scenes"


@pytest.mark.parametrize("processes", [2, 1])
def test_run_gives_the_recordings_of_one_pose_at_a_time(processes):
    """The corridor drive at its defaults (diffraction, edge to edge), moving and
    frozen, five poses, in two processes where they can be forked (2: whatever the
    run's length) and in this one (1): every recording's samples, ground truth and
    metadata byte for byte (and a run of one pose, which starts no thread)."""
    scene = load_scene(SCENES / "corridor.toml")
    frozen = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, motion=None))
    poses = [12, 13, 14, 30, 31]
    for sc in (scene, frozen):
        together = Simulator(sc).run(poses, processes=processes)
        alone = Simulator(sc)
        for i, rec in zip(poses, together):
            ref = alone.simulate_pose(sc.sensor.poses[i], i)
            assert np.array_equal(rec.samples, ref.samples)
            assert np.array_equal(rec.truth.position_world_m, ref.truth.position_world_m)
            assert np.array_equal(rec.truth.delay_s, ref.truth.delay_s)
            assert rec.metadata == ref.metadata
        # one pose asked: run in this thread alone, the same bytes
        (one,) = Simulator(sc).run([poses[3]], processes=processes)
        assert np.array_equal(one.samples, together[3].samples)


def test_run_in_two_processes_raises_the_workers_error_naming_its_pose():
    """A pose that fails wherever it is made (here or in the forked worker): run
    raises its InputError, naming the pose."""
    from processing.base.errors import InputError

    sim = Simulator(load_scene(SCENES / "corridor.toml"))
    prepare = sim._prepare

    def failing(pose, index, n_samples, motion):  # this instance (and the fork's) only
        if index % 2:
            raise InputError("no path found")
        return prepare(pose, index, n_samples, motion)

    sim._prepare = failing
    with pytest.raises(InputError, match=r"pose (11|13|15): no path found"):
        sim.run(range(10, 16), processes=2)


def test_run_forks_only_for_work_worth_a_fork(monkeypatch):
    """A short run (the shoebox's pose thrice, a few ms each once its kernels are
    loaded) is made in this process, by default; asked for two processes, it forks
    where it can; either way the same recordings."""
    from acousim.core import forked

    calls = []
    share = forked.shared_by_two_processes

    def counted(make, n, **kw):
        calls.append(n)
        return share(make, n, **kw)

    monkeypatch.setattr(forked, "shared_by_two_processes", counted)
    sim = Simulator(load_scene(SCENES / "shoebox.toml"))
    sim.run([0])  # the kernels loaded, then a pose's time taken as the pace
    sim.run([0])
    short = sim.run([0, 0, 0])
    assert calls == []
    forced = sim.run([0, 0, 0], processes=2)
    assert calls == ([3] if forked.can_fork() else [])  # the pace known: all three shared
    for a, b in zip(short, forced):
        assert np.array_equal(a.samples, b.samples)


def test_run_stops_at_a_failing_pose_and_names_it():
    """A pose whose preparation fails: run raises its error naming that pose, and
    prepares no pose beyond the ones already queued behind it (PREPARE_AHEAD)."""
    from acousim import simulator
    from processing.base.errors import InputError

    scene = load_scene(SCENES / "corridor.toml")
    sim = Simulator(scene)
    prepared = []
    prepare = sim._prepare

    def failing(pose, index, n_samples, motion):  # this instance only
        prepared.append(index)
        if index == 13:
            raise InputError("no path found")
        return prepare(pose, index, n_samples, motion)

    sim._prepare = failing
    with pytest.raises(InputError, match="pose 13: no path found"):
        sim.run(range(10, 30), processes=1)
    assert max(prepared) <= 13 + simulator.PREPARE_AHEAD - 1
    assert sorted(prepared) == list(range(10, max(prepared) + 1))


def test_edge_to_edge_is_the_same_on_two_threads():
    """The stage's paths (first order and edge to edge, floor as the tracer's) with
    the tracer's two threads and with one: equal bit for bit."""
    mesh = room_objects()
    geometry = DiffractingGeometry(
        find_edges(mesh), np.ones(len(mesh.faces)), face_plane=plane_ids(mesh)
    )
    options = DiffractionOptions(max_path_m=8.0, floor_level=0.5e-4, settings=Diffraction(order=2))
    out = []
    for threads in (1, 2):
        d = diffract(geometry, RayCaster(mesh.triangles, threads), EMITTER, RECEIVER, options)
        out.append(d)
    one, two = out
    assert (one.order == 2).sum() > 100
    for field in ("anchor_m", "first_leg_m", "strength", "edge", "order"):
        assert np.array_equal(getattr(one, field), getattr(two, field))
