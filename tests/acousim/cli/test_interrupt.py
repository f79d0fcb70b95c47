"""Ctrl-C at known points of `simulate`, `image`, `compare`, `record` and `dataset`:
the command exits 130 with one line (or 0 when it had finished), leaves no temporary
file, leaves an existing output untouched, and what it wrote loads; a dataset resumed
afterwards is complete.

The tests never wait on a clock: the command runs with ACOUSIM_PROGRESS_LINES=1 and
says on stderr when it has started and each step of its progress; the interrupt is
sent (to the whole process group, as a terminal does) right after a given line. A
sweep of the interrupt moment over whole runs, on a clock, is
``python -m benchmarks.interrupt_sweep`` (not part of the suite: minutes).
"""

from __future__ import annotations

import os
import selectors
import shutil
import signal
import subprocess
import sys
import weakref
from pathlib import Path

import pytest

import processing as P
from processing.base import interrupt
from processing.base.atomic import TEMP_PREFIX, atomic_path, committed_together, write_text
from tests import REPO

#: a dataset of four samples of a scene (also benchmarks/interrupt_sweep.py's)
SPEC = """[dataset]
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

ROOT = REPO
SCENES = ROOT / "scenes"
TIMEOUT_S = 300  # a generous bound on one command's run, only against a hang


def run_interrupted(
    args: list[str], cwd: Path, after: str | None, *, launcher: list[str] | None = None
) -> tuple[int, list[str]]:
    """Run the command line (by `launcher`, default ``python -m acousim.cli``); send
    Ctrl-C right after it prints the stderr line that ends with `after` (None: never).
    Returns the exit code and the stderr lines."""
    env = {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "OPENBLAS_NUM_THREADS": "1",
        "ACOUSIM_PROGRESS_LINES": "1",
    }
    proc = subprocess.Popen(
        [*(launcher or [sys.executable, "-m", "acousim.cli"]), *args],
        cwd=cwd,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    lines: list[str] = []
    try:
        if after is not None:
            _read_until(proc, lines, after)
            os.killpg(proc.pid, signal.SIGINT)
        _, rest = proc.communicate(timeout=TIMEOUT_S)
    except BaseException:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise
    lines += rest.decode(errors="replace").splitlines()
    text = "\n".join(lines)
    assert "Traceback" not in text and "Exception ignored" not in text, text[-3000:]
    assert proc.returncode in (0, 130), text[-3000:]
    if proc.returncode == 130:  # exactly one line besides the progress lines
        said = [ln for ln in lines if not _is_progress(ln)]
        assert len(said) == 1 and said[0].startswith(f"acousim {args[0]}: interrupted"), said
    return proc.returncode, lines


def _is_progress(line: str) -> bool:
    tail = line.rsplit(" ", 1)[-1]
    return line.endswith((": started", "acousim: loading")) or (
        tail.count("/") == 1 and tail.replace("/", "").isdigit()
    )


def _read_until(proc: subprocess.Popen, lines: list[str], after: str) -> None:
    """Read stderr lines until one ends with `after`; fail if the command ends first."""
    sel = selectors.DefaultSelector()
    sel.register(proc.stderr, selectors.EVENT_READ)
    buf = b""
    while True:
        if not sel.select(timeout=TIMEOUT_S):
            pytest.fail(f"no {after!r} line within {TIMEOUT_S} s: {lines[-5:]}")
        chunk = os.read(proc.stderr.fileno(), 4096)
        if not chunk:
            pytest.fail(f"the command ended before {after!r}: {lines[-5:]}")
        buf += chunk
        *done, buf = buf.split(b"\n")
        for raw in done:
            lines.append(raw.decode(errors="replace"))
            if lines[-1].endswith(after):
                if buf:
                    lines.append(buf.decode(errors="replace"))  # a partial line, kept
                return


def earlier_recordings(path: Path) -> None:
    """A recording file of ours at `path` (as an earlier run leaves: replaceable)."""
    import numpy as np

    P.save_recordings(path, [P.Recording(np.zeros((30, 64)), 450e3, P.urtis_v1(), P.paper_chirp())])


def earlier_image_files(out: Path) -> None:
    """images.h5, peaks.csv, fan.png and drive.gif in `out` as an earlier run of
    `acousim image` leaves them, as far as their content says who wrote them (their
    format and header; replaceable), each with bytes of its own."""
    import h5py

    with h5py.File(out / "images.h5", "w") as f:
        f.attrs["format"] = "acousim-images"
    (out / "peaks.csv").write_text(",".join(P.PEAK_COLUMNS) + "\n")
    (out / "fan.png").write_bytes(b"\x89PNG\r\n\x1a\n an earlier fan.png")
    (out / "drive.gif").write_bytes(b"GIF89a an earlier drive.gif")


def leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.name.startswith(TEMP_PREFIX)]


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def corridor(tmp_path_factory) -> Path:
    """A folder with the corridor scene and two of its recordings (rec.h5)."""
    folder = tmp_path_factory.mktemp("corridor")
    for name in ("corridor.toml", "corridor_drive.csv"):
        shutil.copy(SCENES / name, folder / name)
    shutil.copytree(SCENES / "meshes", folder / "meshes")
    code, _ = run_interrupted(
        ["simulate", "corridor.toml", "--poses", "0:2", "--out", "rec.h5"], folder, None
    )
    assert code == 0
    return folder


CONSOLE_SCRIPT = Path(sys.executable).with_name("acousim")  # pip's `acousim`, if installed


@pytest.mark.parametrize(
    "launcher",
    [
        [sys.executable, "-m", "acousim.cli"],
        pytest.param(
            [str(CONSOLE_SCRIPT)],
            marks=pytest.mark.skipif(not CONSOLE_SCRIPT.is_file(), reason="not installed"),
        ),
    ],
    ids=["python -m acousim.cli", "acousim"],
)
def test_an_interrupt_while_the_command_imports_is_quiet(tmp_path, launcher):
    """Ctrl-C as soon as the command's first line of code has run (its handler
    installed, then "acousim: loading"), while it imports its package, builds its
    parser and loads the scene: exit 130 with the one line, no traceback (checked by
    run_interrupted), nothing written."""
    args = ["simulate", "wall", "--out", "x.h5"]
    code, lines = run_interrupted(args, tmp_path, "acousim: loading", launcher=launcher)
    assert code == 130 and lines[0] == "acousim: loading"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("after", ["started", "simulate 1/3", "simulate 3/3"])
def test_interrupted_simulate_keeps_the_old_output(corridor, tmp_path, after):
    for p in corridor.iterdir():
        (shutil.copytree if p.is_dir() else shutil.copy)(p, tmp_path / p.name)
    old = (tmp_path / "rec.h5").read_bytes()  # an earlier run's output, to be kept
    args = ["simulate", "corridor.toml", "--poses", "2:5", "--out", "rec.h5"]
    code, _ = run_interrupted(args, tmp_path, after)
    assert leftovers(tmp_path) == []
    if code == 130:
        assert (tmp_path / "rec.h5").read_bytes() == old
    else:  # the interrupt came after the file was complete (the last moment only)
        assert after == "simulate 3/3"
        assert [r.metadata["pose_index"] for r in P.load_recordings(tmp_path / "rec.h5")] == [
            2,
            3,
            4,
        ]
    if after != "simulate 3/3":
        assert code == 130


def test_interrupted_simulate_removes_the_folders_it_made(corridor, tmp_path):
    """`--out new/sub/x.h5` makes new/sub (as mkdir -p); Ctrl-C after the first pose:
    nothing was kept, so neither are the two empty folders it made."""
    for p in corridor.iterdir():
        (shutil.copytree if p.is_dir() else shutil.copy)(p, tmp_path / p.name)
    args = ["simulate", "corridor.toml", "--poses", "2:5", "--out", "new/sub/x.h5"]
    code, _ = run_interrupted(args, tmp_path, "simulate 1/3")
    assert code == 130
    assert not (tmp_path / "new").exists() and leftovers(tmp_path) == []


def test_interrupted_rig_simulate_stops_its_threads_and_keeps_the_old_output(tmp_path):
    # a rig's run prepares the next firings in threads while one renders: Ctrl-C
    # after the first firing ends the command with one line, no file replaced
    earlier_recordings(tmp_path / "rig.h5")  # an earlier run's: ours, replaceable
    old = (tmp_path / "rig.h5").read_bytes()
    args = ["simulate", "corridor_rig", "--poses", "40:46", "--out", "rig.h5"]
    code, lines = run_interrupted(args, tmp_path, "simulate 1/6")
    assert code == 130
    assert (tmp_path / "rig.h5").read_bytes() == old
    assert leftovers(tmp_path) == []
    assert not any(ln.endswith("simulate 6/6") for ln in lines)


@pytest.mark.parametrize("after", ["started", "image 1/2", "pictures 1/3"])
def test_interrupted_image_keeps_the_old_pictures(corridor, tmp_path, after):
    shutil.copy(corridor / "rec.h5", tmp_path / "rec.h5")
    out = tmp_path / "out"
    out.mkdir()
    earlier_image_files(out)
    before = snapshot(out)
    args = ["image", "rec.h5", "--out", "out", "--method", "das", "--no-3d"]
    code, _ = run_interrupted(args, tmp_path, after)
    assert code == 130
    assert snapshot(out) == before  # no file replaced, none added
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("after", ["started", "compare 1/2"])
def test_interrupted_compare_writes_nothing(corridor, tmp_path, after):
    shutil.copy(corridor / "rec.h5", tmp_path / "rec.h5")
    args = ["compare", "rec.h5", "--sim", "rec.h5", "--all", "--out", "cmp"]
    code, _ = run_interrupted(args, tmp_path, after)
    assert code == 130
    assert not (tmp_path / "cmp").exists() or list((tmp_path / "cmp").rglob("*.*")) == []
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("after", ["started", "record 2/40"])
def test_interrupted_record_keeps_what_it_measured(tmp_path, after):
    """The first Ctrl-C stops the acquisition and keeps every complete measurement
    (the command's documented behaviour)."""
    args = ["record", "--emulate", str(SCENES / "wall.toml"), "--count", "40", "--rate", "4"]
    code, lines = run_interrupted([*args, "--out", "rec.h5"], tmp_path, after)
    assert code == 130
    assert leftovers(tmp_path) == []
    if after == "started":
        assert not (tmp_path / "rec.h5").exists()
    else:
        n = len(P.load_recordings(tmp_path / "rec.h5"))
        assert 2 <= n < 40


@pytest.mark.parametrize("after", ["started", "shards 1/4"])
def test_interrupted_dataset_then_resumed(tmp_path, after):
    """Workers ignore Ctrl-C (no traceback of theirs, no broken pool); the shards
    written are whole; the one line says how many were kept and the command that
    resumes; that command completes the dataset."""
    import h5py

    from acousim.dataset import DatasetReader

    (tmp_path / "spec.toml").write_text(SPEC.format(scene=SCENES / "points.toml"))
    args = ["dataset", "spec.toml", "--out", "data", "--workers", "2"]
    code, lines = run_interrupted(args, tmp_path, after)
    assert code == 130
    assert leftovers(tmp_path) == []
    kept = sum((tmp_path / "data" / f"shard_{k:05d}.json").is_file() for k in range(4))
    said = next(ln for ln in lines if ln.startswith("acousim dataset: interrupted"))
    assert said == (
        f"acousim dataset: interrupted; {kept} of 4 shards kept in data (each whole; "
        "checked again on resume); resume with: acousim dataset spec.toml --out data "
        "--workers 2"
    )
    for shard in (tmp_path / "data").glob("shard_*.h5"):  # every shard present is whole
        with h5py.File(shard, "r") as f:
            assert [k for k in f if k.isdigit()] == ["00000"]  # its one sample
    assert run_interrupted(args, tmp_path, None)[0] == 0  # resumed to the end
    assert leftovers(tmp_path) == []
    ds = DatasetReader(tmp_path / "data", verify=True)
    assert len(ds) == 4 and ds[3]["image/das"].size > 0


# --- the flag itself, in this process ------------------------------------------------


def test_an_interrupt_in_a_weakref_callback_is_not_lost():
    """The case that lost a Ctrl-C: it landed while the garbage collector ran a weak
    reference's callback, where a raised exception is printed and dropped. The handler
    only sets the flag, which the next checkpoint honours."""

    class Thing:
        pass

    def callback(_ref):
        os.kill(os.getpid(), signal.SIGINT)  # delivered during the callback

    with interrupt.installed():
        thing = Thing()
        ref = weakref.ref(thing, callback)
        del thing  # the callback runs here
        assert ref() is None
        assert interrupt.requested()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()
    interrupt.reset()


def test_a_requested_interrupt_never_replaces_an_existing_file(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with interrupt.installed():
        os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(KeyboardInterrupt):
            write_text(target, "new")
    interrupt.reset()
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_files_committed_together_all_or_none(tmp_path):
    (tmp_path / "a.txt").write_text("old a")
    with pytest.raises(KeyboardInterrupt), committed_together():
        write_text(tmp_path / "a.txt", "new a")
        write_text(tmp_path / "b.txt", "new b")
        assert (tmp_path / "a.txt").read_text() == "old a"  # not yet renamed
        raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    assert (tmp_path / "a.txt").read_text() == "old a"
    with committed_together():
        write_text(tmp_path / "a.txt", "new a")
        with atomic_path(tmp_path / "b.txt") as tmp:
            tmp.write_text("new b")
    assert (tmp_path / "a.txt").read_text() == "new a"
    assert (tmp_path / "b.txt").read_text() == "new b"
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize(
    "argv,orig,ours",
    [
        (["/venv/bin/acousim", "simulate"], ["/venv/bin/python", "/venv/bin/acousim"], True),
        (["-m", "simulate"], ["python", "-X", "importtime", "-m", "acousim.cli"], True),
        (["-m"], ["python", "-macousim.cli"], True),
        (["-m"], ["python", "-m", "pytest"], False),
        (["tool.py", "-m", "acousim.cli"], ["python", "tool.py", "-m", "acousim.cli"], False),
        (["-c"], ["python", "-c", "import acousim.cli", "-m", "acousim.cli"], False),
    ],
)
def test_the_handler_at_import_is_the_commands_alone(monkeypatch, argv, orig, ours):
    """acousim.cli installs its handler when imported only in the acousim command's
    process (a program importing it keeps its Ctrl-C)."""
    from acousim import cli

    monkeypatch.setattr(sys, "argv", argv)
    monkeypatch.setattr(sys, "orig_argv", orig)
    assert cli._is_the_command() is ours
