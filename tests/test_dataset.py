"""Dataset generation: deterministic across workers, resumable, Dask, reader, errors."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from acousim.dataset import DatasetReader, SpecError, generate, load_spec

SCENES = Path(__file__).resolve().parent.parent / "scenes"

SPEC = """
[dataset]
name = "tiny"
samples = 6
shard_size = 2
seed = 3

[[scenes]]
file = "{scenes}/corridor.toml"
poses = "random"
region = {{ x = [1.0, 10.0], y = [-0.5, 0.5], z = [0.3, 0.6], yaw_deg = [-10.0, 10.0] }}

[[scenes]]
file = "{scenes}/wall.toml"
weight = 0.5

[randomize]
snr_db = {{ dist = "uniform", range = [10.0, 30.0] }}
temperature_c = {{ dist = "uniform", range = [15.0, 25.0] }}
mount_jitter_deg = {{ dist = "normal", sigma = 1.0 }}

[store]
images = ["das"]
step_deg = 6.0
max_bins = 64
"""


@pytest.fixture
def spec(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(SPEC.format(scenes=SCENES))
    return p


def shard_hashes(folder):
    return [s["sha256"] for s in json.loads((folder / "manifest.json").read_text())["shards"]]


def test_same_bytes_on_one_or_two_workers_and_reader(spec, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    generate(spec, a, workers=1)
    m = generate(spec, b, workers=2)
    assert shard_hashes(a) == shard_hashes(b)
    assert m["samples"] == 6 and len(m["shards"]) == 3
    r = DatasetReader(b, verify=True)
    assert len(r) == 6
    s = r[4]
    assert s["params"]["index"] == 4
    assert s["image/das"].ndim == 3 and s["image/das"].shape[1:] == (11, 31)
    assert s["labels/depth_m"].shape == (11, 31)
    assert np.isfinite(s["labels/depth_m"]).any()
    assert s["labels/position_sensor_m"].shape[1] == 3
    # the depth map sees the nearest wall: the corridor is 2 m wide, the wall scene 2 m
    assert 0.3 < np.nanmin(s["labels/depth_m"]) < 2.5
    x, y = r.torch(("image/das", "labels/depth_m"))[4]
    assert x.dtype == np.float32 and y.shape == (11, 31)


def test_resume_after_a_kill_gives_the_same_dataset(spec, tmp_path, monkeypatch):
    clean = tmp_path / "clean"
    generate(spec, clean, workers=1)
    killed = tmp_path / "killed"
    import acousim.dataset.generation as g

    real = g.make_sample
    calls = {"n": 0}

    def dying(spec_, i):
        calls["n"] += 1
        if calls["n"] == 4:  # in the middle of the second shard
            raise KeyboardInterrupt
        return real(spec_, i)

    monkeypatch.setattr(g, "make_sample", dying)
    with pytest.raises(KeyboardInterrupt):
        generate(spec, killed, workers=1)
    assert (killed / "shard_00000.h5").is_file() and not (killed / "shard_00001.h5").exists()
    assert not list(killed.glob(".*part"))  # nothing half-written looks complete
    monkeypatch.setattr(g, "make_sample", real)
    m = generate(spec, killed, workers=1)
    assert m["summary"]["samples_computed"] == 4  # shard 0 was kept
    assert shard_hashes(killed) == shard_hashes(clean)
    assert (killed / "manifest.json").read_text() == (clean / "manifest.json").read_text()


def test_bytes_do_not_depend_on_when_h5py_objects_are_released(spec, tmp_path, monkeypatch):
    """HDF5 places a chunk when its cache is flushed; h5py flushes when the last
    reference goes.  Holding every dataset and group until the file closes (as Dask's
    profiler can, briefly) must not change the bytes."""
    import h5py

    import acousim.dataset.generation as g

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = g.write_shard(load_spec(spec), 0, tmp_path / "a")
    held = []
    create, group = h5py.Group.create_dataset, g._group

    def holding_create(self, *args, **kw):
        held.append(create(self, *args, **kw))
        return held[-1]

    def holding_group(parent, name):
        held.append(group(parent, name))
        return held[-1]

    monkeypatch.setattr(h5py.Group, "create_dataset", holding_create)
    monkeypatch.setattr(g, "_group", holding_group)
    b = g.write_shard(load_spec(spec), 0, tmp_path / "b")
    assert len(held) > 10 and a["sha256"] == b["sha256"]


def test_dask_local_cluster(spec, tmp_path):
    from dask.distributed import LocalCluster

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        generate(spec, tmp_path / "dask", scheduler=cluster.scheduler_address)
    generate(spec, tmp_path / "local", workers=1)
    assert shard_hashes(tmp_path / "dask") == shard_hashes(tmp_path / "local")
    a, b = DatasetReader(tmp_path / "dask", verify=True), DatasetReader(tmp_path / "local")
    assert len(a) == len(b) == 6
    for i in range(6):
        sa, sb = a[i], b[i]
        assert sa["params"] == sb["params"] and sorted(sa) == sorted(sb)
        for k in sa:
            if k != "params":
                np.testing.assert_array_equal(sa[k], sb[k])


WALL = "[[scenes]]\nfile = '{scenes}/wall.toml'\n"
RANDOM = WALL + "poses = 'random'\nregion = "


@pytest.mark.parametrize(
    "text,pattern",
    [
        (
            "[dataset]\nsamples = 0\n[[scenes]]\nfile = '{scenes}/wall.toml'\n",
            r"dataset.samples = 0: outside the allowed range",
        ),
        ("[datset]\n", r"datset: unknown key 'datset'; did you mean 'dataset'"),
        ("[dataset]\n", r"needs at least one \[\[scenes\]\]"),
        ("[[scenes]]\nfile = 'nope.toml'\n", "scene file not found"),
        (WALL + "[store]\nimages = ['bogus']\n", "store.images = .*'bogus' is not one of"),
        (
            WALL + "[randomize]\nsnr_db = {{dist='cauchy'}}\n",
            r"randomize.snr_db.dist = 'cauchy': is not one of",
        ),
        # issue 17: each names the key and the value
        (WALL + "[store]\nraw = 'no'\n", r"store.raw = 'no': must be true or false"),
        (WALL + "[randomize]\nhumidity_percent = 500\n", r"randomize.humidity_percent = 500"),
        (
            WALL + "[randomize]\nhumidity_percent = {{range = [20, 500]}}\n",
            r"randomize.humidity_percent.range",
        ),
        (WALL + "[randomize]\nsnr_db = nan\n", r"randomize.snr_db = nan: .*not NaN"),
        (RANDOM + "{{x = [1.0], y = [0, 1], z = [0, 1]}}\n", r"region.x = \[1.0\]: must be"),
        (RANDOM + "{{x = [0, 1], y = [0, 1]}}\n", r"scenes\[0\].region.z: missing"),
        (RANDOM + "5\n", r"scenes\[0\].region = 5: must be a table"),
        (
            RANDOM + "{{x = [0, 1], y = [0, 1], z = [0, 1], yaw_deg = 'left'}}\n",
            r"region.yaw_deg = 'left': must be",
        ),
        ("dataset = 5\n[[scenes]]\nfile = '{scenes}/wall.toml'\n", r"dataset = 5: must be a table"),
        (WALL + "[store]\nstep_deg = 'a'\n", r"store.step_deg = 'a': must be a number"),
        (WALL + "[store]\nazimuth_deg = [10, -10]\n", r"store.azimuth_deg = .*low is above high"),
        ("scenes = [5]\n", r"scenes\[0\] = 5: must be a table"),
        ("[[scenes]]\nfile = 'broken.toml'\n", r"scenes\[0\].file: not a usable scene .*rays"),
    ],
)
def test_malformed_specs(tmp_path, text, pattern):
    p = tmp_path / "bad.toml"
    p.write_text(text.format(scenes=SCENES))
    (tmp_path / "broken.toml").write_text("[simulation]\nrays = -1\n")
    with pytest.raises(SpecError, match=pattern):
        load_spec(p)


def test_dataset_command(spec, tmp_path, capsys):
    from acousim.cli import main

    assert main(["dataset", str(spec), "--out", str(tmp_path / "d"), "--workers", "1"]) == 0
    assert "6 samples in 3 shards" in capsys.readouterr().out
    shutil.copy(spec, tmp_path / "other.toml")
    (tmp_path / "other.toml").write_text(spec.read_text().replace("seed = 3", "seed = 4"))
    assert main(["dataset", str(tmp_path / "other.toml"), "--out", str(tmp_path / "d")]) == 2
    assert "another spec" in capsys.readouterr().err
