"""Random dataset poses the simulation accepts: every pose the sampler accepts is
one the tracer accepts (the emitter and every microphone at least 1 cm from every
surface and 1 mm from every point reflector, no emitter inside a solid; a rig's other
sonars' emitters too, with crosstalk), a refused draw is drawn again from the seeded
generator, and ``clearance_m`` is a true distance to the mesh.  Distances are checked
here by a point-to-triangle distance written in the test, on the scene's own STL."""

import hashlib

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

import processing as P
from acousim.bundled import resolve_scene
from acousim.dataset import SpecError, generate, load_spec, sample_parameters

#: the simulation's clearance (docs/scene-format.md, "Checked before anything is computed")
SIMULATION_CLEARANCE_M = 0.01

SCENE = """
[scene]
name = "box"

[sensor]
array = "urtis_v1"
sample_rate_hz = 450000
direct_path = false

[sensor.pose]
position_m = [0.0, 0.0, 0.0]

[simulation]
max_range_m = 1.0
bounces = 1
quality = "fast"

[[materials]]
name = "wall"
reflection = 0.9

[[meshes]]
file = "box.stl"
material = "wall"
"""

SPEC = """
[dataset]
samples = {samples}
shard_size = 3
seed = {seed}

[[scenes]]
file = "box.toml"
poses = "random"
region = {region}
clearance_m = {clearance}

{randomize}
[store]
images = []
snapshot = false
depth_map = false
"""

#: within 3 cm of the box's edge at x = z = 0.5: the urtis_v1 array (2 x 1.5 cm,
#: emitter at its centre) often reaches within 1 cm of a wall there
TIGHT = "{ x = [0.47, 0.4999], y = [-0.2, 0.2], z = [0.47, 0.4999], yaw_deg = [-90.0, 90.0] }"


def _room(folder, obstacle=False):
    """A 1 m cube room (faces inward) centred at 0, and a 0.2 m cube inside it at
    (0.2, 0.2, 0) (faces outward) if `obstacle`, as box.stl and box.toml in `folder`."""
    room = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    room.invert()
    if obstacle:
        block = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
        block.apply_translation((0.2, 0.2, 0.0))
        room = trimesh.util.concatenate([room, block])
    room.export(folder / "box.stl")
    (folder / "box.toml").write_text(SCENE)
    return folder / "box.stl"


JITTER = """[randomize]
mount_jitter_deg = { dist = "normal", mean = 0.0, sigma = 5.0 }
mount_jitter_m = { dist = "normal", mean = 0.0, sigma = 0.002 }
"""


def _spec(folder, region, clearance, samples=6, seed=3, randomize=JITTER):
    path = folder / "spec.toml"
    text = SPEC.format(
        samples=samples, seed=seed, region=region, clearance=clearance, randomize=randomize
    )
    path.write_text(text)
    return path


def _triangle_distance(p, tri):
    """Distance from point p (3,) to each triangle of tri (F, 3, 3): to its plane
    where p's foot lies inside it, else to the nearest of its three sides."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    height = np.einsum("ij,ij->i", p - a, n)
    foot = p - height[:, None] * n
    inside = np.ones(len(tri), bool)
    for u, v in ((a, b), (b, c), (c, a)):  # the foot on the inner side of every side
        inside &= np.einsum("ij,ij->i", np.cross(v - u, foot - u), n) >= 0
    side = np.full(len(tri), np.inf)
    for u, v in ((a, b), (b, c), (c, a)):
        t = np.clip(np.einsum("ij,ij->i", p - u, v - u) / np.einsum("ij,ij->i", v - u, v - u), 0, 1)
        side = np.minimum(side, np.linalg.norm(p - (u + t[:, None] * (v - u)), axis=1))
    return np.where(inside, np.abs(height), side)


def _mesh_distance(points, stl):
    """Nearest distance (K,) from each point (K, 3) to the STL's triangles."""
    tri = np.asarray(trimesh.load(stl, process=False).triangles)
    return np.array([_triangle_distance(p, tri).min() for p in points])


def _ends(pose):
    """The urtis_v1 emitter and microphones (31, 3) m in the world at a stored pose
    (position, yaw/pitch/roll in degrees: rotations about z, then y, then x)."""
    a = P.urtis_v1()
    R = Rotation.from_euler(
        "ZYX", [pose["yaw_deg"], pose["pitch_deg"], pose["roll_deg"]], degrees=True
    ).as_matrix()
    local = np.vstack([a.emitter_m[None], a.positions_m])
    return local @ R.T + np.asarray(pose["position_m"])


def _sha(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.glob("shard_*.h5")}


def test_the_tight_region_often_puts_the_sensor_on_a_wall(tmp_path):
    """The premise of the next tests: a plain uniform draw in TIGHT (no redraw) puts
    the emitter or a microphone within 1 cm of a wall most of the time."""
    stl = _room(tmp_path)
    rng = np.random.default_rng(0)
    near = 0
    for _ in range(60):
        pose = {
            "position_m": [
                rng.uniform(0.47, 0.4999),
                rng.uniform(-0.2, 0.2),
                rng.uniform(0.47, 0.4999),
            ],
            "yaw_deg": rng.uniform(-90, 90),
            "pitch_deg": 0.0,
            "roll_deg": 0.0,
        }
        near += _mesh_distance(_ends(pose), stl).min() < SIMULATION_CLEARANCE_M
    assert near > 30, near


def test_a_tiny_clearance_in_a_tight_region_generates_every_sample(tmp_path):
    stl = _room(tmp_path)
    spec = _spec(tmp_path, TIGHT, 0.001)
    manifest = generate(spec, tmp_path / "out")
    table = manifest["sample_table"]
    assert sorted(s["index"] for s in table) == list(range(6))
    assert len(_sha(tmp_path / "out")) == 2
    for s in table:
        gap = _mesh_distance(_ends(s["pose"]), stl).min()
        assert gap >= SIMULATION_CLEARANCE_M, (s["index"], gap)
        assert np.all(np.abs(s["pose"]["position_m"]) < 0.5)  # inside the room
    # the same seed gives the same bytes
    generate(spec, tmp_path / "again")
    assert _sha(tmp_path / "again") == _sha(tmp_path / "out")


def test_clearance_m_is_a_true_distance_also_off_the_axes(tmp_path):
    """Around the corner of a block in the room, where a surface may be near along
    no axis (its edge diagonally): every drawn sensor end keeps clearance_m."""
    stl = _room(tmp_path, obstacle=True)
    region = "{ x = [0.28, 0.42], y = [0.28, 0.42], z = [-0.05, 0.05], yaw_deg = [-180.0, 180.0] }"
    spec = load_spec(_spec(tmp_path, region, 0.08, samples=25))
    gaps = [_mesh_distance(_ends(sample_parameters(spec, i)["pose"]), stl).min() for i in range(25)]
    assert min(gaps) >= 0.08, min(gaps)
    # the premise: the block's edge (0.3, 0.3, z) is nearer than 0.08 m to part of
    # the region, diagonally: from (0.35, 0.35, 0) the six axis probes miss the
    # block (x and y beyond its faces) and meet the walls 0.15 m or more away
    corner = np.array([[0.35, 0.35, 0.0]])
    assert _mesh_distance(corner, stl)[0] < 0.08


@pytest.mark.parametrize(
    "region,clearance,why",
    [
        (  # the emitter within 5 mm of the wall x = 0.5, whatever the draw
            "{ x = [0.495, 0.4999], y = [-0.1, 0.1], z = [-0.1, 0.1] }",
            0.0,
            r"100 put the emitter or a microphone within the simulation's 0.01 m of a surface",
        ),
        (  # the position 5 to 5.5 cm under the ceiling, the microphones 7.7 mm higher
            "{ x = [-0.1, 0.1], y = [-0.1, 0.1], z = [0.445, 0.449] }",
            0.05,
            r"100 put the emitter or a microphone nearer than clearance_m = 0.05 m",
        ),
    ],
)
def test_a_region_where_no_pose_fits_is_refused_before_any_work(tmp_path, region, clearance, why):
    _room(tmp_path)
    spec = _spec(tmp_path, region, clearance, randomize="")
    with pytest.raises(
        SpecError, match=r"spec.toml: scenes\[0\].region = .*no usable pose in 100 draws.*" + why
    ):
        generate(spec, tmp_path / "out")
    assert not (tmp_path / "out").exists()


# ------------------------------------------------ the bundled wall: a 0.1 m solid slab

WALL = resolve_scene("wall")  # its slab: 2 <= x <= 2.1 m, 10 x 10 m


def _wall_spec(folder, region, extra="", samples=20):
    path = folder / "spec.toml"
    path.write_text(
        f"[dataset]\nsamples = {samples}\nseed = 11\n[[scenes]]\nfile = '{WALL.as_posix()}'\n"
        f"poses = 'random'\nregion = {region}\nclearance_m = 0.001\n{extra}"
    )
    return path


def test_no_emitter_inside_a_solid_wall(tmp_path):
    """Draws straddling the slab: none inside it (the simulation refuses an emitter
    inside a closed mesh), none within 1 cm of it (the premise: 1 draw in 3 lies in
    x in (2, 2.1))."""
    stl = WALL.parent / "meshes" / "wall.stl"
    region = "{ x = [1.9, 2.2], y = [-0.5, 0.5], z = [-0.5, 0.5], yaw_deg = [-180.0, 180.0] }"
    spec = load_spec(_wall_spec(tmp_path, region))
    for i in range(20):
        ends = _ends(sample_parameters(spec, i)["pose"])
        assert not np.any((ends[:, 0] > 2.0) & (ends[:, 0] < 2.1)), i
        assert _mesh_distance(ends, stl).min() >= SIMULATION_CLEARANCE_M, i


def test_a_region_inside_a_solid_is_refused_before_any_work(tmp_path):
    spec = _wall_spec(tmp_path, "{ x = [2.03, 2.07], y = [-0.5, 0.5], z = [-0.5, 0.5] }")
    why = r"100 put an emitter inside a closed mesh .*move the region out of it"
    with pytest.raises(
        SpecError, match=r"scenes\[0\].region = .*no usable pose in 100 draws.*" + why
    ):
        generate(spec, tmp_path / "out")
    assert not (tmp_path / "out").exists()


RIG = """
[body]
pose = {{ position_m = [0, 0, 0] }}
[rig]
crosstalk = {crosstalk}
[[sensors]]
name = "a"
array = "urtis_v1"
mount = {{ position_m = [0.5, 0.0, 0.0] }}
firing = {{ rate_hz = 20, offset_s = 0.005, count = 2 }}
[[sensors]]
name = "b"
array = "urtis_v1"
firing = {{ rate_hz = 20, offset_s = 0.0, count = 2 }}
[[meshes]]
file = "{stl}"
"""


@pytest.mark.parametrize("crosstalk", [True, False])
def test_a_rigs_other_emitter_keeps_the_clearance_with_crosstalk(tmp_path, crosstalk):
    """Sonar b sampled, sonar a 0.5 m ahead of it on the body, the body 1.35 to
    1.55 m before the wall: a's emitter 1.85 to 2.05 m, within 1 cm of the wall or
    inside it in 3 draws out of 10.  With crosstalk a's call is simulated, from its
    emitter, which must keep clear; without, a is not simulated and may stand anywhere."""
    stl = (WALL.parent / "meshes" / "wall.stl").as_posix()
    (tmp_path / "rig.toml").write_text(RIG.format(crosstalk=str(crosstalk).lower(), stl=stl))
    region = "{ x = [1.35, 1.55], y = [-0.2, 0.2], z = [-0.2, 0.2] }"
    (tmp_path / "spec.toml").write_text(
        "[dataset]\nsamples = 30\nseed = 2\n[[scenes]]\nfile = 'rig.toml'\nsensor = 'b'\n"
        f"poses = 'random'\nregion = {region}\nclearance_m = 0.001\n"
    )
    spec = load_spec(tmp_path / "spec.toml")
    xa = []
    for i in range(30):
        body = sample_parameters(spec, i)["body_pose"]
        assert body["yaw_deg"] == 0 and body["pitch_deg"] == 0
        xa.append(body["position_m"][0] + 0.5)  # a's emitter: its array's centre
    if crosstalk:
        assert max(xa) <= 2.0 - SIMULATION_CLEARANCE_M, max(xa)
    else:
        assert max(xa) > 2.0 - SIMULATION_CLEARANCE_M  # drawn as before: a is not simulated


def test_a_rig_with_crosstalk_near_a_wall_generates_every_sample(tmp_path):
    """The body 1.47 to 1.52 m before the wall: sonar a's emitter within 1 cm of it
    or inside it in 6 draws out of 10; every sample is simulated (the tracer, which
    checks a's emitter for its call, refuses none)."""
    stl = (WALL.parent / "meshes" / "wall.stl").as_posix()
    scene = RIG.format(crosstalk="true", stl=stl) + "[simulation]\nmax_range_m = 3.0\n"
    (tmp_path / "rig.toml").write_text(scene + "quality = 'fast'\n")
    region = "{ x = [1.47, 1.52], y = [-0.2, 0.2], z = [-0.2, 0.2] }"
    (tmp_path / "spec.toml").write_text(
        "[dataset]\nsamples = 4\nseed = 2\n[[scenes]]\nfile = 'rig.toml'\nsensor = 'b'\n"
        f"poses = 'random'\nregion = {region}\nclearance_m = 0.001\n"
        "[store]\nimages = []\nsnapshot = false\ndepth_map = false\n"
    )
    table = generate(tmp_path / "spec.toml", tmp_path / "out")["sample_table"]
    assert sorted(s["index"] for s in table) == [0, 1, 2, 3]
    assert all(s["body_pose"]["position_m"][0] + 0.5 <= 1.99 for s in table)


def test_no_sensor_end_within_a_millimetre_of_a_point_reflector(tmp_path):
    """A point reflector inside the region of the array's centre (the simulation
    refuses a point within 1 mm of the emitter or a microphone): every sample keeps
    1 mm; the premise: 1 uniform draw in 10 or more would not."""
    (tmp_path / "points.toml").write_text(
        '[sensor]\narray = "urtis_v1"\n[[points]]\nposition_m = [1.0, 0.0, 0.0]\n'
    )
    region = "{ x = [0.999, 1.001], y = [-0.01, 0.01], z = [-0.008, 0.008] }"
    (tmp_path / "spec.toml").write_text(
        "[dataset]\nsamples = 30\nseed = 4\n[[scenes]]\nfile = 'points.toml'\n"
        f"poses = 'random'\nregion = {region}\nclearance_m = 0.0\n"
    )
    spec = load_spec(tmp_path / "spec.toml")
    point = np.array([1.0, 0.0, 0.0])
    gaps = [
        np.linalg.norm(_ends(sample_parameters(spec, i)["pose"]) - point, axis=1).min()
        for i in range(30)
    ]
    assert min(gaps) >= 1e-3, min(gaps)
    rng = np.random.default_rng(1)
    still = {"yaw_deg": 0.0, "pitch_deg": 0.0, "roll_deg": 0.0}
    draws = [
        [rng.uniform(0.999, 1.001), rng.uniform(-0.01, 0.01), rng.uniform(-0.008, 0.008)]
        for _ in range(200)
    ]
    near = [
        np.linalg.norm(_ends({**still, "position_m": p}) - point, axis=1).min() < 1e-3
        for p in draws
    ]
    assert np.mean(near) > 0.1, np.mean(near)
