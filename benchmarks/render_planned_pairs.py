"""Paired, alternating CPU time of the moving render (step 5,
:func:`acousim.synth.doppler.render_planned`) in two checkouts, on the same plans.

``dump PATH``: the :class:`~acousim.synth.doppler.DopplerPlan` of 20 corridor poses
(``benchmarks.stages``' poses) pickled to PATH.  ``compare BASE PATH [pairs]``: a
worker process per checkout (this one and BASE) loads the plans and, told in turn,
renders them all (each process configured as the command line configures it:
:func:`acousim.process.configure`); reported: the median over the pairs of the ratio of their CPU
times (base / this), each side's median CPU ms per render, and the residual of this
checkout's signals against the base's (dB re the base's energy; noise-free, all
microphones).

    python -m benchmarks.render_planned_pairs dump /tmp/plans.pkl
    python -m benchmarks.render_planned_pairs compare /tmp/base_e58 /tmp/plans.pkl 9
"""

from __future__ import annotations

import pickle
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.paired import Worker
from benchmarks.stages import POSES, SCENE

ROOT = Path(__file__).resolve().parent.parent


def dump(path: str) -> None:
    """The plans of the corridor's POSES pickled to `path`."""
    from acousim.scene import load_scene
    from acousim.simulator import SCENE_MOTION, Simulator

    sim = Simulator(load_scene(SCENE))
    plans = []
    for i in POSES:
        pose = sim.scene.sensor.poses[i]
        plans.append(sim._planned(sim._prepare(pose, i, None, SCENE_MOTION)).plan)
    Path(path).write_bytes(pickle.dumps(plans))


def serve(path: str) -> None:
    """A worker: renders the plans of `path` when told ``run`` (CPU s answered) or
    ``save OUT`` (the signals stacked to OUT, .npy)."""
    import json

    from acousim.process import configure

    configure()  # the process's policy, as the command line and benchmarks.paired set it
    from acousim.synth.doppler import render_planned

    plans = pickle.loads(Path(path).read_bytes())
    render_planned(plans[0])  # compiled kernels
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        cmd = line.split()
        if cmd[0] == "run":
            t = []
            for plan in plans:
                c = time.process_time()
                render_planned(plan)
                t.append(time.process_time() - c)
            out = {"cpu": sum(t), "median": float(np.median(t))}
        else:
            np.save(cmd[1], np.stack([render_planned(p) for p in plans]))
            out = {"saved": cmd[1]}
        print(json.dumps(out), flush=True)


def compare(base: str, path: str, pairs: int) -> None:
    """Paired, alternating CPU time of the two checkouts' renders of the plans."""
    me = Path(__file__).resolve()
    sides = [Worker(Path(base), me, "serve", path), Worker(ROOT, me, "serve", path)]
    ratio, ms = [], []
    for k in range(pairs):
        order = sides if k % 2 == 0 else sides[::-1]
        t = {id(w): w.ask("run") for w in order}
        b, n = t[id(sides[0])], t[id(sides[1])]
        ratio.append(b["cpu"] / n["cpu"])
        ms.append((b["median"] * 1e3, n["median"] * 1e3))
        print(f"pair {k}: base {ms[-1][0]:.1f} ms, new {ms[-1][1]:.1f} ms: {ratio[-1]:.2f}x")
    saved = (f"{path}.base.npy", f"{path}.new.npy")  # beside the plans: one per comparison
    sides[0].ask(f"save {saved[0]}")
    sides[1].ask(f"save {saved[1]}")
    for w in sides:
        w.close()
    b, n = np.load(saved[0]), np.load(saved[1])
    res = 10 * np.log10(np.sum((n - b) ** 2) / np.sum(b**2)) if np.any(n != b) else -np.inf
    m = np.median(np.array(ms), axis=0)
    print(
        f"median of {pairs} pairs: {np.median(ratio):.2f}x CPU; per render base {m[0]:.1f} ms, "
        f"new {m[1]:.1f} ms; residual {res:.1f} dB, identical bytes: {np.array_equal(b, n)}"
    )


if __name__ == "__main__":
    if sys.argv[1] == "dump":
        dump(sys.argv[2])
    elif sys.argv[1] == "serve":
        serve(sys.argv[2])
    else:
        compare(sys.argv[2], sys.argv[3], int(sys.argv[4]) if len(sys.argv) > 4 else 9)
