"""Ray-traced paths against ground truth: image sources, a flat wall, a sphere."""

import dataclasses
import itertools
import shutil

import numpy as np
import pytest
import trimesh

from acousim.scene import Pose, load_scene, parse_scene
from acousim.simulator import Simulator
from acousim.trace import KIND
from tests import REPO

SCENES = REPO / "scenes"
ROOM = np.array([[-1.0, 3.2], [-1.6, 1.9], [-1.1, 1.5]])  # scenes/build_scenes.py


def image_sources(src, bounds, max_order=2):
    """Independent image-source method for a rectangular room: (image, order) pairs."""
    per_axis = []
    for s, (a, b) in zip(src, bounds):
        per_axis.append(
            [(s, 0), (2 * a - s, 1), (2 * b - s, 1), (s + 2 * (b - a), 2), (s - 2 * (b - a), 2)]
        )
    out = []
    for combo in itertools.product(*per_axis):
        order = sum(o for _, o in combo)
        if 1 <= order <= max_order:
            out.append((np.array([c for c, _ in combo]), order))
    return out


def specular_echoes(sim, pose):
    paths = sim.paths(pose)
    spec = paths.select(paths.kind == KIND["specular"])
    mics = pose.to_world(sim.scene.sensor.array.positions_m)
    return spec, spec.echoes(mics, pose.rotation[:, 0], sim.c), mics


def full_beam(scene, **kw):
    return dataclasses.replace(
        scene, simulation=dataclasses.replace(scene.simulation, beam_deg=180.0, **kw)
    )


def test_shoebox_matches_the_image_source_method():
    scene = full_beam(load_scene(SCENES / "shoebox.toml"))
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    spec, echoes, mics = specular_echoes(sim, pose)
    ref = image_sources(pose.to_world(scene.sensor.array.emitter_m), ROOM)
    assert len(ref) == 24
    assert len(spec) == len(ref), "missing or spurious specular paths"
    R = scene.materials["wall"].reflection
    for img, order in ref:
        j = np.flatnonzero(np.linalg.norm(spec.anchor_m - img, axis=1) < 1e-6)
        assert j.size == 1, f"image {img} (order {order}) not found exactly once"
        j = j[0]
        assert spec.order[j] == order
        dist = np.linalg.norm(img - mics, axis=1)
        assert np.max(np.abs(echoes.delay_s[:, j] - dist / sim.c)) <= 0.1e-6
        level_db = 20 * np.log10(echoes.gain[:, j] / (R**order / dist))
        assert np.max(np.abs(level_db)) <= 0.1


def test_shoebox_agrees_with_pyroomacoustics():
    """The same room through pyroomacoustics' image-source model (an implementation
    that is not ours): the same 24 first- and second-order paths, all visible from
    every microphone, the same delays and the same reflection losses."""
    pra = pytest.importorskip("pyroomacoustics")
    scene = full_beam(load_scene(SCENES / "shoebox.toml"))
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    spec, echoes, mics = specular_echoes(sim, pose)
    R = scene.materials["wall"].reflection
    origin = ROOM[:, 0]  # pyroomacoustics' rooms start at the origin
    room = pra.ShoeBox(
        ROOM[:, 1] - origin,
        fs=450000,
        materials=pra.Material(1 - R**2),  # energy absorption: amplitude R per bounce
        max_order=2,
        air_absorption=False,
        ray_tracing=False,
    )
    room.add_source(pose.to_world(scene.sensor.array.emitter_m) - origin)
    room.add_microphone_array((mics - origin).T)
    room.image_source_model()
    src = room.sources[0]
    keep = src.orders >= 1
    assert np.all(room.visibility[0][:, keep])
    images, orders, damping = src.images[:, keep].T + origin, src.orders[keep], src.damping[0, keep]
    assert len(images) == len(spec) == 24
    for img, order, damp in zip(images, orders, damping):
        j = np.flatnonzero(np.linalg.norm(spec.anchor_m - img, axis=1) < 1e-6)
        assert j.size == 1 and spec.order[j[0]] == order
        dist = np.linalg.norm(img - mics, axis=1)
        assert np.max(np.abs(echoes.delay_s[:, j[0]] - dist / sim.c)) <= 0.1e-6
        assert np.max(np.abs(20 * np.log10(echoes.gain[:, j[0]] * dist / damp))) <= 0.1


@pytest.mark.parametrize("yaw_deg,pitch_deg", [(0, 0), (20, 0), (35, 10), (-40, -15)])
def test_large_wall_gives_one_echo_at_two_d_over_c(yaw_deg, pitch_deg):
    scene = load_scene(SCENES / "wall.toml")
    pose = Pose([0.0, 0.3, 0.1], np.deg2rad(yaw_deg), np.deg2rad(pitch_deg))
    scene = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, poses=(pose,)))
    sim = Simulator(scene)
    spec, echoes, mics = specular_echoes(sim, pose)
    assert len(sim.paths(pose)) == 1 and len(spec) == 1
    e = pose.to_world(scene.sensor.array.emitter_m)
    d = 2.0 - e[0]  # the wall's front face is the plane x = 2
    image = e + [2 * d, 0, 0]
    np.testing.assert_allclose(spec.anchor_m[0], image, atol=1e-9)
    dist = np.linalg.norm(image - mics, axis=1)
    np.testing.assert_allclose(echoes.delay_s[:, 0], dist / sim.c, atol=1e-9)
    np.testing.assert_allclose(echoes.gain[:, 0], 0.95 / dist, rtol=1e-9)
    # at the emitter itself: 2 d / c
    assert np.linalg.norm(image - e) / sim.c == pytest.approx(2 * d / sim.c, abs=1e-12)


def test_sphere_gives_one_geometric_optics_echo():
    scene = load_scene(SCENES / "sphere.toml")
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    paths = sim.paths(pose)
    centre = pose.to_world(scene.sensor.array.positions_m).mean(axis=0)
    dist = np.linalg.norm(paths.anchor_m - centre, axis=1)
    level = paths.strength / dist
    rng = (paths.first_leg_m + dist) / 2
    k = np.argmax(level)
    a, r = 0.2, 1.5
    assert rng[k] == pytest.approx(r - a, abs=2e-3)  # 2 (r - a) / c
    assert abs(20 * np.log10(level[k] / (a / (2 * r**2)))) <= 2.0
    assert level[k] ** 2 >= 0.9 * np.sum(level**2), "energy spread over facet glints"


def _scene_with_mesh(tmp_path, mesh, pose_pos=(0.0, 0.0, 0.0), units="m", rays=20000):
    mesh.export(tmp_path / "m.obj", digits=12)  # text, full precision (STL is float32)
    return parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "direct_path": False,
                "pose": {"position_m": list(pose_pos)},
            },
            "simulation": {"max_range_m": 8.0, "rays": rays, "bounces": 2, "beam_deg": 180.0},
            "materials": [{"name": "wall", "reflection": 0.9}],
            "meshes": [{"file": "m.obj", "material": "wall", "units": units}],
        },
        base_dir=tmp_path,
    )


def _echo_table(sim, pose):
    spec, echoes, _ = specular_echoes(sim, pose)
    order = np.lexsort((echoes.gain[0], echoes.delay_s[0]))
    return echoes.delay_s[:, order], echoes.gain[:, order]


def _room():
    room = trimesh.load(SCENES / "meshes" / "shoebox.stl")
    return room


@pytest.mark.parametrize("variant", ["millimetres", "one_km_away", "degenerate_and_duplicate"])
def test_robust_geometry_gives_the_same_echoes(tmp_path, variant):
    clean = Simulator(_scene_with_mesh(tmp_path, _room()))
    d0, g0 = _echo_table(clean, clean.scene.sensor.poses[0])
    mesh = _room()
    pose = (0.0, 0.0, 0.0)
    units = "m"
    if variant == "millimetres":
        mesh.apply_scale(1000.0)
        units = "mm"
    elif variant == "one_km_away":
        shift = np.array([1000.0, -700.0, 30.0])
        mesh.apply_translation(shift)
        pose = tuple(shift)
    else:
        f = mesh.faces
        v = mesh.vertices
        degenerate = np.array([[f[0, 0], f[0, 0], f[0, 1]]])  # zero-area
        mesh = trimesh.Trimesh(v, np.vstack([f, f[:3], degenerate]), process=False)
    sim = Simulator(_scene_with_mesh(tmp_path, mesh, pose, units))
    d1, g1 = _echo_table(sim, sim.scene.sensor.poses[0])
    assert d1.shape == d0.shape
    assert np.max(np.abs(d1 - d0)) <= 0.1e-6
    assert np.max(np.abs(20 * np.log10(g1 / g0))) <= 0.1


def test_corridor_converges_with_rays():
    """The corridor at its automatic budget against 16 times the 5000 rays it used to
    set."""
    scene = load_scene(SCENES / "corridor.toml")
    pose = scene.sensor.poses[20]
    base = Simulator(scene).paths(pose)
    many = Simulator(
        dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, rays=80_000))
    ).paths(pose)
    centre = pose.to_world(scene.sensor.array.positions_m).mean(axis=0)

    def table(p, kind):
        sel = p.select(p.kind == KIND[kind])
        lvl = sel.strength / np.linalg.norm(sel.anchor_m - centre, axis=1)
        return sel, lvl

    s0, l0 = table(base, "specular")
    s1, l1 = table(many, "specular")
    strong = l1 >= l1.max() * 10 ** (-40 / 20)
    # every specular echo within 40 dB of the strongest is found at the default budget,
    # with the same delay and level (exact paths do not depend on the ray budget)
    for img, lv in zip(s1.anchor_m[strong], l1[strong]):
        j = np.flatnonzero(np.linalg.norm(s0.anchor_m - img, axis=1) < 1e-9)
        assert j.size == 1
        assert l0[j[0]] == pytest.approx(lv, rel=1e-12)
    # scattered energy (diffuse walls, pipes) within 1 dB of the 16x reference
    _, c0 = table(base, "scatter")
    _, c1 = table(many, "scatter")
    assert abs(10 * np.log10(np.sum(c0**2) / np.sum(c1**2))) < 1.0


def test_no_embree_without_meshes(tmp_path):
    shutil.copy(SCENES / "points.toml", tmp_path / "p.toml")
    sim = Simulator(load_scene(tmp_path / "p.toml"))
    assert sim.tracer.caster is None and sim.tracer.world is None
    paths = sim.paths(sim.scene.sensor.poses[0])
    assert len(paths) == 3 and np.all(paths.kind == KIND["point"])


def test_grazing_wall_along_the_axis(tmp_path):
    """A wall parallel to the sensor's axis: every ray that reaches it grazes it, and its
    one specular path leaves at 90° (the edge of a hemispherical beam)."""
    wall = trimesh.creation.box(extents=(20.0, 0.1, 4.0))
    wall.apply_translation([5.0, 1.05, 0.0])  # inner face: the plane y = 1
    wall.export(tmp_path / "side.obj", digits=12)
    scene = parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False},
            "simulation": {"max_range_m": 4.0, "rays": 20000, "bounces": 1, "beam_deg": 90.0},
            "meshes": [{"file": "side.obj"}],
        },
        base_dir=tmp_path,
    )
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    spec, echoes, mics = specular_echoes(sim, pose)
    assert len(spec) == 1
    np.testing.assert_allclose(spec.anchor_m[0], [0.0, 2.0, 0.0], atol=1e-9)
    dist = np.linalg.norm(np.array([0.0, 2.0, 0.0]) - mics, axis=1)
    assert np.max(np.abs(echoes.delay_s[:, 0] - dist / sim.c)) <= 0.1e-6


def test_microphone_directivity_is_a_piston_at_the_band_centre(tmp_path):
    from acousim.synth.response import piston_directivity

    base = {
        "sensor": {"array": "urtis_v1", "direct_path": False},
        "simulation": {"max_range_m": 3.0, "absorption": False},
        "points": [{"position_m": [0.5, 0.866, 0.0]}],
    }  # 60° off the axis, 1 m
    omni = Simulator(parse_scene(base, base_dir=tmp_path))
    base["sensor"]["mic_radius_m"] = 0.004
    directive = Simulator(parse_scene(base, base_dir=tmp_path))
    pose = omni.scene.sensor.poses[0]
    mics = pose.to_world(omni.scene.sensor.array.positions_m)
    g0 = omni.paths(pose).echoes(mics, pose.rotation[:, 0], omni.c).gain
    n = directive.scene.n_samples()
    g1 = directive.heard(pose, None, n).echoes.gain
    expected = piston_directivity(37.5e3, np.deg2rad(60), 0.004, omni.c)
    np.testing.assert_allclose(g1 / g0, expected, rtol=0.02)
    assert 0.3 < expected < 0.95


def test_a_pure_tone_call_traces_a_mesh_scene(tmp_path):
    """f_start == f_end: the range resolution is c times the call's duration (no
    division by a zero bandwidth); the sphere's glint is still one echo at r - a."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.2)
    sphere.apply_translation([1.5, 0.0, 0.0])
    sphere.export(tmp_path / "s.obj", digits=12)
    scene = parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "direct_path": False,
                "call": {"f_start_hz": 40e3, "f_end_hz": 40e3, "duration_s": 1e-3},
            },
            "simulation": {"max_range_m": 3.0, "rays": 20000, "bounces": 1, "beam_deg": 30.0},
            "meshes": [{"file": "s.obj"}],
        },
        base_dir=tmp_path,
    )
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    paths = sim.paths(pose)
    assert len(paths) >= 1 and np.all(np.isfinite(paths.strength))
    centre = pose.to_world(scene.sensor.array.positions_m).mean(axis=0)
    rng = (paths.first_leg_m + np.linalg.norm(paths.anchor_m - centre, axis=1)) / 2
    k = np.argmax(paths.strength / np.linalg.norm(paths.anchor_m - centre, axis=1))
    assert rng[k] == pytest.approx(1.3, abs=0.01)
    rec = sim.simulate_pose(pose, 0)
    assert np.all(np.isfinite(rec.samples))
