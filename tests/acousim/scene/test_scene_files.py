"""Scene files: the bundled scenes load, and bad input is refused with clear errors."""

import math
import shutil

import numpy as np
import pytest

from acousim.scene import Pose, SceneError, load_scene, parse_scene, rotation
from processing.base.errors import InputError
from tests import REPO

SCENES = REPO / "scenes"


@pytest.mark.parametrize("name", ["corridor", "shoebox", "wall", "sphere", "points", "panel_wall"])
def test_bundled_scenes_load(name):
    sc = load_scene(SCENES / f"{name}.toml")
    assert sc.name == name and sc.description and sc.file_sha256
    assert len(sc.sensor.poses) >= 1


def test_corridor_drive_is_at_least_5_s_at_10_hz():
    sc = load_scene(SCENES / "corridor.toml")
    assert sc.sensor.rate_hz == 10 and len(sc.sensor.poses) >= 50
    assert sc.sensor.poses[-1].time_s >= 4.9
    assert sc.sensor.array.name == "urtis_v1" and sc.sensor.sample_rate_hz == 450e3


def base(**over):
    d = {"sensor": {"array": "urtis_v1"}, "points": [{"position_m": [1.0, 0, 0]}]}
    for k, v in over.items():
        d[k] = v
    return d


@pytest.mark.parametrize(
    "data,pattern",
    [
        (base(simulaton={}), r"simulaton: unknown key 'simulaton'; did you mean 'simulation'"),
        (base(simulation={"rays": -5}), r"simulation.rays = -5: outside the allowed range"),
        (base(simulation={"bounces": 1.5}), r"simulation.bounces = 1.5: must be a whole number"),
        (base(simulation={"max_rnage_m": 3}), r"did you mean 'max_range_m'"),
        (base(simulation={"snr_db": math.nan}), r"simulation.snr_db = nan: .*not NaN"),
        (base(simulation={"absorption": "no"}), r"simulation.absorption = 'no': must be true"),
        (base(environment={"humidity_percent": 500}), r"environment.humidity_percent = 500"),
        (base(environment=5), r"environment = 5: must be a table"),
        (base(sensor={"array": "urtis"}), r"sensor.array = 'urtis': is not one of .*did you mean"),
        (
            base(sensor={"array": "urtis_v1", "sample_rate_hz": 80000}),
            r"sensor.sample_rate_hz = 80000.0: is below twice",
        ),
        (
            base(sensor={"array": "urtis_v1", "emitter_m": [0.0, 0.0, 11.0]}),
            r"sensor.emitter_m = \[0.0, 0.0, 11.0\]: must be .* in \[-10, 10\]",
        ),
        (base(points=[{"position_m": [1.0, math.nan, 0]}]), r"points\[0\].position_m = .*must be"),
        (base(points=[{"position_m": [1.0]}]), r"points\[0\].position_m = \[1.0\]: must be"),
        (
            base(meshes=[{"file": "nope.stl"}]),
            r"meshes\[0\].file = 'nope.stl': mesh file not found",
        ),
        (base(meshes=[{"file": "wall.toml", "units": "inch"}]), r"meshes\[0\].units = 'inch'"),
        (base(materials=[{"name": "m", "reflection": 5}]), r"materials\[0\].reflection = 5"),
        ({"sensor": {"array": "urtis_v1"}}, r"neither meshes nor points"),
    ],
)
def test_validation_errors_name_key_and_value(data, pattern):
    with pytest.raises(SceneError, match=pattern) as exc:
        parse_scene(data, base_dir=SCENES, source="bad.toml")
    assert str(exc.value).startswith("bad.toml: ")
    assert isinstance(exc.value, InputError)


def test_not_toml_and_missing_file(tmp_path):
    f = tmp_path / "x.toml"
    f.write_text("this is = = not toml")
    with pytest.raises(SceneError, match="x.toml: not valid TOML"):
        load_scene(f)
    with pytest.raises(SceneError, match="missing.toml: no such file, nor a bundled scene"):
        load_scene(tmp_path / "missing.toml")


def test_a_bundled_scene_by_its_name_as_the_command_line_takes_it(tmp_path, monkeypatch):
    # from an empty folder: "wall" is the bundled wall (its file's scene, byte for
    # byte the same values), a near miss gets the command line's suggestion, and a
    # file of that name in the folder wins over the bundled scene
    from acousim.bundled import find_scene

    monkeypatch.chdir(tmp_path)
    wall = load_scene("wall")
    assert str(wall.source) == str(find_scene("wall")) and wall.name == "wall"
    with pytest.raises(SceneError, match="corridr: .*did you mean 'corridor'"):
        load_scene("corridr")
    mine = (
        '[scene]\nname = "mine"\n[sensor]\narray = "urtis_v1"\n[[points]]\nposition_m = [1, 0, 0]\n'
    )
    (tmp_path / "wall").write_text(mine)
    assert load_scene("wall").name == "mine"


def test_broken_meshes_are_refused(tmp_path):
    from acousim.simulator import Simulator

    (tmp_path / "empty.obj").write_text("# no faces\nv 0 0 0\n")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n")
    for name, pattern in [("empty.obj", "no faces"), ("nan.obj", "NaN")]:
        sc = parse_scene(
            {"sensor": {"array": "urtis_v1"}, "meshes": [{"file": name}]}, base_dir=tmp_path
        )
        with pytest.raises(ValueError, match=f"{name}.*{pattern}"):
            Simulator(sc)


def test_pose_inside_a_wall_is_refused(tmp_path):
    from acousim.simulator import Simulator

    shutil.copy(SCENES / "meshes" / "wall.stl", tmp_path / "wall.stl")
    sc = parse_scene(
        {
            "sensor": {"array": "urtis_v1", "pose": {"position_m": [2.05, 0, 0]}},
            "meshes": [{"file": "wall.stl"}],
        },
        base_dir=tmp_path,
    )
    with pytest.raises(ValueError, match="inside a closed mesh"):
        Simulator(sc).paths(sc.sensor.poses[0])


def test_a_room_with_outward_normals_says_to_invert_them(tmp_path):
    """A closed box exported as modellers make it (normals out) with the sensor in it:
    the refusal says that a room's faces must face into it, and where the docs say so."""
    import trimesh

    from acousim.simulator import Simulator

    trimesh.creation.box((4.0, 4.0, 3.0)).export(tmp_path / "room.stl")
    (tmp_path / "room.toml").write_text(
        '[sensor]\narray = "urtis_v1"\n[[meshes]]\nfile = "room.stl"\n'
    )
    sc = load_scene(tmp_path / "room.toml")
    with pytest.raises(InputError) as info:
        Simulator(sc).simulate_pose(sc.sensor.poses[0], 0)
    msg = str(info.value)
    assert msg.startswith(f"{tmp_path / 'room.toml'}: pose 0: the sensor at [0.0, 0.0, 0.0] m")
    assert "inside a closed mesh" in msg and "normals may be inverted" in msg
    assert 'docs/scene-format.md, "Meshes"' in msg
    docs = (REPO / "docs" / "scene-format.md").read_text()
    section = docs.split("\n## Meshes\n")[1].split("\n## ")[0]
    assert "normals pointing inwards" in section and "invert" in section


def test_pose_rotation_conventions():
    np.testing.assert_allclose(rotation(np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rotation(0, np.pi / 2) @ [1, 0, 0], [0, 0, -1], atol=1e-15)
    p = Pose([1.0, 2.0, 3.0], 0.3, 0.2, 0.1)
    x = np.array([[0.5, -0.2, 0.1]])
    np.testing.assert_allclose(p.to_sensor(p.to_world(x)), x, atol=1e-14)


@pytest.mark.parametrize(
    "sensor,pattern",
    [
        ({"pose": {"pitch_deg": 120}}, r"sensor.pose.pitch_deg = 120"),
        ({"pose": {"yaw_deg": "left"}}, r"sensor.pose.yaw_deg = 'left'"),
        ({"trajectory": {"poses": [[0, 0, 0, 0, 95]]}}, r"trajectory row 0 pitch_deg = 95.0"),
        ({"trajectory": {"poses": [[0, 0, 0, 400]]}}, r"trajectory row 0 yaw_deg = 400.0"),
    ],
)
def test_pose_angles_in_tables_and_trajectories(sensor, pattern):
    data = base(sensor={"array": "urtis_v1", **sensor})
    with pytest.raises(SceneError, match=pattern):
        parse_scene(data, base_dir=SCENES, source="bad.toml")


def test_pose_refuses_non_finite_values():
    with pytest.raises(InputError, match="Pose.yaw_rad = nan"):
        Pose([0, 0, 0], math.nan)
    with pytest.raises(InputError, match="Pose.position_m"):
        Pose([0, 0])


def test_fractional_delays_are_the_renderers():
    from acousim.scene.model import FRACTIONAL_DELAYS
    from acousim.synth.render import INTERPOLATORS

    assert set(FRACTIONAL_DELAYS) == {"sinc", "lagrange", "nearest"}
    assert set(FRACTIONAL_DELAYS) <= set(INTERPOLATORS)


def _box_scene(tmp_path, extents, **mesh_keys) -> str:
    """A scene file with one box mesh of `extents` (in the file's numbers) and the
    keys `mesh_keys` of its [[meshes]] table; returns the file's path."""
    import trimesh

    trimesh.creation.box(extents).export(tmp_path / "box.stl")
    keys = "".join(f"{k} = {v!r}\n".replace("'", '"') for k, v in mesh_keys.items())
    (tmp_path / "box.toml").write_text(
        f'[sensor]\narray = "urtis_v1"\n[[meshes]]\nfile = "box.stl"\n{keys}'
    )
    return str(tmp_path / "box.toml")


def test_a_mesh_in_millimetres_without_units_is_refused(tmp_path):
    """A 6 x 6.5 x 5.3 m room drawn in mm, read as metres, spans kilometres."""
    path = _box_scene(tmp_path, (6000.0, 6500.0, 5300.0))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: meshes[0].units: box.stl spans 6000 x 6500 x 5300 m")
    assert 'set units = "mm"' in msg and 'units = "m" if metres were meant' in msg


@pytest.mark.parametrize(
    "extents,keys,metres",
    [
        ((6000.0, 6500.0, 5300.0), {"units": "mm"}, 6.5),  # its units given
        ((6000.0, 6500.0, 5300.0), {"units": "m"}, 6500.0),  # metres meant: any size
        ((6000.0, 6500.0, 5300.0), {"scale": 0.001}, 6.5),  # scaled to metres
        ((990.0, 20.0, 5.0), {}, 990.0),  # a kilometre at most, in metres
    ],
)
def test_a_mesh_with_units_or_of_plausible_size_is_read(tmp_path, extents, keys, metres):
    scene = load_scene(_box_scene(tmp_path, extents, **keys))
    T = scene.meshes[0].transform
    assert np.abs(T[:3, :3] @ np.array(extents)).max() == pytest.approx(metres)


def _trajectory_scene(tmp_path, csv_text: str, **more) -> str:
    (tmp_path / "drive.csv").write_text(csv_text)
    extra = "".join(f"{k} = {v}\n" for k, v in more.items())
    (tmp_path / "t.toml").write_text(
        '[sensor]\narray = "urtis_v1"\n[sensor.trajectory]\nfile = "drive.csv"\n'
        f"rate_hz = 10\n{extra}[[points]]\nposition_m = [1.0, 0.0, 0.0]\n"
    )
    return str(tmp_path / "t.toml")


@pytest.mark.parametrize(
    "csv_text,pattern",
    [
        (
            "x,y,z,yaw_deg\n0,0,0,0\n",
            r"t\.toml: sensor\.trajectory\.file: .*drive\.csv: line 1 \('x,y,z,yaw_deg'\) is "
            r"not numbers: a trajectory CSV has no header row .* start it with '#'",
        ),
        (
            "0,0,0,0\n0.05,0,0\n",
            r"drive\.csv: line 2 has 3 column\(s\), 4 \(as line 1\) expected",
        ),
        (
            "# x, y, z\n\n0,0,0,0,1,2,3\n",
            r"drive\.csv: line 3 has 7 column\(s\), 4, 5 or 6 expected",
        ),
        ("0,0,0,0\n0.1,0,zero,0\n", r"drive\.csv: line 2: 'zero' is not a number"),
        ("# only a comment\n", r"drive\.csv: no rows"),
    ],
)
def test_a_bad_trajectory_csv_names_its_line(tmp_path, csv_text, pattern):
    with pytest.raises(SceneError, match=pattern) as info:
        load_scene(_trajectory_scene(tmp_path, csv_text))
    assert "usecols" not in str(info.value) and "float64" not in str(info.value)


def test_a_trajectory_csv_with_comments_is_read(tmp_path):
    text = "# x, y, z, yaw_deg, pitch_deg\n0, 0, 0.3, 0, 0\n\n0.05, 0.01, 0.3, 10, -5  # turning\n"
    poses = load_scene(_trajectory_scene(tmp_path, text)).sensor.poses
    assert len(poses) == 2 and poses[1].time_s == pytest.approx(0.1)
    np.testing.assert_allclose(poses[1].position_m, [0.05, 0.01, 0.3])
    assert poses[1].yaw_rad == pytest.approx(math.radians(10))
    assert poses[1].pitch_rad == pytest.approx(math.radians(-5))


def test_a_trajectory_with_both_file_and_poses_is_refused(tmp_path):
    path = _trajectory_scene(tmp_path, "0,0,0,0\n", poses="[[0, 0, 0, 0]]")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert str(info.value) == (
        f"{path}: sensor.trajectory: give either 'file' or 'poses' (the poses inline), not both"
    )


def test_a_mesh_without_units_is_read_once_for_the_check_and_the_world(tmp_path, monkeypatch):
    """The unitless check measures the mesh the world is then built from: the file is
    read from the disk once, and the world holds the box where the file puts it."""
    import trimesh

    from acousim.trace.world.build import build_world

    trimesh.creation.box((2.0, 3.0, 4.0)).export(tmp_path / "box.obj")
    (tmp_path / "box.toml").write_text(
        '[sensor]\narray = "urtis_v1"\n[[meshes]]\nfile = "box.obj"\nposition_m = [5, 0, 0]\n'
    )
    reads = []
    load = trimesh.load

    def counted(path, *args, **kwargs):
        reads.append(str(path))
        return load(path, *args, **kwargs)

    monkeypatch.setattr(trimesh, "load", counted)
    world = build_world(load_scene(tmp_path / "box.toml"))
    assert reads == [str(tmp_path / "box.obj")]
    corners = world.triangles.reshape(-1, 3)
    np.testing.assert_allclose(corners.min(axis=0), [4.0, -1.5, -2.0], atol=1e-12)
    np.testing.assert_allclose(corners.max(axis=0), [6.0, 1.5, 2.0], atol=1e-12)


def test_a_mesh_changed_after_loading_is_read_again(tmp_path):
    """The mesh kept from the check is used only while the file is unchanged."""
    import os

    import trimesh

    from acousim.trace.world.build import build_world

    trimesh.creation.box((2.0, 2.0, 2.0)).export(tmp_path / "box.obj")
    (tmp_path / "box.toml").write_text(
        '[sensor]\narray = "urtis_v1"\n[[meshes]]\nfile = "box.obj"\n'
    )
    scene = load_scene(tmp_path / "box.toml")
    trimesh.creation.box((1.0, 1.0, 1.0)).export(tmp_path / "box.obj")
    os.utime(tmp_path / "box.obj", ns=(1, 1))  # another time, whatever the clock's grain
    corners = build_world(scene).triangles.reshape(-1, 3)
    np.testing.assert_allclose(corners.max(axis=0) - corners.min(axis=0), [1.0, 1.0, 1.0])
