"""Paired, alternating timing of `Simulator.run` in two checkouts (or two settings).

Each side is a worker process (:mod:`benchmarks.paired_worker`) that builds its
`Simulator` once, warms up, then times `run` over the same poses when told; the
driver tells them in turn (never both at once), so a loaded machine's drift falls
on both sides of a pair alike.  Reported: the median of the pairs' ratios of wall
time and of CPU time (the cross-check on a shared machine), and measurements/s.

    python -m benchmarks.paired --base /path/to/old/checkout [--pairs 7]
        [--overrides '{"diffraction": false}'] [--base-overrides '{}'] [--save DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
WORKER = Path(__file__).resolve().parent / "paired_worker.py"
SCENE = ROOT / "scenes" / "corridor.toml"


class Worker:
    """A script run in a process of its own with one checkout first on its path,
    answering one JSON line per command line (and one when ready)."""

    def __init__(self, checkout: Path, script: Path, *args: str):
        env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
        self.proc = subprocess.Popen(
            [sys.executable, str(script), *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=env,
            cwd=str(checkout),
        )
        self.answer()  # ready

    def answer(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("worker ended")
        return json.loads(line)

    def ask(self, command: str) -> dict:
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return self.answer()

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, required=True, help="checkout to compare against")
    ap.add_argument("--new", type=Path, default=ROOT, help="checkout timed (this one)")
    ap.add_argument("--scene", type=Path, default=SCENE)
    ap.add_argument("--first", type=int, default=10)
    ap.add_argument("--poses", type=int, default=40)
    ap.add_argument("--pairs", type=int, default=7)
    ap.add_argument("--overrides", default="{}", help="simulation settings of the new side")
    ap.add_argument("--base-overrides", default="{}")
    ap.add_argument("--save", type=Path, default=None, help="save both sides' samples here")
    a = ap.parse_args(argv)
    scene = a.scene.resolve()
    args = (str(scene), str(a.first), str(a.poses))
    base = Worker(a.base, WORKER, *args, a.base_overrides)
    new = Worker(a.new, WORKER, *args, a.overrides)
    if a.save is not None:
        a.save.mkdir(parents=True, exist_ok=True)
        base.ask(f"save {a.save / 'base.npy'}")
        new.ask(f"save {a.save / 'new.npy'}")
    wall, cpu, rate = [], [], []
    for k in range(a.pairs):
        order = (base, new) if k % 2 == 0 else (new, base)
        t = {id(w): w.ask("run") for w in order}
        tb, tn = t[id(base)], t[id(new)]
        wall.append(tb["wall"] / tn["wall"])
        cpu.append(tb["cpu"] / tn["cpu"])
        rate.append((a.poses / tb["wall"], a.poses / tn["wall"]))
        print(
            f"pair {k}: base {tb['wall']:.2f} s ({tb['cpu']:.2f} CPU), new {tn['wall']:.2f} s "
            f"({tn['cpu']:.2f} CPU): speed-up {wall[-1]:.2f}x wall, {cpu[-1]:.2f}x CPU",
            flush=True,
        )
    base.close()
    new.close()
    r = np.array(rate)
    print(
        f"median of {a.pairs} pairs: {np.median(wall):.2f}x wall, {np.median(cpu):.2f}x CPU; "
        f"measurements/s base {np.median(r[:, 0]):.1f}, new {np.median(r[:, 1]):.1f}"
    )
    if a.save is not None:
        b, n = np.load(a.save / "base.npy"), np.load(a.save / "new.npy")
        res = 10 * np.log10(np.sum((n - b) ** 2) / np.sum(b**2))
        print(f"residual of the new recordings against the base: {res:.1f} dB")


if __name__ == "__main__":
    main()
