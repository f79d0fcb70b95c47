"""CPU time per measurement of the scenes that need little work, stage by stage
(docs/physics.md, "Cost that follows the scene"): `simulate_pose` of a bundled
scene's first pose, the trace paid every time (the tracer's cache emptied), the
process configured as the command line configures it, medians over `n` poses.

Stages: the trace; the echoes and the ground truth (the rest of the preparation);
the render; the noise and the recording.

    python -m benchmarks.scene_cost [shoebox wall ...] [--n 60]
    python -m benchmarks.scene_cost --base ../main --rounds 16   # against a checkout

With ``--base DIR`` (another checkout's root, which needs not have this script) it
runs itself in alternating processes importing this tree's code and DIR's (each
first in every other round), and prints the medians of the rounds' medians and of
the pairs' ratios (DIR over this tree).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import acousim.process
import acousim.synth.signal_model as model
from acousim.bundled import find_scene
from acousim.scene import load_scene
from acousim.simulator import SCENE_MOTION, Simulator

STAGES = ("trace", "echoes+truth", "render", "noise+record", "total")
HERE = Path(__file__).resolve().parent.parent


def stage_times(name: str, n: int = 60) -> dict[str, float]:
    """Median CPU seconds per stage of `n` measurements of the scene `name`'s first
    pose (after 5 not counted)."""
    sim = Simulator(load_scene(find_scene(name)))
    pose = sim.scene.sensor.poses[0]
    render = model._render
    spent = {}

    def timed(*args):
        t = time.process_time()
        y = render(*args)
        spent["render"] = time.process_time() - t
        return y

    times = {k: [] for k in STAGES}
    model._render = timed
    try:
        for i in range(n + 5):
            sim.tracer.forget()
            t0 = time.process_time()
            sim.tracer.traced(pose, sim._traced_array)
            t1 = time.process_time()
            prep = sim._prepare(pose, 0, None, SCENE_MOTION)
            t2 = time.process_time()
            sim._record(prep, 0, None)
            t3 = time.process_time()
            if i < 5:
                continue
            for k, v in zip(STAGES, (t1 - t0, t2 - t1, spent["render"], t3 - t2 - spent["render"])):
                times[k].append(v)
            times["total"].append(t3 - t0)
    finally:
        model._render = render
    return {k: float(np.median(v)) for k, v in times.items()}


def _one_process(root: Path, scenes: list[str], n: int) -> dict[str, dict[str, float]]:
    """The stage medians (ms) of `scenes` measured by this script in a process
    importing the checkout `root`'s code (first on the path)."""
    env = {**os.environ, "PYTHONPATH": str(root), "OPENBLAS_NUM_THREADS": "1"}
    cmd = [sys.executable, str(Path(__file__).resolve()), *scenes, "--n", str(n)]
    text = subprocess.run(cmd, cwd=root, env=env, check=True, capture_output=True, text=True)
    out = {}
    for line in text.stdout.splitlines():
        name, rest = line.split(" ", 1)
        out[name] = {k: float(v) for k, v in re.findall(r"([a-z+]+) ([0-9.]+)", rest)}
    return out


def paired(base: Path, scenes: list[str], n: int, rounds: int) -> None:
    """This tree against the checkout `base` in alternating processes (module
    docstring)."""
    runs = {"base": [], "now": []}
    for r in range(rounds):
        order = (("base", base), ("now", HERE)) if r % 2 == 0 else (("now", HERE), ("base", base))
        for label, root in order:
            runs[label].append(_one_process(root, scenes, n))
    for name in scenes:
        for label in ("base", "now"):
            med = {k: np.median([r[name][k] for r in runs[label]]) for k in STAGES}
            least = min(r[name]["total"] for r in runs[label])
            print(name, label, " | ".join(f"{k} {v:.2f}" for k, v in med.items()), end=" ")
            print(f"ms CPU (medians of {rounds} rounds; least total {least:.2f})")
        ratio = [b[name]["total"] / a[name]["total"] for b, a in zip(runs["base"], runs["now"])]
        q1, q2, q3 = np.percentile(ratio, [25, 50, 75])
        print(f"{name} base / now, total: median {q2:.2f}x (quartiles {q1:.2f}x-{q3:.2f}x)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=["shoebox", "wall"])
    ap.add_argument("--n", type=int, default=60, help="measurements per scene")
    ap.add_argument("--base", type=Path, help="another checkout's root, run alternately")
    ap.add_argument("--rounds", type=int, default=16, help="alternating rounds (--base)")
    args = ap.parse_args()
    if args.base is not None:
        paired(args.base.resolve(), args.scenes, args.n, args.rounds)
        return
    acousim.process.configure()
    for name in args.scenes:
        t = stage_times(name, args.n)
        print(name, " | ".join(f"{k} {v * 1e3:.2f}" for k, v in t.items()), "ms CPU")


if __name__ == "__main__":
    main()
