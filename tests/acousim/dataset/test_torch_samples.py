"""Datasets a training loop takes as they are: one image grid for every sample whatever
its air, the floor (never NaN) at gated bins, and batches of the stock PyTorch
DataLoader that hold the numbers of the files."""

import json
import math
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

import processing as P
from acousim.dataset import DatasetReader, SpecError, TorchSamples, generate, load_spec
from tests.acousim.dataset.test_chirp_shards import SCENE as CHIRP_SCENE
from tests.acousim.dataset.test_chirp_shards import SPEC as CHIRP_SPEC
from tests.acousim.dataset.wall import wall_spec
from tests.oracles.analytic import echo_recording

WALL = """
[sensor]
array = "urtis_v1"
direct_path = false
[simulation]
max_range_m = 3.0
rays = 1000
bounces = 1
[[meshes]]
file = "{mesh}"
"""

# a wide spread of air: 0 to 40 degC is 331 to 355 m/s, so a range axis that followed
# the speed of sound would differ by 7 % (14 cm at 2 m) from sample to sample
SPEC = """
[dataset]
samples = 8
shard_size = 4
seed = 11

[[scenes]]
file = "wall.toml"

[randomize]
temperature_c = { dist = "uniform", range = [0.0, 40.0] }
mount_jitter_deg = { dist = "normal", sigma = 3.0 }

[store]
images = ["das"]
step_deg = 6.0
elevation_deg = [-24.0, 24.0]
azimuth_deg = [-60.0, 60.0]
range_step_m = 0.01
floor_db = -50.0
max_peaks = 5
"""


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    d = tmp_path_factory.mktemp("torchds")
    generate(wall_spec(d, WALL, SPEC), d / "out")
    return d / "out"


def _groups(folder):
    """Every sample's group read with h5py alone: (shard file, group name) by index."""
    sides = sorted(folder.glob("shard_*.json"))
    table = [s for side in sides for s in json.loads(side.read_text())["samples"]]
    return {
        s["index"]: (folder / f"shard_{s['shard']:05d}.h5", f"{s['offset']:05d}") for s in table
    }


def _expected_axes():
    """The grid written out from the spec's numbers and the scene's: 0.25 m (the
    default min_range_m) to the scene's max_range_m in 1 cm steps; -24..24 and
    -60..60 degrees in 6 degree steps."""
    max_range = tomllib.loads(WALL)["simulation"]["max_range_m"]
    n = math.floor((max_range - 0.25) / 0.01 + 1e-9) + 1
    return 0.25 + 0.01 * np.arange(n), np.arange(-24, 25, 6.0), np.arange(-60, 61, 6.0)


@pytest.mark.parametrize("c", [331.0, 355.0])
def test_range_bins_on_a_given_axis_put_an_echo_at_its_range_in_any_air(c):
    """Exact echoes (conftest, written independently of the simulator) of a point 1.5
    m ahead, in cold and hot air: on a range axis of 5 mm steps the strongest bin is
    the one at 1.5 m (within the echo's energy centre: the paper call's matched
    filter is symmetric), its range reported as the axis value; one STFT hop per bin
    (the paper's default) would put its bins c * 16 / fs / 2 apart, following c."""
    rec = echo_recording(P.ura(4, 4, 0.0055), [(0, 0, 1.5, 1.0)], fs=450e3, c=c, n_samples=8192)
    axis = 0.5 + 0.005 * np.arange(401)  # 0.5 .. 2.5 m
    s = P.ProcessingSettings(energy_fraction=0.0, range_limits_m=(0.5, 2.5), range_step_m=0.005)
    snap = P.recording_snapshot(rec, s)
    np.testing.assert_allclose(snap.range_m, axis, atol=1e-12)
    assert snap.bin_range_m == pytest.approx(0.005)
    assert abs(snap.range_m[np.argmax(snap.energy)] - 1.5) <= 0.005
    default = P.recording_snapshot(rec, P.ProcessingSettings(energy_fraction=0.0))
    assert default.bin_range_m == pytest.approx(c * 16 / 450e3 / 2)


@pytest.mark.parametrize(
    ("store", "pattern"),
    [
        ("max_range_m = 0.1", r"store.max_range_m = 0.1: below min_range_m = 0.25"),
        ("range_step_m = 0", r"store.range_step_m = 0: outside the allowed range"),
        ("floor_db = 3.0", r"store.floor_db = 3.0: outside the allowed range"),
        ("max_peaks = -1", r"store.max_peaks = -1: outside the allowed range"),
    ],
)
def test_a_bad_grid_is_refused_naming_file_key_and_value(tmp_path, store, pattern):
    wall_spec(tmp_path, WALL)
    (tmp_path / "bad.toml").write_text(f"[[scenes]]\nfile = 'wall.toml'\n[store]\n{store}\n")
    with pytest.raises(SpecError, match=pattern) as err:
        load_spec(tmp_path / "bad.toml")
    assert "bad.toml" in str(err.value)


@pytest.mark.parametrize("seed", range(6))
def test_stored_peaks_are_the_whole_images_peaks(seed):
    """The peaks a sample stores (searched near the strong range bins only) are those
    processing.find_peaks finds on the whole image on the whole range axis, gated
    bins at power 0: sparse random images with plateaus, random thresholds."""
    from acousim.dataset.generation import _image_arrays
    from acousim.dataset.spec import StoreOptions

    rng = np.random.default_rng(seed)
    axis = 0.25 + 0.01 * np.arange(300)
    index = np.sort(rng.choice(300, 60, replace=False))
    kept = rng.random((60, 9, 21)) ** rng.uniform(4, 30)
    kept[:3] = kept.max()  # plateaus
    el, az = np.linspace(-0.5, 0.5, 9), np.linspace(-1, 1, 21)
    st = StoreOptions(peak_threshold_db=float(rng.uniform(-40, -3)), max_peaks=50)
    got = _image_arrays("das", P.Image(kept, axis[index], el, az, "das", 4e4), axis, index, st)
    whole = np.zeros((300, 9, 21))
    whole[index] = kept
    ref = P.find_peaks(P.Image(whole, axis, el, az, "das", 4e4), st.peak_threshold_db, max_peaks=50)
    cells = got["peaks/das/index"]
    assert len(cells) == len(ref) > 0
    np.testing.assert_array_equal(axis[cells[:, 0]], ref.range_m)
    np.testing.assert_array_equal(el[cells[:, 1]], ref.elevation_rad)
    np.testing.assert_array_equal(az[cells[:, 2]], ref.azimuth_rad)
    np.testing.assert_allclose(got["peaks/das/level_db"], ref.level_db, rtol=1e-6)
    db = got["image/das"]
    assert db.dtype == np.float16 and np.all(np.delete(db, index, axis=0) == -60.0)


class _Chirp:
    """A CHIRP dataset of one sample, as TorchSamples reads it (a DatasetReader's
    interface), with five paths."""

    folder, manifest = Path("."), {"shard_format": "chirp"}

    def __len__(self):
        return 1

    def __getitem__(self, i):
        pose = {"position_m": [1.0, 2.0, 3.0], "yaw_deg": 90.0, "pitch_deg": 0, "roll_deg": 0}
        return {
            "params": {"index": 0, "pose": pose, "speed_of_sound_m_s": 343.0},
            "raw": np.zeros((2, 8), np.float32),
            "labels/amplitude": np.array([0.1, 0.5, 0.2, 0.9, 0.3], np.float32),
            "labels/order": np.arange(5, dtype=np.int8),
            "labels/position_sensor_m": np.arange(15, dtype=np.float32).reshape(5, 3),
        }


def test_more_paths_than_max_paths_keep_the_strongest_in_order():
    s = TorchSamples(_Chirp(), max_paths=3)[0]
    assert s["n_paths"] == 3
    np.testing.assert_array_equal(s["paths"]["order"], [1, 3, 4])  # amplitudes .5 .9 .3
    np.testing.assert_array_equal(s["paths"]["amplitude"], np.float32([0.5, 0.9, 0.3]))
    np.testing.assert_array_equal(s["paths"]["position_sensor_m"][1], [9, 10, 11])
    np.testing.assert_allclose(s["pose"], [1, 2, 3, np.pi / 2, 0, 0], rtol=1e-6)
    padded = TorchSamples(_Chirp(), max_paths=7)[0]
    assert padded["n_paths"] == 5
    np.testing.assert_array_equal(padded["paths"]["order"], [0, 1, 2, 3, 4, -1, -1])


def test_every_sample_has_one_grid_the_floor_and_no_nan(dataset):
    ranges, elevations, azimuths = _expected_axes()
    shape = (ranges.size, elevations.size, azimuths.size)
    speeds = []
    for shard, name in _groups(dataset).values():
        with h5py.File(shard, "r") as f:
            g = f[name]
            params = json.loads(g.attrs["params"])
            speeds.append(params["speed_of_sound_m_s"])
            img = g["image/das"][()]
            kept = g["range_index"][()]
            np.testing.assert_allclose(g["range_m"][()], ranges, rtol=0, atol=1e-12)
            np.testing.assert_allclose(f["axes/range_m"][()], ranges, rtol=0, atol=1e-12)
            np.testing.assert_allclose(f["axes/elevation_deg"][()], elevations, atol=1e-9)
            np.testing.assert_allclose(f["axes/azimuth_deg"][()], azimuths, atol=1e-9)
            assert img.shape == shape
            assert not np.isnan(img).any()
            gated = np.setdiff1d(np.arange(ranges.size), kept)
            assert gated.size > 0 and kept.size > 0
            assert np.all(img[gated] == np.float16(-50.0))  # the spec's floor, exactly
            assert img.min() == np.float16(-50.0) and img.max() == 0
            assert g["image/das"].attrs["floor_db"] == -50.0
    # the samples drew airs far apart: a grid following c would differ between them
    assert max(speeds) - min(speeds) > 8.0


def test_the_wall_echo_sits_at_its_range_in_every_air(dataset):
    """The strongest peak of each image is at the wall's distance, 2 m (the mesh's
    plane x = 2, the sensor at the origin: tilting it keeps the perpendicular), in a
    hot or a cold sample alike."""
    ds = DatasetReader(dataset)
    errors = []
    for s in ds:
        (cell,) = s["peaks/das/index"][:1]
        errors.append(ds.range_m[cell[0]] - 2.0)
    # one range bin (1 cm) around the truth, in every air: a grid following the air
    # would be off by up to 7 % of 2 m
    assert np.ptp(errors) <= 0.02 + 1e-9
    assert np.abs(errors).max() <= 0.03


def test_the_stock_dataloader_batches_eight_samples_of_the_files_numbers(dataset):
    ds = DatasetReader(dataset)
    ranges, elevations, azimuths = _expected_axes()
    R, E, A = ranges.size, elevations.size, azimuths.size
    batch = next(iter(DataLoader(ds.torch(method="das", mask=True), batch_size=8)))
    assert batch["image"].shape == (8, 2, R, E, A) and batch["image"].dtype == torch.float32
    assert batch["kept"].shape == (8, R) and batch["kept"].dtype == torch.bool
    assert batch["peaks"].shape == (8, 5, 4) and batch["peaks"].dtype == torch.float32
    assert batch["peak_index"].shape == (8, 5, 3) and batch["peak_index"].dtype == torch.int64
    assert batch["n_peaks"].shape == (8,) and batch["n_peaks"].dtype == torch.int64
    assert batch["pose"].shape == (8, 6) and batch["pose"].dtype == torch.float32
    assert batch["depth_m"].shape == (8, E, A)
    assert batch["paths"]["position_sensor_m"].shape == (8, 256, 3)
    assert batch["paths"]["order"].dtype == torch.int64
    # the truth's label maps (acousim.imaging.labels), one per image, of its shape
    assert batch["labels"]["object"].shape == (8, R, E, A)
    assert batch["labels"]["order"].dtype == torch.int64
    assert not torch.isnan(batch["image"]).any()
    groups = _groups(dataset)
    for b in range(8):
        shard, name = groups[int(batch["index"][b])]
        with h5py.File(shard, "r") as f:
            g = f[name]
            img = g["image/das"][()].astype(np.float32)
            kept = np.zeros(R, bool)
            kept[g["range_index"][()]] = True
            cells = g["peaks/das/index"][()]
            level = g["peaks/das/level_db"][()]
            pose = json.loads(g.attrs["params"])["pose"]
            positions = g["labels/position_sensor_m"][()]
        np.testing.assert_array_equal(batch["image"][b, 0].numpy(), img)
        np.testing.assert_array_equal(
            batch["image"][b, 1].numpy(),
            np.broadcast_to(kept[:, None, None], (R, E, A)).astype(np.float32),
        )
        assert np.all(img[~kept] == -50.0)
        np.testing.assert_array_equal(batch["kept"][b].numpy(), kept)
        n = len(cells)
        assert int(batch["n_peaks"][b]) == n and 1 <= n <= 5
        np.testing.assert_array_equal(batch["peak_index"][b, :n].numpy(), cells)
        assert np.all(batch["peak_index"][b, n:].numpy() == -1)
        peaks = batch["peaks"][b].numpy()
        np.testing.assert_allclose(peaks[:n, 0], ranges[cells[:, 0]], rtol=1e-6)
        np.testing.assert_allclose(peaks[:n, 1], np.deg2rad(elevations[cells[:, 1]]), atol=1e-6)
        np.testing.assert_allclose(peaks[:n, 2], np.deg2rad(azimuths[cells[:, 2]]), atol=1e-6)
        np.testing.assert_array_equal(peaks[:n, 3], level)
        # the peaks' levels: each is the image's value at its cell
        np.testing.assert_allclose(level, img[tuple(cells.T)], atol=0.05)
        assert np.all(peaks[n:] == 0)
        expected = [
            *pose["position_m"],
            *np.deg2rad([pose[k] for k in ("yaw_deg", "pitch_deg", "roll_deg")]),
        ]
        np.testing.assert_allclose(batch["pose"][b].numpy(), expected, rtol=1e-6, atol=1e-6)
        k = int(batch["n_paths"][b])
        assert k == len(positions)
        np.testing.assert_array_equal(batch["paths"]["position_sensor_m"][b, :k].numpy(), positions)


def test_a_label_map_beside_the_image_is_batched_as_labels(dataset, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    rng = np.random.default_rng(0)
    written = {}
    for index, (shard, name) in _groups(copy).items():
        with h5py.File(shard, "r+") as f:
            shape = f[name]["image/das"].shape
            obj = rng.integers(-1, 3, shape).astype(np.int16)
            order = rng.integers(-1, 4, shape).astype(np.int8)
            for key, data in (("label_map/das/object", obj), ("label_map/das/order", order)):
                if key in f[name]:  # the simulation's own label maps: replaced by these
                    del f[name][key]
                f[name].create_dataset(key, data=data)
            written[index] = obj, order
    ds = DatasetReader(copy, verify=False)  # the shards' bytes changed
    batch = next(iter(DataLoader(ds.torch(), batch_size=8)))
    assert batch["labels"]["object"].dtype == torch.int64
    assert batch["labels"]["order"].shape == (8, *batch["image"].shape[2:])
    for b in range(8):
        obj, order = written[int(batch["index"][b])]
        np.testing.assert_array_equal(batch["labels"]["object"][b].numpy(), obj)
        np.testing.assert_array_equal(batch["labels"]["order"][b].numpy(), order)


def test_chirp_shards_batch_too(tmp_path):
    generate(wall_spec(tmp_path, CHIRP_SCENE, CHIRP_SPEC), tmp_path / "d")
    ds = DatasetReader(tmp_path / "d")
    batch = next(iter(DataLoader(ds.torch(max_paths=4, max_points=5000), batch_size=3)))
    raws = [ds[i]["raw"] for i in range(3)]
    assert batch["raw"].shape == (3, *raws[0].shape) and batch["raw"].dtype == torch.float32
    for b in range(3):
        i = int(batch["index"][b])
        np.testing.assert_array_equal(batch["raw"][b].numpy(), raws[i])
        s = ds[i]
        n = int(batch["n_paths"][b])
        assert n == len(s["labels/order"]) == 1
        np.testing.assert_array_equal(
            batch["paths"]["position_sensor_m"][b, :n].numpy(), s["labels/position_sensor_m"]
        )
        assert np.all(batch["paths"]["order"][b, n:].numpy() == -1)
        m = int(batch["n_lidar_points"][b])
        assert m == len(s["lidar/points_m"]) > 0
        np.testing.assert_array_equal(batch["lidar_points_m"][b, :m].numpy(), s["lidar/points_m"])
    assert batch["lidar_points_m"].shape == (3, 5000, 3)
