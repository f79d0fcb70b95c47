"""Dataset shards written as CHIRP files (``[dataset] format = "chirp"``)."""

import hashlib

import h5py
import numpy as np
import pytest

import processing as P
from acousim.dataset import DatasetReader, generate, load_spec
from acousim.dataset.chirp_shards import capture_samples
from tests.acousim.dataset.wall import wall_spec

SCENE = """
[sensor]
array = "urtis_v1"
direct_path = false
[sensor.pose]
yaw_deg = 15.0
[sensor.lidar]
preset = "vlp16"
azimuth_step_deg = 2.0
[simulation]
max_range_m = 4.0
rays = 2000
bounces = 1
[[meshes]]
file = "{mesh}"
"""

SPEC = """
[dataset]
samples = 3
shard_size = 2
seed = 3
format = "chirp"
[[scenes]]
file = "wall.toml"
[randomize]
temperature_c = { dist = "uniform", range = [10.0, 30.0] }
"""


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory):
    d = tmp_path_factory.mktemp("spec")
    return wall_spec(d, SCENE, SPEC)


def test_chirp_shards(spec_path, tmp_path):
    generate(spec_path, tmp_path / "a")
    generate(spec_path, tmp_path / "b")
    for k in (0, 1):
        a, b = (tmp_path / x / f"shard_{k:05d}.h5" for x in "ab")
        assert hashlib.sha256(a.read_bytes()).digest() == hashlib.sha256(b.read_bytes()).digest()
        assert P.is_chirp(a)
    shard = tmp_path / "a" / "shard_00000.h5"
    n = capture_samples(load_spec(spec_path))
    with h5py.File(shard, "r") as f:
        assert f["sensors/acoustic_sensor_00/data/signals"].shape == (2, n, 30)
        assert f["sensors/lidar_00/data/points"].shape[0] == 2
    # every capture holds the wall's echo where its speed of sound puts it, and is
    # long enough for the scene's maximum range in its air
    recs = P.load_recordings(shard)
    for r in recs:
        c = r.speed_of_sound_m_s
        assert 337 < c < 350 and r.metadata["sample"]["speed_of_sound_m_s"] == c
        env = np.abs(r.samples).max(axis=0)
        first = np.flatnonzero(env > 0.1 * env.max())[0] / r.sample_rate_hz
        dist = (
            np.linalg.norm(r.truth.position_sensor_m[0] - r.array.emitter_m)
            + np.linalg.norm(r.truth.position_sensor_m[0] - r.array.positions_m, axis=1).min()
        )
        assert 0 <= first - dist / c < 1e-4  # the call's Hann ramp reaches 10 % in 65 us
        assert r.n_samples / r.sample_rate_hz >= 2 * 4.0 / c + 2.5e-3  # max_range covered
    sample = DatasetReader(tmp_path / "a")[2]
    assert sample["params"]["index"] == 2
    assert sample["raw"].shape == (30, n)
    assert sample["lidar/points_m"].shape[1] == 3 and len(sample["labels/order"]) == 1
