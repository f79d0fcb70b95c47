"""Paired, alternating CPU time of the kinematics stage (`Simulator._prepare` after
the trace, as :mod:`benchmarks.stages` times it) in two checkouts.

Each side is a process of its own (this file run as a worker with its checkout
first on the path) that builds the corridor's `Simulator`, warms up, then on each
``run`` traces the poses (not timed) and times ``_prepare`` of each (CPU); the
driver asks the two sides in turn, so the machine's drift falls on both alike.
Reported: per pair the medians over the poses, and the median of the pairs' ratios.

    python -m benchmarks.kinematics_paired --base /path/to/old/checkout [--pairs 7]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"
POSES = list(range(10, 50, 2))  # as benchmarks.stages


def worker() -> None:
    """Answer ``run`` with the median CPU seconds of the stage over POSES."""
    from acousim.scene import load_scene
    from acousim.simulator import SCENE_MOTION, Simulator

    sim = Simulator(load_scene(SCENE))
    sim.run([0, 1])  # compiled kernels, caches
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        if line.split() != ["run"]:
            print(json.dumps({"error": line}), flush=True)
            continue
        sim.tracer.forget()
        spent = []
        for i in POSES:
            pose = sim.scene.sensor.poses[i]
            sim.tracer.trace(pose)
            t = time.process_time()
            sim._prepare(pose, i, None, SCENE_MOTION)
            spent.append(time.process_time() - t)
        print(json.dumps({"cpu": float(np.median(spent))}), flush=True)


def main(argv: list[str] | None = None) -> None:
    from benchmarks.paired import Worker

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, required=True, help="checkout to compare against")
    ap.add_argument("--new", type=Path, default=SCENE.parent.parent, help="checkout timed")
    ap.add_argument("--pairs", type=int, default=7)
    a = ap.parse_args(argv)
    me = Path(__file__).resolve()
    base, new = Worker(a.base, me, "worker"), Worker(a.new, me, "worker")
    ratio = []
    for k in range(a.pairs):
        order = (base, new) if k % 2 == 0 else (new, base)
        t = {id(w): w.ask("run")["cpu"] for w in order}
        tb, tn = t[id(base)], t[id(new)]
        ratio.append(tb / tn)
        line = f"pair {k}: base {tb * 1e3:.1f} ms, new {tn * 1e3:.1f} ms: {ratio[-1]:.2f}x"
        print(line, flush=True)
    base.close()
    new.close()
    print(f"kinematics stage, median of {a.pairs} pairs: {np.median(ratio):.2f}x CPU")


if __name__ == "__main__":
    if sys.argv[1:] == ["worker"]:
        worker()
    else:
        main()
