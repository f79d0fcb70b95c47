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
import time
from pathlib import Path

import numpy as np

import acousim.process
import acousim.synth.signal_model as model
from acousim.bundled import find_scene
from acousim.scene import load_scene
from acousim.simulator import SCENE_MOTION, Simulator

STAGES = ("trace", "echoes+truth", "render", "noise+record", "total")


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


def paired(base: Path, scenes: list[str], n: int, rounds: int) -> None:
    """This tree against the checkout `base` in alternating processes (module
    docstring)."""
    # imported here: the processes it starts import another checkout's code
    from benchmarks.alternating import alternate, stage_fields, summary

    runs = alternate(Path(__file__).resolve(), [*scenes, "--n", str(n)], base, rounds)
    for name in scenes:
        fields = {
            label: [
                stage_fields(line.split(" ", 1)[1])
                for out in outs
                for line in out.splitlines()
                if line.split(" ", 1)[0] == name
            ]
            for label, outs in runs.items()
        }
        print(summary(fields, STAGES, name))


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
