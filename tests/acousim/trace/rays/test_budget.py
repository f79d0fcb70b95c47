"""The automatic ray budget against ten times the fixed budgets the bundled scenes used
to set: every exact path those rays found, the diffuse tail's energy per range bin,
and the budget's own contract (same bytes, a fixed `rays` honoured, the cap)."""

import dataclasses

import numpy as np
import pytest

from acousim.scene import load_scene
from acousim.simulator import Simulator
from acousim.trace import KIND
from acousim.trace.rays.budget import ray_work
from acousim.trace.rays.scatter import scatter
from acousim.trace.rays.shoot import shoot
from acousim.trace.tracer import Tracer
from tests import REPO

SCENES = REPO / "scenes"
#: the rays each bundled scene set before the automatic budget, and a pose to test
#: (the corridor: two along the drive)
OLD = {
    "corridor": (5000, (20, 55)),
    "ertis_sample": (5000, (0,)),
    "panel_wall": (5000, (0,)),
    "shoebox": (40000, (0,)),
    "sphere": (200000, (0,)),
    "wall": (5000, (0,)),
}
BIN_M = 0.5


def _with(scene, **simulation):
    return dataclasses.replace(
        scene, simulation=dataclasses.replace(scene.simulation, **simulation)
    )


def _ends(scene, pose):
    array = scene.sensor.array
    return pose.to_world(array.emitter_m), pose.to_world(array.positions_m.mean(axis=0))


def _tail(c) -> np.ndarray:
    """Lambert energy at the receiver per 0.5 m range bin (range: half the path)."""
    if c is None:
        return np.zeros(0)
    rng = (c.first_leg_m + c.last_leg_m)[c.lambert] / 2
    return np.bincount(np.floor(rng / BIN_M).astype(int), c.intensity[c.lambert])


def _fixed_contributions(tracer, scene, pose, rays):
    s = tracer.settings
    emitter, receiver = _ends(scene, pose)
    shot = shoot(
        tracer.world,
        tracer.caster,
        emitter,
        pose.rotation[:, 0],
        rays,
        s.bounces,
        s.beam_rad,
        s.max_path_m,
    )
    return scatter(tracer.world, tracer.caster, shot.hits, receiver, s.max_path_m)


@pytest.mark.parametrize("name", sorted(OLD))
def test_automatic_budget_finds_what_ten_times_the_old_rays_find(name):
    scene = load_scene(SCENES / f"{name}.toml")
    assert scene.simulation.rays is None  # the bundled scenes take the automatic budget
    old, poses = OLD[name]
    auto = Tracer(scene)
    ref = Tracer(_with(scene, rays=10 * old))
    for i in poses:
        pose = scene.sensor.poses[i]
        a, r = auto.trace(pose), ref.trace(pose)
        # every exact path (image sources, edge elements) and every first-order glint
        # (scattered paths of order 1 on curved surfaces are the same geometric-optics
        # points in both) the reference found is found, at the same place and level
        exact = np.isin(r.kind, [KIND["specular"], KIND["diffraction"]])
        for j in np.flatnonzero(exact | (r.kind == KIND["scatter"]) & (r.order == 1)):
            same = (np.linalg.norm(a.anchor_m - r.anchor_m[j], axis=1) < 1e-9) & (
                np.abs(a.first_leg_m - r.first_leg_m[j]) < 1e-9
            )
            if exact[j] or np.any(same):
                assert np.any(same & (a.strength == r.strength[j])), (name, i, j, r.kind[j])
        # the curved surfaces the rays reach after a reflection (their lobes), and the
        # diffuse tail per 0.5 m of range within 0.5 dB where it carries energy
        emitter, receiver = _ends(scene, pose)
        work = ray_work(
            auto.world, auto.caster, auto.settings, emitter, receiver, pose.rotation[:, 0]
        )
        c_ref = _fixed_contributions(ref, scene, pose, 10 * old)
        c_auto = work.contributions
        if c_auto is None:  # no rays: nothing can scatter
            assert not np.any(c_ref.intensity > 0), name
            continue
        lobes_ref = set(zip(c_ref.surface[~c_ref.lambert], c_ref.order[~c_ref.lambert]))
        lobes_auto = set(zip(c_auto.surface[~c_auto.lambert], c_auto.order[~c_auto.lambert]))
        assert lobes_ref <= lobes_auto, (name, i)
        t_ref, t_auto = _tail(c_ref), _tail(c_auto)
        width = max(len(t_ref), len(t_auto))
        t_ref, t_auto = (
            np.pad(t_ref, (0, width - len(t_ref))),
            np.pad(t_auto, (0, width - len(t_auto))),
        )
        strong = t_ref >= t_ref.max() * 10 ** (-20 / 10)
        error_db = 10 * np.log10(t_auto[strong] / t_ref[strong])
        assert np.max(np.abs(error_db)) <= 0.5, (name, i, np.round(error_db, 2))
        assert work.rays < 10 * old


def test_scenes_without_scattering_shoot_at_most_a_probe():
    """The shoebox, the plate, the wall and the sphere (rigid, smooth, one bounce on the
    curved one): image sources and glints; over the whole sphere no ray at all, in a
    narrower beam one batch that tells which plane sequences the beam meets, shot
    only when some image source's path leaves the emitter outside the beam (the
    shoebox: the wall behind the sensor; the plate and the wall: none); the sphere
    (no planes) none."""
    for name, probed in (("shoebox", True), ("ertis_sample", False), ("wall", False)):
        scene = load_scene(SCENES / f"{name}.toml")
        pose = scene.sensor.poses[0]
        whole = Tracer(_with(scene, beam_deg=180.0))
        every = whole.trace(pose)
        assert whole.rays_used(pose) == 0, name
        spec = every.select(every.kind == KIND["specular"])
        cos = spec.departure @ pose.rotation[:, 0]
        assert np.any(cos < np.cos(np.deg2rad(scene.simulation.beam_deg))) == probed, name
        tracer = Tracer(scene)
        tracer.trace(pose)
        assert tracer.rays_used(pose) == (1000 if probed else 0), name
    sphere = load_scene(SCENES / "sphere.toml")
    tracer = Tracer(sphere)
    tracer.trace(sphere.sensor.poses[0])
    assert tracer.rays_used(sphere.sensor.poses[0]) == 0


@pytest.mark.parametrize("behind", [False, True])
def test_a_path_leaving_just_outside_the_beam_is_kept_if_a_ray_meets_its_wall(tmp_path, behind):
    """A wall beside the sensor, its axis turned 0.5 degrees away from it: the one
    image-source path leaves at 90.5 degrees, outside the 90 degree beam.  Where
    the wall runs ahead, rays in the beam graze it and the path is kept; where it
    ends 5 mm past the reflection point, no ray of the beam meets it and the path
    is not: as a fixed budget of 20 000 rays (whose paths are the plane sequences
    its rays met) decides."""
    import trimesh

    from acousim.scene import parse_scene

    wall = trimesh.creation.box(extents=(20.0, 0.1, 4.0))
    wall.apply_translation([-9.995 if behind else 9.8, 1.05, 0.0])  # inner face y = 1
    wall.export(tmp_path / "side.obj", digits=12)
    found, used = {}, {}
    for rays, beam_deg in ((None, 180.0), (None, 90.0), (20000, 90.0)):
        simulation = {"max_range_m": 4.0, "bounces": 1, "beam_deg": beam_deg}
        simulation.update({} if rays is None else {"rays": rays})
        spec = {
            "sensor": {"array": "urtis_v1", "direct_path": False},
            "simulation": simulation,
            "meshes": [{"file": "side.obj"}],
        }
        scene = parse_scene(spec, base_dir=tmp_path)
        pose = dataclasses.replace(scene.sensor.poses[0], yaw_rad=float(np.deg2rad(-0.5)))
        tracer = Tracer(scene)
        paths = tracer.trace(pose)
        found[rays, beam_deg] = paths.select(paths.kind == KIND["specular"])
        used[rays, beam_deg] = tracer.rays_used(pose)
    every = found[None, 180.0]
    assert len(every) == 1 and used[None, 180.0] == 0
    assert every.departure[0] @ pose.rotation[:, 0] < np.cos(np.deg2rad(90.0))
    assert used[None, 90.0] == 1000  # the probe, shot for the path outside the beam
    assert len(found[None, 90.0]) == len(found[20000, 90.0]) == (0 if behind else 1)


def test_same_seed_same_bytes_and_the_rays_in_the_metadata():
    scene = load_scene(SCENES / "corridor.toml")
    recs = [Simulator(scene).simulate_pose(scene.sensor.poses[30], 30) for _ in range(2)]
    assert recs[0].samples.tobytes() == recs[1].samples.tobytes()
    rays = recs[0].metadata["rays"]
    assert rays >= 1000 and rays == recs[1].metadata["rays"]


def test_a_fixed_budget_shoots_exactly_that_many_rays_and_the_cap_holds():
    scene = load_scene(SCENES / "corridor.toml")
    pose = scene.sensor.poses[10]
    fixed = Simulator(_with(scene, rays=1234))
    assert fixed.simulate_pose(pose).metadata["rays"] == 1234
    # exactly that many rays leave the emitter: Embree is asked for 1234 first hits
    # before any other ray (the scattered hits' shadow rays come after)
    tracer = Tracer(_with(scene, rays=1234))
    counts = []
    real = tracer.caster.first_hit
    tracer.caster.first_hit = lambda o, *a, **k: counts.append(len(o)) or real(o, *a, **k)
    tracer.trace(pose)
    # before them: the clearance's 26 rays from the emitter and each microphone, and
    # the pose check's 64 rays
    n_ends = 1 + len(scene.sensor.array.positions_m)
    assert counts[:3] == [26 * n_ends, 64, 1234]
    capped = Tracer(_with(scene, rays_max=1500))
    capped.trace(pose)
    assert capped.rays_used(pose) <= 1500


def _box_scene(tmp_path, box, position):
    import trimesh  # noqa: F401  (the box is a trimesh)

    box.export(tmp_path / "box.obj", digits=12)
    from acousim.scene import parse_scene

    return parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False, "pose": {"position_m": position}},
            "simulation": {"max_range_m": 5.0, "bounces": 2, "beam_deg": 90.0},
            "materials": [{"name": "wall", "reflection": 0.9}],
            "meshes": [{"file": "box.obj", "material": "wall"}],
        },
        base_dir=tmp_path,
    )


def test_enumerated_edge_paths_only_in_concave_corners(tmp_path):
    """Every plane sequence is enumerated in a box, but two reflections at one point of
    an edge are a specular path only inside a concave corner: looking into a room's
    corner, the echo at the emitter mirrored through the corner's edge (amplitude
    R^2); looking at a block's outer edge, none of order 2 (that is diffraction)."""
    import trimesh

    # a room 4 x 4 x 3 m, the sensor 1 m from the corner x = 2, y = 2 on its bisector
    room = trimesh.creation.box(extents=(4.0, 4.0, 3.0))
    room.invert()
    pos = [2 - 1 / np.sqrt(2), 2 - 1 / np.sqrt(2), 0.0]
    scene = _box_scene(tmp_path, room, pos)
    pose = dataclasses.replace(scene.sensor.poses[0], yaw_rad=np.pi / 4)
    paths = Tracer(scene).trace(pose)
    emitter = pose.to_world(scene.sensor.array.emitter_m)
    image = emitter.copy()
    image[:2] = 2 * np.array([2.0, 2.0]) - emitter[:2]  # through the edge x = y = 2
    spec = paths.select(paths.kind == KIND["specular"])
    j = np.flatnonzero(np.linalg.norm(spec.anchor_m - image, axis=1) < 1e-6)
    assert j.size == 1 and spec.order[j[0]] == 2
    assert spec.strength[j[0]] == pytest.approx(0.9**2, rel=1e-12)
    # a 1 m block whose edge x = y = 0.5 faces the sensor: first order from its two
    # faces in view (none here: both at 45 deg, their mirror points off the faces),
    # and no path of order 2
    block = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    pos = [0.5 + 1.5 / np.sqrt(2), 0.5 + 1.5 / np.sqrt(2), 0.0]
    scene = _box_scene(tmp_path, block, pos)
    pose = dataclasses.replace(scene.sensor.poses[0], yaw_rad=np.pi + np.pi / 4)
    tracer = Tracer(scene)
    paths = tracer.trace(pose)
    assert not np.any((paths.kind == KIND["specular"]) & (paths.order == 2))


def test_shoebox_third_order_matches_pyroomacoustics():
    """Every plane sequence of up to 3 walls enumerated (no rays): the same image
    sources as pyroomacoustics' image-source model (an implementation not ours),
    including those whose reflections meet in the room's corners."""
    pra = pytest.importorskip("pyroomacoustics")
    scene = _with(load_scene(SCENES / "shoebox.toml"), bounces=3, beam_deg=180.0)
    room_box = np.array([[-1.0, 3.2], [-1.6, 1.9], [-1.1, 1.5]])  # scenes/build_scenes.py
    pose = scene.sensor.poses[0]
    tracer = Tracer(scene)
    paths = tracer.trace(pose)
    assert tracer.rays_used(pose) == 0
    spec = paths.select(paths.kind == KIND["specular"])
    room = pra.ShoeBox(room_box[:, 1] - room_box[:, 0], fs=450000, max_order=3)
    room.add_source(pose.to_world(scene.sensor.array.emitter_m) - room_box[:, 0])
    mics = pose.to_world(scene.sensor.array.positions_m)
    room.add_microphone_array((mics - room_box[:, 0]).T)
    room.image_source_model()
    src = room.sources[0]
    images = src.images[:, src.orders >= 1].T + room_box[:, 0]
    assert len(images) == len(spec) == 62
    for img, order in zip(images, src.orders[src.orders >= 1]):
        j = np.flatnonzero(np.linalg.norm(spec.anchor_m - img, axis=1) < 1e-6)
        assert j.size == 1 and spec.order[j[0]] == order


@pytest.mark.parametrize("name", ["shoebox", "wall", "ertis_sample"])
def test_the_probe_meets_the_sequences_the_followed_rays_meet(name):
    """The probe's answer (:func:`sequences_met`, its rays aimed by geometry first)
    is that of the rays followed in full (:func:`follow`, every hit recorded), for
    every enumerated plane sequence, at poses around the room and in two beams."""
    from acousim.scene.pose import Pose
    from acousim.trace.rays.budget import all_sequences, batch_directions
    from acousim.trace.rays.shoot import follow, sequences_met

    scene = load_scene(SCENES / f"{name}.toml")
    tracer = Tracer(scene)
    s, world, caster = tracer.settings, tracer.world, tracer.caster
    every = all_sequences(world, s.bounces)
    wanted = {tuple(r) for k in every for r in every[k].tolist()}
    rng = np.random.default_rng(11)
    found = 0
    for _ in range(4):
        p0 = scene.sensor.poses[0].position_m
        pose = Pose(p0 + rng.uniform(-0.3, 0.3, 3), rng.uniform(-np.pi, np.pi), rng.normal(0, 0.3))
        emitter = pose.to_world(scene.sensor.array.emitter_m)
        for beam in (s.beam_rad, np.deg2rad(50.0)):
            dirs = batch_directions(1000, pose.rotation[:, 0], beam, 0)
            d_omega = 2 * np.pi * (1 - np.cos(beam)) / 1000
            args = (world, caster, emitter, dirs, d_omega, s.bounces, s.max_path_m)
            full = set(follow(*args).sequences) & wanted
            found += len(full)
            assert sequences_met(*args, wanted) == full
    assert found  # the rays met some


def test_the_compiled_aim_marks_the_rays_its_numpy_twin_marks(monkeypatch):
    """:func:`aimed` compiled and in numpy (numba missing): the same rays, every
    enumerated sequence and a third of them wanted, poses around the shoebox."""
    pytest.importorskip("numba")
    from acousim.scene.pose import Pose
    from acousim.trace.rays import shoot
    from acousim.trace.rays.budget import all_sequences, batch_directions

    scene = load_scene(SCENES / "shoebox.toml")
    tracer = Tracer(scene)
    s = tracer.settings
    every = all_sequences(tracer.world, s.bounces)
    wanted = [tuple(r) for k in every for r in every[k].tolist()]
    rng = np.random.default_rng(2)
    marks = []
    for _ in range(6):
        pose = Pose(rng.uniform(-0.5, 0.5, 3), rng.uniform(-np.pi, np.pi), rng.normal(0, 0.3))
        emitter = pose.to_world(scene.sensor.array.emitter_m)
        dirs = batch_directions(1000, pose.rotation[:, 0], s.beam_rad, 0)
        for some in (set(wanted), set(wanted[::3])):
            marks.append((emitter, dirs, some))
    compiled = [shoot.aimed(tracer.world, tracer.caster, *m) for m in marks]
    monkeypatch.setattr(shoot, "optional_kernel", lambda *a: None)
    plain = [shoot.aimed(tracer.world, tracer.caster, *m) for m in marks]
    assert sum(c.sum() for c in compiled) > 0
    for c, p in zip(compiled, plain):
        np.testing.assert_array_equal(c, p)


def test_the_first_two_batches_merged_whole_are_their_concatenation():
    """The first two batches' contributions taken whole (no copy) are the two halves
    concatenated, each half's intensities times its share of the rays (written
    here)."""
    from acousim.trace.rays.budget import _merged
    from acousim.trace.rays.scatter import Contributions, take

    rng = np.random.default_rng(4)
    K = 50
    whole = Contributions(
        rng.normal(size=(K, 3)),
        rng.uniform(0, 1, K),
        rng.uniform(1, 5, K),
        rng.uniform(1, 5, K),
        rng.normal(size=(K, 3)),
        rng.integers(0, 9, K),
        rng.integers(1, 3, K),
        rng.uniform(size=K) > 0.5,
    )
    halves = [take(whole, slice(0, 20)), take(whole, slice(20, None))]
    early = [((), halves[0]), ((), halves[1]), whole]
    merged = _merged([(halves[0], 64), (halves[1], 64)], 128, early)
    for f in dataclasses.fields(Contributions):
        got, parts = getattr(merged, f.name), [getattr(h, f.name) for h in halves]
        if f.name == "intensity":
            parts = [p * (64 / 128) for p in parts]
        if parts[0] is None:
            assert got is None
        else:
            assert np.array_equal(got, np.concatenate(parts)), f.name
