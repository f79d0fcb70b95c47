"""Ctrl-C swept over whole runs of `simulate`, `image`, `compare`, `record` and
`dataset` (issue 25): every moment from 0.05 s to the end of the run, in steps.

Not a speed benchmark and not part of the test suite (minutes; it waits on a clock,
which tests never do: tests/acousim/cli/test_interrupt.py interrupts at lines the command
prints). For each moment the command runs in a fresh folder holding an earlier
output, gets SIGINT (to its process group, as from a terminal) and must: exit 130
with exactly one line on stderr, or 0 having finished; print no traceback; leave no
temporary file; leave the earlier output byte-identical when it exits 130 (`record`
keeps what it measured, its documented behaviour: the file then loads).

    python -m benchmarks.interrupt_sweep [--step 0.25] [--commands simulate,image]
    python -m benchmarks.interrupt_sweep --step 0.05 --until 1 --commands simulate

Prints one line per command: runs, exits 130 / 0 / other, and the failures.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.acousim.cli.test_interrupt import SPEC  # a dataset of four samples of a scene

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"
PREFIX = ".acousim-tmp-"


COMMANDS = {
    "simulate": (["simulate", "corridor.toml", "--poses", "0:4", "--out", "rec.h5"], "rec.h5"),
    "image": (["image", "rec.h5", "--out", "out", "--method", "das", "--no-3d"], "out"),
    "compare": (["compare", "rec.h5", "--sim", "rec.h5", "--all", "--out", "cmp"], "cmp"),
    "record": (
        ["record", "--emulate", str(SCENES / "wall.toml"), "--count", "8", "--rate", "4"]
        + ["--out", "meas.h5"],
        "meas.h5",
    ),
    "dataset": (["dataset", "spec.toml", "--out", "data", "--workers", "2"], None),
}


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}


def _prepare(folder: Path, base: Path) -> None:
    for p in base.iterdir():
        (shutil.copytree if p.is_dir() else shutil.copy)(p, folder / p.name)


def _base(tmp: Path) -> Path:
    """A folder with the corridor scene, a recording of two poses (rec.h5), earlier
    outputs of every command (out/, cmp/, meas.h5) and a dataset spec."""
    base = tmp / "base"
    base.mkdir()
    for name in ("corridor.toml", "corridor_drive.csv"):
        shutil.copy(SCENES / name, base / name)
    shutil.copytree(SCENES / "meshes", base / "meshes")
    args = ["simulate", "corridor.toml", "--poses", "0:2", "--out", "rec.h5"]
    subprocess.run([sys.executable, "-m", "acousim.cli", *args], cwd=base, env=_env(), check=True)
    for folder in ("out", "cmp"):
        (base / folder).mkdir()
        (base / folder / "earlier.txt").write_text("an earlier output")
    (base / "out" / "fan.png").write_text("an earlier picture")
    (base / "meas.h5").write_text("an earlier measurement file")
    (base / "spec.toml").write_text(SPEC.format(scene=SCENES / "points.toml"))
    return base


def _snapshot(path: Path) -> dict:
    if path.is_file():
        return {"": path.read_bytes()}
    return {str(p): p.read_bytes() for p in path.rglob("*") if p.is_file()} if path.exists() else {}


def one(command: str, base: Path, work: Path, delay_s: float) -> tuple[int, str | None, bool]:
    """Run `command` with Ctrl-C after `delay_s`: its exit code, None if everything
    held (else why, or "python start-up"), and whether it had finished first."""
    args, output = COMMANDS[command]
    folder = Path(tempfile.mkdtemp(dir=work))
    _prepare(folder, base)
    before = _snapshot(folder / output) if output else None
    proc = subprocess.Popen(
        [sys.executable, "-m", "acousim.cli", *args],
        cwd=folder,
        env=_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    time.sleep(delay_s)
    finished_first = proc.poll() is not None
    try:
        os.killpg(proc.pid, signal.SIGINT)
    except ProcessLookupError:
        finished_first = True
    try:
        _, err = proc.communicate(timeout=600)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return 0, "ignored the interrupt", False
    text = err.decode(errors="replace")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    code = proc.returncode
    problems = []
    if code in (1, -signal.SIGINT) and _in_python_start(text):
        # Python's own start, before any of our code runs (its site imports, runpy):
        # killed by the signal, or "Fatal Python error"; nothing of ours to fix
        return code, "python start-up", finished_first
    if code not in (0, 130):
        problems.append(f"exit {code}")
    if "Traceback" in text or "Exception ignored" in text:
        problems.append("traceback")
    if code == 130 and len(lines) != 1:
        problems.append(f"{len(lines)} lines")
    if [p for p in folder.rglob("*") if p.name.startswith(PREFIX)]:
        problems.append("temporary file left")
    if code == 130 and output and command != "record" and _snapshot(folder / output) != before:
        problems.append("earlier output changed")
    shutil.rmtree(folder, ignore_errors=True)
    why = "; ".join(problems) + f" ({text[-300:]!r})" if problems else None
    return code, why, finished_first


def _in_python_start(stderr: str) -> bool:
    """Whether an interrupt landed before any of this project's code ran: Python's
    fatal start-up errors, or a traceback without a frame of ours (or none at all)."""
    if "init_import_site" in stderr or "Could not import runpy module" in stderr:
        return True
    ours = [ln for ln in stderr.splitlines() if ln.strip().startswith("File") and str(ROOT) in ln]
    return not ours


def sweep(
    command: str, base: Path, work: Path, step_s: float, until_s: float = math.inf
) -> tuple[int, dict, list]:
    """Moments from 0.05 s until a run finishes before its interrupt (or `until_s`)."""
    outcomes: dict[str, int] = {}
    failures = []
    delay, runs = 0.05, 0
    while True:
        code, why, finished_first = one(command, base, work, delay)
        runs += 1
        start = why == "python start-up"
        key = "python start-up" if start else f"exit {code}" + ("" if why is None else " failed")
        outcomes[key] = outcomes.get(key, 0) + 1
        if why and not start:
            failures.append((round(delay, 2), why))
        if finished_first or delay + step_s > until_s:  # the run ended before its interrupt
            break
        delay += step_s
    return runs, outcomes, failures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--step", type=float, default=0.25, help="seconds between moments")
    parser.add_argument("--commands", default=",".join(COMMANDS), help="comma-separated")
    parser.add_argument("--until", type=float, default=math.inf, help="last moment (s)")
    args = parser.parse_args(argv)
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        base = _base(Path(tmp))
        for command in args.commands.split(","):
            runs, outcomes, failures = sweep(command, base, Path(tmp), args.step, args.until)
            print(f"{command}: {runs} moments, {outcomes}", flush=True)
            for delay, why in failures:
                print(f"  at {delay} s: {why}", flush=True)
            bad += len(failures)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
