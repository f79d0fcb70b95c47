"""Dataset generation: deterministic across workers, resumable, Dask, reader, errors."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from acousim.dataset import DatasetReader, SpecError, generate, load_spec
from tests import REPO

SCENES = REPO / "scenes"

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


# ------------------------------------------------------------ file contents


def test_shard_metadata_axes_units_and_a_regular_range_axis(spec, tmp_path):
    import h5py

    generate(spec, tmp_path / "d", workers=1)
    r = DatasetReader(tmp_path / "d")
    np.testing.assert_allclose(r.azimuth_deg, np.arange(-90, 91, 6.0))
    np.testing.assert_allclose(r.elevation_deg, np.arange(-30, 31, 6.0))
    for i in range(len(r)):
        s = r[i]
        p = s["params"]
        # the spec's grid, in any air: 0.25 m (min_range_m) to the corridor's 6 m
        # (the scenes' largest max_range_m) every 6 mm (range_step_m's default)
        assert p["range_step_m"] == 0.006
        np.testing.assert_allclose(s["range_m"], 0.25 + 0.006 * np.arange(959), atol=1e-12)
        img, kept = s["image/das"], s["range_index"]
        assert img.shape == (959, 11, 31)
        assert np.isfinite(img).all()
        assert np.all(np.delete(img, kept, axis=0) == -60.0)  # the floor, never NaN
        assert s["snapshot"].shape[1] == kept.size
        # the truth image beside it: per cell an object of the sample and a path order
        obj, order = s["label_map/das/object"], s["label_map/das/order"]
        assert obj.shape == order.shape == img.shape and obj.dtype == np.int16
        assert (obj >= 0).any() and obj.max() < len(p["object_names"])
        assert np.all(order[obj >= 0] >= 0) and order.max() >= 1
        n = s["labels/order"].size
        assert s["labels/apparent_position_sensor_m"].shape == (n, 3)
        assert s["labels/delay_s"].shape == s["labels/object_index"].shape == (n,)
        assert 20e3 <= p["frequency_hz"] <= 80e3  # inside the call's band
        assert set(p["pose"]) >= {"position_m", "yaw_deg", "pitch_deg", "roll_deg"}
        scene = (spec.parent / p["scene"]).resolve()
        assert scene.parent == SCENES and ".." not in Path(p["scene"]).name
    with h5py.File(tmp_path / "d" / "shard_00000.h5") as f:
        assert f.attrs["schema"] == b"acousim.dataset.shard"
        g = f["00000"]
        assert g["range_m"].attrs["units"] == b"m" and g["image/das"].attrs["units"] == b"dB"
        assert g["labels/depth_m"].attrs["units"] == b"m"
        assert g["label_map/das/object"].attrs["units"] == b"1"
        assert g["labels/delay_s"].attrs["units"] == b"s"
        assert all(d.fletcher32 for d in _datasets(f) if d.size)
        assert f["arrays"][r[0]["params"]["array"]]["positions_m"].shape[1] == 3


def _datasets(f):
    import h5py

    found = []
    f.visititems(lambda k, o: found.append(o) if isinstance(o, h5py.Dataset) else None)
    return found


# ------------------------------------------------------------ robustness


def test_second_generator_on_a_folder_is_refused(spec, tmp_path):
    import fcntl
    import os

    from processing.base.errors import InputError

    out = tmp_path / "d"
    out.mkdir()
    fd = os.open(out / ".acousim-dataset.lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)  # as a running generator holds it
    try:
        with pytest.raises(InputError, match="another acousim dataset generator"):
            generate(spec, out, workers=1)
    finally:
        os.close(fd)
    assert not list(out.glob("shard_*"))


def _flip(path, offset):
    raw = bytearray(path.read_bytes())
    raw[offset] ^= 0xFF
    path.write_bytes(bytes(raw))


def _chunk_offset(path, dataset):
    import h5py

    with h5py.File(path) as f:
        return f[dataset].id.get_chunk_info(0).byte_offset


def test_resume_redoes_damaged_shards(spec, tmp_path, capsys):
    clean = tmp_path / "clean"
    generate(spec, clean, workers=1)
    d = tmp_path / "d"
    shutil.copytree(clean, d)
    _flip(d / "shard_00001.h5", _chunk_offset(d / "shard_00001.h5", "00000/range_m") + 3)
    (d / "shard_00002.h5").write_bytes(b"")  # truncated to nothing
    from acousim.cli import main

    assert main(["dataset", str(spec), "--out", str(d), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "4 computed now" in out
    assert "redone: 2 damaged shard(s)" in out and "shard_00001.h5, shard_00002.h5" in out
    manifest = json.loads((d / "manifest.json").read_text())
    assert manifest["damaged_shards"] == ["shard_00001.h5", "shard_00002.h5"]
    assert shard_hashes(d) == shard_hashes(clean)
    (d / "shard_00000.h5").write_bytes(b"")
    m = generate(spec, d, workers=1)
    assert m["summary"]["damaged_shards"] == [0]
    assert m["summary"]["samples_computed"] == 2
    assert shard_hashes(d) == shard_hashes(clean)


def test_reader_refuses_corruption_with_and_without_verify(spec, tmp_path):
    from acousim.dataset import DatasetError

    d = tmp_path / "d"
    generate(spec, d, workers=1)
    shard = d / "shard_00001.h5"
    _flip(shard, _chunk_offset(shard, "00000/range_m") + 3)
    r = DatasetReader(d)  # verify=True by default: sha256 on the shard's first opening
    r[0]
    with pytest.raises(DatasetError, match="shard_00001.h5: sha256 .* does not match"):
        r[2]
    r = DatasetReader(d, verify=False)  # fletcher32 still catches it
    with pytest.raises(DatasetError, match="shard_00001.h5: /00000/range_m: cannot be read"):
        r[2]


def test_manifest_names_stay_inside_the_folder(spec, tmp_path):
    import json as js

    from acousim.dataset import DatasetError

    d = tmp_path / "d"
    generate(spec, d, workers=1)
    m = js.loads((d / "manifest.json").read_text())
    m["shards"][0]["file"] = "../../../../etc/hostname"
    (d / "manifest.json").write_text(js.dumps(m))
    with pytest.raises(DatasetError, match=r"shards.file = '../../../../etc/hostname'"):
        DatasetReader(d)


def test_unreachable_scheduler_fails_at_once(spec, tmp_path):
    import socket

    from processing.base.errors import InputError

    with socket.socket() as s:  # a port nothing listens on once closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(InputError, match=rf"--scheduler = 'tcp://127.0.0.1:{port}': no Dask"):
        generate(spec, tmp_path / "d", scheduler=f"tcp://127.0.0.1:{port}")
    assert not (tmp_path / "d").exists()


def _children(pid):
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def _alive(pid):
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_killing_the_main_process_ends_its_workers(spec, tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import time

    from processing.base.errors import InputError

    big = tmp_path / "big.toml"
    big.write_text(spec.read_text().replace("samples = 6", "samples = 40"))
    code = (
        "from acousim.dataset import generate; import sys; "
        "generate(sys.argv[1], sys.argv[2], workers=2)"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    main = subprocess.Popen([sys.executable, "-c", code, str(big), str(tmp_path / "d")], env=env)
    try:
        deadline = time.monotonic() + 60
        while len(_children(main.pid)) < 2 and time.monotonic() < deadline:
            time.sleep(0.2)
        workers = _children(main.pid)
        assert len(workers) >= 2
        os.kill(main.pid, signal.SIGKILL)
        main.wait()
        deadline = time.monotonic() + 10
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_alive(w) for w in workers)
    finally:
        if main.poll() is None:
            main.kill()
        for w in _children(main.pid) + locals().get("workers", []):
            if _alive(w):
                os.kill(w, signal.SIGKILL)
    # and the interrupted folder resumes to a complete dataset (a worker forked just
    # before the kill may still be starting: it ends within its watch interval)
    deadline = time.monotonic() + 10
    while True:
        try:
            m = generate(big, tmp_path / "d", workers=1)
            break
        except InputError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)
    assert m["samples"] == 40


def test_info_on_a_shard_and_a_dataset_folder(spec, tmp_path, capsys):
    from acousim.cli import main

    d = tmp_path / "d"
    generate(spec, d, workers=1)
    assert main(["info", str(d / "shard_00000.h5")]) == 0
    out = capsys.readouterr().out
    assert "dataset shard, 2 sample(s)" in out and "image/das (" in out
    assert "azimuth -90..90° (31)" in out
    assert main(["info", str(d)]) == 0
    out = capsys.readouterr().out
    assert "dataset 'tiny', 6 sample(s) in 3 shard(s)" in out
    assert main(["info", str(tmp_path / "nothing")]) == 2
    capsys.readouterr()
    (d / "manifest.json").unlink()
    assert main(["info", str(d)]) == 2
    assert "no manifest.json (generation unfinished?)" in capsys.readouterr().err


def test_dataset_command_with_an_unreachable_scheduler(spec, tmp_path, capsys):
    import socket

    from acousim.cli import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "d"
    assert main(["dataset", str(spec), "--out", str(out), "--scheduler", f"127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--scheduler = '127.0.0.1:{port}'" in err, err
