"""A dataset's quality preset: ``--quality`` (or ``[dataset] quality``) is the
scene's ``simulation.quality`` for every scene, and a folder is resumed only under
the quality it was made with."""

import json

import pytest

from acousim.cli import main
from acousim.dataset import DatasetReader, SpecError, generate, load_spec
from tests.acousim.dataset.wall import wall_spec

SCENE = """
[sensor]
array = "urtis_v1"
direct_path = false
[simulation]
max_range_m = 2.5
rays = 300
bounces = 1
snr_db = 200.0
{quality}
[[meshes]]
file = "{{mesh}}"
"""

SPEC = """
[dataset]
samples = 2
shard_size = 1
seed = 4
{quality}

[[scenes]]
file = "wall.toml"

[store]
raw = true
images = []
snapshot = false
depth_map = false
"""


def _raw(folder):
    r = DatasetReader(folder)
    return [r[i]["raw"].tobytes() for i in range(len(r))]


def test_quality_fast_equals_a_scene_that_sets_it(tmp_path, capsys):
    (tmp_path / "flag").mkdir()
    (tmp_path / "file").mkdir()
    flag = wall_spec(tmp_path / "flag", SCENE.format(quality=""), SPEC.format(quality=""))
    in_file = wall_spec(
        tmp_path / "file",
        SCENE.format(quality='quality = "fast"'),
        SPEC.format(quality=""),
    )
    assert main(["dataset", str(flag), "--out", str(tmp_path / "a"), "--quality", "fast"]) == 0
    generate(in_file, tmp_path / "b")
    generate(flag, tmp_path / "default")
    fast = _raw(tmp_path / "a")
    assert fast == _raw(tmp_path / "b")
    assert fast != _raw(tmp_path / "default")  # the preset changes the recordings
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["quality"] == "fast"
    assert json.loads((tmp_path / "a" / "inputs.json").read_text())["quality"] == "fast"

    # resuming under another quality (here: none given, each scene's own) is refused
    capsys.readouterr()
    assert main(["dataset", str(flag), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "another quality (the shards: 'fast'; this run: each scene's own)" in err
    assert main(["dataset", str(flag), "--out", str(tmp_path / "a"), "--quality", "fast"]) == 0


def test_the_spec_key_is_the_flag(tmp_path):
    spec = wall_spec(tmp_path, SCENE.format(quality=""), SPEC.format(quality='quality = "fast"'))
    assert load_spec(spec).quality == "fast"
    generate(spec, tmp_path / "a")
    generate(spec, tmp_path / "b", quality="fast")  # the same, so the folder resumes
    assert _raw(tmp_path / "a") == _raw(tmp_path / "b")
    assert generate(spec, tmp_path / "b", quality="fast")["summary"]["samples_computed"] == 0


def test_an_unknown_quality_names_the_key(tmp_path):
    spec = wall_spec(tmp_path, SCENE.format(quality=""), SPEC.format(quality='quality = "best"'))
    with pytest.raises(SpecError, match=r"dataset\.quality.*fast, default, reference"):
        load_spec(spec)
