"""A reader of a dataset of many shards: a bounded set of open files, so a shuffled
epoch runs under a low limit of open files and in DataLoader worker processes."""

import hashlib
import json
import pickle
import subprocess
import sys

import numpy as np
import pytest

from acousim.dataset import DatasetReader, generate
from tests import REPO
from tests.acousim.dataset.wall import wall_spec

SCENE = """
[sensor]
array = "urtis_v1"
direct_path = false
[simulation]
max_range_m = 2.0
rays = 200
bounces = 1
[[meshes]]
file = "{mesh}"
"""

SPEC = """
[dataset]
samples = 24
shard_size = 1
seed = 11

[[scenes]]
file = "wall.toml"

[store]
images = ["das"]
step_deg = 15.0
max_bins = 16
depth_map = false
"""

# in a subprocess: open files limited to what it has now plus `margin`, read the
# samples in a shuffled order with at most `cap` shards open, print their digests
READ = """
import hashlib, json, os, resource, sys
import numpy as np
from acousim.dataset import DatasetReader
folder, cap, margin = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
r = DatasetReader(folder, open_shards=cap)
used = len(os.listdir("/proc/self/fd"))
resource.setrlimit(resource.RLIMIT_NOFILE, (used + margin, used + margin))
order = np.random.default_rng(1).permutation(len(r))
out = {}
for epoch in range(2):
    for i in order:
        s = r[int(i)]
        out[int(i)] = hashlib.sha256(
            b"".join(np.ascontiguousarray(s[k]).tobytes() for k in sorted(s) if k != "params")
        ).hexdigest()
print(json.dumps(out))
"""


def digest(s: dict) -> str:
    arrays = (np.ascontiguousarray(s[k]).tobytes() for k in sorted(s) if k != "params")
    return hashlib.sha256(b"".join(arrays)).hexdigest()


@pytest.fixture(scope="module")
def many(tmp_path_factory):
    folder = tmp_path_factory.mktemp("many")
    generate(wall_spec(folder, SCENE, SPEC), folder / "ds")
    return folder / "ds"


def _read(folder, cap, margin):
    return subprocess.run(
        [sys.executable, "-c", READ, str(folder), str(cap), str(margin)],
        capture_output=True,
        text=True,
        cwd=REPO,
    )


def test_a_shuffled_epoch_under_a_low_open_file_limit_reads_what_the_order_does(many):
    r = DatasetReader(many)
    assert len(r.manifest["shards"]) == 24
    in_order = {i: digest(s) for i, s in enumerate(r)}
    assert len(r._files) == r.open_shards == 16  # the default cap, never more
    r.close()
    done = _read(many, cap=4, margin=8)  # 24 shards, room for 8 more files
    assert done.returncode == 0, done.stderr
    assert {int(k): v for k, v in json.loads(done.stdout).items()} == in_order
    # the limit is real: 24 shards open at once do not fit in it
    failed = _read(many, cap=24, margin=8)
    assert failed.returncode != 0 and "Too many open files" in failed.stderr


def test_a_pickled_or_forked_reader_opens_its_own_files(many):
    import torch
    from torch.utils.data import DataLoader

    r = DatasetReader(many, open_shards=2)
    first = digest(r[0])
    copy = pickle.loads(pickle.dumps(r))  # a spawned worker's reader: no files
    assert not copy._files and digest(copy[0]) == first
    loader = DataLoader(r.torch(("image/das",)), batch_size=4, num_workers=2)
    batches = torch.cat([b[0] for b in loader]).numpy()
    expected = np.stack([np.asarray(r[i]["image/das"], np.float32) for i in range(len(r))])
    assert np.array_equal(batches, expected)
    assert len(r._files) <= 2


def test_open_shards_must_be_positive(many):
    with pytest.raises(ValueError, match="open_shards"):
        DatasetReader(many, open_shards=0)


def test_the_manifest_holds_no_sample_parameters_and_an_older_one_still_reads(many, tmp_path):
    """The samples' parameters live in the sidecars and shards; the manifest lists
    the shards. A manifest of an earlier acousim (its ``sample_table``) reads the
    same samples."""
    manifest = json.loads((many / "manifest.json").read_text())
    assert "sample_table" not in manifest
    sides = [json.loads(p.read_text()) for p in sorted(many.glob("shard_*.json"))]
    table = [s for side in sides for s in side["samples"]]
    r = DatasetReader(many)
    for s in table:  # the sidecar's record names the sample's shard and place in it
        assert r[s["index"]]["params"]["pose"] == s["pose"]
    old = tmp_path / "old"
    old.mkdir()
    for p in many.glob("shard_*.h5"):
        (old / p.name).symlink_to(p)
    shuffled = [table[i] for i in np.random.default_rng(0).permutation(len(table))]
    (old / "manifest.json").write_text(json.dumps({**manifest, "sample_table": shuffled}))
    o = DatasetReader(old)
    assert len(o) == len(r) and digest(o[-1]) == digest(r[-1]) and digest(o[5]) == digest(r[5])
    # shards whose counts do not make the samples: a clear error at open
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "manifest.json").write_text(json.dumps({**manifest, "samples": 25}))
    with pytest.raises(ValueError, match="malformed manifest.*not 25 in shards of 1"):
        DatasetReader(bad)
