"""A dataset folder's identity (the spec and every file its samples read), a failed
run leaving nothing behind, where random poses may land, and spec values that were
accepted silently before."""

import hashlib
import json
import re
import shutil

import numpy as np
import pytest
import trimesh

from acousim.bundled import resolve_scene
from acousim.dataset import SpecError, generate, load_spec, sample_parameters
from processing.base.errors import InputError

WALL = resolve_scene("wall")
SHOEBOX = resolve_scene("shoebox")

SPEC = """
[dataset]
samples = 2
shard_size = 1
seed = 5

[[scenes]]
file = "{scene}"
{extra}

[store]
images = []
snapshot = false
depth_map = false
"""


def _copy_wall(folder):
    """The bundled wall scene and its mesh, copied to `folder`: (scene, mesh)."""
    (folder / "meshes").mkdir()
    mesh = folder / "meshes" / "wall.stl"
    shutil.copy(WALL.parent / "meshes" / "wall.stl", mesh)
    scene = folder / "wall.toml"
    shutil.copy(WALL, scene)
    return scene, mesh


def _spec(folder, scene, extra="", name="spec.toml"):
    p = folder / name
    p.write_text(SPEC.format(scene=scene, extra=extra))
    return p


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _shards(folder):
    return {p.name: _sha(p) for p in sorted(folder.glob("shard_*.h5"))}


# --------------------------------------------------- item 1: what a resume checks


def test_resume_refuses_an_edited_scene_or_mesh_naming_the_file(tmp_path):
    scene, mesh = _copy_wall(tmp_path)
    spec = _spec(tmp_path, "wall.toml")
    out = tmp_path / "out"
    manifest = generate(spec, out)
    first = _shards(out)
    # the manifest records every file the samples read, hashed here independently
    assert manifest["inputs"] == {
        "spec.toml": _sha(spec),
        "wall.toml": _sha(scene),
        "meshes/wall.stl": _sha(mesh),
    }
    assert json.loads((out / "manifest.json").read_text())["inputs"] == manifest["inputs"]

    original = scene.read_text()
    scene.write_text(original + "\n[[materials]]\nname = 'soft'\nreflection = 0.3\n")
    for p in out.glob("shard_00001.*"):
        p.unlink()
    with pytest.raises(InputError, match=r"wall\.toml changed \(sha256 [0-9a-f]{12}"):
        generate(spec, out)
    assert not (out / "shard_00001.h5").exists()  # nothing computed from the edited scene

    scene.write_text(original)
    mesh.write_bytes(mesh.read_bytes() + b"\0")  # the mesh's bytes, not its shape
    with pytest.raises(InputError, match=r"meshes/wall\.stl changed") as err:
        generate(spec, out)
    assert "wall.toml changed" not in str(err.value)

    shutil.copy(WALL.parent / "meshes" / "wall.stl", mesh)  # restored: resumed
    generate(spec, out)
    assert _shards(out) == first


def test_another_spec_is_refused_with_both_hashes(tmp_path):
    _copy_wall(tmp_path)
    spec = _spec(tmp_path, "wall.toml")
    out = tmp_path / "out"
    generate(spec, out)
    other = tmp_path / "other.toml"
    other.write_text(spec.read_text().replace("seed = 5", "seed = 6"))
    want = rf"another spec \(sha256 {_sha(spec)[:12]}\.\.\., other\.toml: {_sha(other)[:12]}"
    with pytest.raises(InputError, match=want):
        generate(other, out)


# ------------------------------------------ item 2: a failed run leaves nothing


@pytest.mark.parametrize(
    "bad,message",
    [
        ("[dataset\n", "not valid TOML"),
        (
            SPEC.format(
                scene=WALL.as_posix(),
                extra="poses = 'random'\nregion = { x = [1.95, 2.15], y = [0, 0], z = [0, 0] }",
            ),
            r"scenes\[0\].region",
        ),
    ],
)
def test_a_failed_run_creates_nothing_and_the_fixed_spec_then_runs(tmp_path, capsys, bad, message):
    from acousim.cli import main

    _copy_wall(tmp_path)
    spec = tmp_path / "spec.toml"
    spec.write_text(bad)
    out = tmp_path / "out"
    assert main(["dataset", str(spec), "--out", str(out), "--workers", "1"]) == 2
    assert re.search(message, capsys.readouterr().err)
    with pytest.raises(SpecError, match=message):
        generate(spec, out)
    assert not out.exists()
    _spec(tmp_path, "wall.toml")
    assert main(["dataset", str(spec), "--out", str(out), "--workers", "1"]) == 0
    assert len(_shards(out)) == 2


def test_a_folder_without_shards_takes_a_new_spec(tmp_path):
    _copy_wall(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    # what a failed run of an older acousim, or of another spec, left behind
    (out / "spec.sha256").write_text("0" * 64 + "\n")
    (out / "inputs.json").write_text(json.dumps({"spec": "x.toml", "files": {"x.toml": "1"}}))
    spec = _spec(tmp_path, "wall.toml")
    generate(spec, out)
    assert len(_shards(out)) == 2
    assert not (out / "spec.sha256").exists()
    assert json.loads((out / "inputs.json").read_text())["files"]["spec.toml"] == _sha(spec)


# ------------------------------------------------ item 3: where random poses land


def _poses(spec, n=12):
    s = load_spec(spec)
    return np.array([sample_parameters(s, i)["pose"]["position_m"] for i in range(n)])


def test_random_poses_in_an_open_scene_keep_the_clearance(tmp_path):
    lo, hi = trimesh.load(WALL.parent / "meshes" / "wall.stl").bounds[:, 0]  # the slab's x
    region = "region = { x = [-1.0, 3.0], y = [-1.0, 1.0], z = [-1.0, 1.0] }"
    spec = _spec(tmp_path, WALL.as_posix(), f"poses = 'random'\nclearance_m = 0.4\n{region}")
    x = _poses(spec)[:, 0]
    assert np.all((x <= lo - 0.4) | (x >= hi + 0.4)), x  # in front of or behind the wall
    assert np.any(x >= hi + 0.4)  # behind the open wall is fine too
    # clearance 0 (the user's wall spec): every draw in the region is accepted
    spec = _spec(tmp_path, WALL.as_posix(), f"poses = 'random'\nclearance_m = 0.0\n{region}")
    assert np.all((_poses(spec) >= -1) & (_poses(spec) <= 3))


def test_random_poses_in_a_closed_room_stay_inside_it(tmp_path):
    box = trimesh.load(SHOEBOX.parent / "meshes" / "shoebox.stl").bounds  # (2, 3)
    region = "region = { x = [-3.0, 5.0], y = [-3.0, 3.0], z = [-0.5, 0.5] }"
    spec = _spec(tmp_path, SHOEBOX.as_posix(), f"poses = 'random'\nclearance_m = 0.1\n{region}")
    p = _poses(spec)
    assert np.all((p >= box[0] + 0.1) & (p <= box[1] - 0.1)), p


@pytest.mark.parametrize(
    "scene,extra,why",
    [
        (
            SHOEBOX,
            "region = { x = [10.0, 12.0], y = [0, 0], z = [0, 0] }",
            r"100 were outside the closed scene .* move the region inside the room",
        ),
        (
            WALL,
            "region = { x = [1.8, 2.3], y = [0, 0], z = [0, 0] }\nclearance_m = 0.5",
            r"100 had a surface nearer than clearance_m = 0.5 m \(lower clearance_m",
        ),
    ],
)
def test_a_region_without_a_pose_says_which_rule_failed(tmp_path, scene, extra, why):
    spec = _spec(tmp_path, scene.as_posix(), f"poses = 'random'\n{extra}")
    with pytest.raises(SpecError, match=r"spec.toml: scenes\[0\].region = .*" + why):
        generate(spec, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_every_scene_region_is_checked_before_any_work(tmp_path):
    good = SPEC.format(scene=WALL.as_posix(), extra="weight = 1.0")
    bad = f"\n[[scenes]]\nfile = '{SHOEBOX.as_posix()}'\nweight = 1e-6\nposes = 'random'\n"
    spec = tmp_path / "spec.toml"
    spec.write_text(good + bad + "region = { x = [10.0, 12.0], y = [0, 0], z = [0, 0] }\n")
    s = load_spec(spec)
    assert all(sample_parameters(s, i)["scene"].endswith("wall.toml") for i in range(2))
    with pytest.raises(SpecError, match=r"scenes\[1\].region"):
        generate(spec, tmp_path / "out")
    assert not (tmp_path / "out").exists()


# ------------------------------------------------- item 7: values accepted silently


@pytest.mark.parametrize(
    "extra,message",
    [
        (
            "[randomize]\nsnr_db = { dist = 'normal', mean = 30 }\n",
            r"randomize.snr_db.sigma: missing",
        ),
        (
            "region = { x = [0, 1], y = [0, 0], z = [0, 0] }\n",
            r"scenes\[0\].region = .*poses = \"random\"",
        ),
    ],
)
def test_values_once_accepted_silently_are_refused(tmp_path, extra, message):
    if extra.startswith("[randomize]"):
        text = SPEC.format(scene=WALL.as_posix(), extra="") + extra
    else:
        text = SPEC.format(scene=WALL.as_posix(), extra=extra)
    (tmp_path / "spec.toml").write_text(text)
    with pytest.raises(SpecError, match=r"spec.toml: " + message):
        load_spec(tmp_path / "spec.toml")


def test_a_bundled_scene_by_name(tmp_path):
    s = load_spec(_spec(tmp_path, "shoebox"))
    assert s.scenes[0].file == SHOEBOX
    assert _sha(SHOEBOX) in s.inputs.values()
    with pytest.raises(SpecError, match=r"scenes\[0\].file = 'shoebx': scene file not found"):
        load_spec(_spec(tmp_path, "shoebx"))


def test_reflection_scale_multiplies_each_coefficient_up_to_one(tmp_path):
    from acousim.dataset.samples import _varied_scene

    spec = load_spec(_spec(tmp_path, "panel_wall", "[randomize]\nreflection_scale = 1.5"))
    params = sample_parameters(spec, 0)
    assert params["conditions"]["reflection_scale"] == 1.5
    scene = _varied_scene(params, spec)
    got = sorted(
        str(np.round(x.reflection, 6).tolist())
        for m in scene.meshes
        for x in (m.material, *m.materials.values())
    )
    # panel_wall.toml: 0.95 and the table [0.8, 0.6, 0.45, 0.35], times 1.5, at most 1
    want = {"1.0", str([1.0, 0.9, 0.675, 0.525])}
    assert set(got) == want


# ----------------------------------------- item 4: raw alone, one M per dataset


def test_raw_carries_its_sample_rate_and_emission_index(tmp_path):
    from scipy.signal import hilbert

    from acousim.dataset import DatasetReader

    spec = _spec(tmp_path, WALL.as_posix()).read_text()
    spec = spec.replace("snapshot = false", "snapshot = false\nraw = true\nimages = ['das']")
    spec = spec.replace("images = []\n", "")
    (tmp_path / "spec.toml").write_text(spec)
    generate(tmp_path / "spec.toml", tmp_path / "out")
    ds = DatasetReader(tmp_path / "out")
    s = ds[0]
    p = s["params"]
    assert p["sample_rate_hz"] == 450e3  # wall.toml's [sensor] sample_rate_hz
    # the wall's echo (its face at x = 2 m, the sensor at the origin: 4 m there and
    # back) starts 4 / c after the call does, at emission_index
    power = (np.abs(hilbert(s["raw"].astype(float), axis=1)) ** 2).sum(axis=0)
    onset = np.flatnonzero(power > 0.3 * power.max())[0]
    expected = p["emission_index"] + 4.0 / p["speed_of_sound_m_s"] * p["sample_rate_hz"]
    assert abs(onset - expected) / p["sample_rate_hz"] < 0.2e-3
    torch_sample = ds.torch(method="das")[0]
    assert torch_sample["raw"].shape == (30, s["raw"].shape[1])  # uRTIS: 30 microphones
    assert torch_sample["raw"].dtype == np.float32


MIXED = """
[[scenes]]
file = "{wall}"
[[scenes]]
file = "{ertis}"
[store]
images = ["das"]
"""


@pytest.mark.parametrize("store", ["raw = true", "snapshot = true", ""])
def test_arrays_of_different_microphone_counts_store_images_only(tmp_path, store):
    text = MIXED.format(wall=WALL.as_posix(), ertis=resolve_scene("ertis_sample").as_posix())
    p = tmp_path / "mix.toml"
    p.write_text(text + store + "\n")
    with pytest.raises(SpecError, match=r"mix.toml: scenes: .*scenes\[0\]: urtis_v1 M = 30, "):
        load_spec(p)
    with pytest.raises(SpecError, match=r"scenes\[1\]: ertis_v3d1 M = 32\)"):  # eRTIS: 32
        load_spec(p)
    p.write_text(text + "raw = false\nsnapshot = false\n")
    assert len(load_spec(p).scenes) == 2


def test_a_scene_lists_the_files_it_reads():
    import tomllib

    from acousim.scene import load_scene

    path = resolve_scene("corridor_rig")
    toml = tomllib.loads(path.read_text())
    declared = [m["file"] for m in toml["meshes"]] + [toml["body"]["trajectory"]["file"]]
    assert load_scene(path).files == tuple(path.parent / f for f in declared)


def test_a_scene_edited_during_the_run_stops_it(tmp_path):
    scene, _ = _copy_wall(tmp_path)
    spec = _spec(tmp_path, "wall.toml")

    def edit_after_the_first_shard(done, total):
        if done == 1:
            scene.write_text(scene.read_text() + "\n# edited\n")

    with pytest.raises(InputError, match=r"spec.toml: changed during the run: wall\.toml changed"):
        generate(spec, tmp_path / "out", progress=edit_after_the_first_shard)
    assert sorted(_shards(tmp_path / "out")) == ["shard_00000.h5"]


def test_shards_of_an_older_acousim_cannot_be_resumed(tmp_path):
    _copy_wall(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "spec.sha256").write_text("0" * 64 + "\n")
    (out / "shard_00000.h5").write_bytes(b"old")
    with pytest.raises(InputError, match=r"out: holds shards without a record of the scene files"):
        generate(_spec(tmp_path, "wall.toml"), out)
    assert (out / "shard_00000.h5").read_bytes() == b"old"
