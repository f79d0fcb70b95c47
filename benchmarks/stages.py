"""CPU time per stage of a corridor pose (docs/physics.md, speed): trace, kinematics
(the paths turned into echoes and Doppler factors), the render's plan, the render,
noise and record; the stages one after the other in one thread (the tracer's
Embree threads counted: process time), the median over 20 poses of the drive.

    python -m benchmarks.stages ['{"render_rate": "baseband"}']
    python -m benchmarks.stages --base ../old --rounds 8   # against a checkout

The process is configured as the command line configures it
(:func:`acousim.process.configure`: BLAS on one thread, freed memory kept; without
it OpenBLAS's threads spin and about double the CPU time).  With ``--base DIR``
(another checkout's root, which needs not have this script) it
runs itself in alternating processes importing this tree's code and DIR's
(:mod:`benchmarks.alternating`) and prints the medians of the rounds' medians per
stage and of the rounds' ratios of the totals (DIR over this tree).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from acousim.process import configure
from acousim.scene import load_scene
from acousim.simulator import SCENE_MOTION, Simulator

try:
    import acousim.synth.signal_model as model
except ModuleNotFoundError:  # a checkout before the layout by concept (fae701f)
    import acousim.synth.model as model  # type: ignore[no-redef]

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"
POSES = list(range(10, 50, 2))
STAGES = ("trace", "kinematics", "plan", "render", "noise+record", "total")


def stage_times(overrides: dict) -> dict[str, float]:
    """Median CPU seconds per stage over POSES."""
    scene = load_scene(SCENE)
    scene = dataclasses.replace(
        scene, simulation=dataclasses.replace(scene.simulation, **overrides)
    )
    sim = Simulator(scene)
    sim.run([0, 1])  # compiled kernels, caches
    sim.tracer.forget()
    times = {k: [] for k in STAGES}
    render = model.render_planned
    spent = {}

    def timed(plan):
        t = time.process_time()
        y = render(plan)
        spent["render"] = time.process_time() - t
        return y

    model.render_planned = timed
    try:
        for i in POSES:
            pose = sim.scene.sensor.poses[i]
            t0 = time.process_time()
            sim.tracer.trace(pose)
            t1 = time.process_time()
            prep = sim._prepare(pose, i, None, SCENE_MOTION)
            t2 = time.process_time()
            prep = sim._planned(prep)
            t3 = time.process_time()
            sim._record(prep, i, None)
            t4 = time.process_time()
            for k, v in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, spent["render"])):
                times[k].append(v)
            times["noise+record"].append(t4 - t3 - spent["render"])
            times["total"].append(t4 - t0)
    finally:
        model.render_planned = render
    return {k: float(np.median(v)) for k, v in times.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("overrides", nargs="?", default="{}", help="simulation settings (JSON)")
    ap.add_argument("--base", type=Path, help="another checkout's root, run alternately")
    ap.add_argument("--rounds", type=int, default=8, help="alternating rounds (--base)")
    args = ap.parse_args()
    configure()  # the process's policy, as the command line sets it (BLAS on one thread)
    if args.base is not None:
        # imported here: the processes it starts import another checkout's code
        from benchmarks.alternating import alternate, stage_fields, summary

        runs = alternate(
            Path(__file__).resolve(), [args.overrides], args.base.resolve(), args.rounds
        )
        fields = {k: [stage_fields(out) for out in outs] for k, outs in runs.items()}
        print(summary(fields, STAGES, "corridor"))
        return
    t = stage_times(json.loads(args.overrides))
    print(" | ".join(f"{k} {v * 1e3:.2f}" for k, v in t.items()), "ms CPU (median of 20 poses)")


if __name__ == "__main__":
    main()
