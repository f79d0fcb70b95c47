"""Ctrl-C at several moments of `simulate` and `dataset`: the command stops (exit 130,
or 0 when it had finished), leaves no partial or temporary file, and what it wrote
loads; a dataset resumed afterwards is complete.

The interrupt is sent to the command's whole process group, as a terminal does. The
moments are delays after the start; on a loaded machine they fall at different
stages from run to run, and the assertions hold at any moment.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import processing as P
from processing.atomic import TEMP_PREFIX

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"
# -SIGINT: interrupted while Python was starting (on a loaded machine a Ctrl-C can also
# land in Python's site import, which exits 1 with "Fatal Python error:
# init_import_site": counted as the same)
FINISHED = (0, 130, -signal.SIGINT)


def run_and_interrupt(args: list[str], cwd: Path, delay_s: float | None) -> int:
    """Run the command line, send Ctrl-C after `delay_s` (None: never), wait."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "acousim.cli", *args],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    if delay_s is not None:
        time.sleep(delay_s)
        try:
            os.killpg(proc.pid, signal.SIGINT)
        except ProcessLookupError:
            pass  # already finished
    try:
        out, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # the interrupt was swallowed
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        pytest.fail(f"{args[0]} ignored Ctrl-C after {delay_s} s")
    if proc.returncode == 1 and b"init_import_site" in err and b"KeyboardInterrupt" in err:
        return -signal.SIGINT  # Python's own start-up interrupted (before any of our code)
    assert proc.returncode in FINISHED, err.decode()[-2000:]
    assert b"Traceback" not in err or proc.returncode == -signal.SIGINT, err.decode()[-2000:]
    return proc.returncode


def leftovers(folder: Path) -> list[Path]:
    return [
        p
        for p in folder.rglob("*")
        if p.name.startswith(TEMP_PREFIX) or p.name.endswith(".part") or ".part." in p.name
    ]


@pytest.mark.parametrize("delay_s", [0.5, 2.5, 5.0, 7.5])
def test_interrupted_simulate(tmp_path, delay_s):
    """Startup takes a few seconds (imports), 16 corridor poses a few more."""
    for name in ("corridor.toml", "corridor_drive.csv"):
        shutil.copy(SCENES / name, tmp_path / name)
    shutil.copytree(SCENES / "meshes", tmp_path / "meshes")
    args = ["simulate", "corridor.toml", "--poses", "0:16", "--out", "out.h5"]
    code = run_and_interrupt(args, tmp_path, delay_s)
    assert leftovers(tmp_path) == []
    # an interrupt that lands after the rename (exit 130 with the file written) is fine:
    # whatever file exists is whole
    if (tmp_path / "out.h5").exists():
        assert len(P.load_recordings(tmp_path / "out.h5")) == 16
    else:
        assert code != 0


SPEC = """
[dataset]
samples = 4
shard_size = 1
seed = 3

[[scenes]]
file = "{scene}"

[store]
images = ["das"]
step_deg = 10.0
depth_map = false
"""


@pytest.mark.parametrize("delay_s", [1.0, 5.0, 7.0])
def test_interrupted_dataset_then_resumed(tmp_path, delay_s):
    import h5py

    from acousim.dataset import DatasetReader

    (tmp_path / "spec.toml").write_text(SPEC.format(scene=SCENES / "points.toml"))
    args = ["dataset", "spec.toml", "--out", "data", "--workers", "2"]
    run_and_interrupt(args, tmp_path, delay_s)
    assert leftovers(tmp_path) == []
    for shard in (tmp_path / "data").glob("shard_*.h5"):  # every shard present is whole
        with h5py.File(shard, "r") as f:
            assert [k for k in f if k.isdigit()] == ["00000"]  # its one sample
    assert run_and_interrupt(args, tmp_path, None) == 0  # resumed to the end
    assert leftovers(tmp_path) == []
    ds = DatasetReader(tmp_path / "data", verify=True)
    assert len(ds) == 4 and ds[3]["image/das"].size > 0
