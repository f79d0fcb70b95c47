"""Paired, alternating CPU time of the tracer's ray stages (``trace_pose`` less edge
diffraction and the energy floor: shooting, scattering, clustering, the exact
specular stage and the glints) in two checkouts, on the corridor drive.

Each side is a worker process (this file run as a script, its checkout first on
the path) that builds its `Simulator` once, warms up, then traces the same 20 poses
(every trace paid) when told; the driver tells them in turn, so a loaded machine's
drift falls on both sides of a pair alike.  Reported per pose (CPU ms, each side's
median over the pairs) and the median of the pairs' ratios (base / new).

    python -m benchmarks.trace_rays --base /path/to/old/checkout [--pairs 9]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "corridor.toml"
POSES = list(range(10, 50, 2))
#: trace_pose and what of it is not the ray stages (those a checkout has: the later
#: energy floor's candidate count as well)
PARTS = ("trace_pose", "edge_diffraction", "energy_floor", "_floor_so_far")
FLOOR = ("diffraction_candidates",)


def worker(scene_path: str) -> None:
    """Answer ``run`` with CPU seconds: the whole of trace_pose and its parts."""
    import acousim.trace.tracer as tracer
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    names = [n for n in PARTS + FLOOR if hasattr(tracer, n)]
    spent = dict.fromkeys(PARTS + FLOOR, 0.0)

    def timed(name, fn):
        def call(*args, **kwargs):
            t = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[name] += time.process_time() - t

        return call

    for name in names:
        setattr(tracer, name, timed(name, getattr(tracer, name)))
    sim = Simulator(load_scene(scene_path))
    sim.run([0, 1])  # compiled kernels, caches
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        if line.strip() != "run":
            continue
        sim.tracer.forget()
        for k in spent:
            spent[k] = 0.0
        for i in POSES:
            sim.tracer.trace(sim.scene.sensor.poses[i])
        print(json.dumps(spent), flush=True)


def rays_part(t: dict) -> float:
    """CPU s of the ray stages: trace_pose less diffraction and the energy floor."""
    floor = t["energy_floor"] + t["_floor_so_far"] + sum(t.get(n, 0.0) for n in FLOOR)
    return t["trace_pose"] - t["edge_diffraction"] - floor


def main(argv: list[str] | None = None) -> None:
    from benchmarks.paired import Worker

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, required=True, help="checkout to compare against")
    ap.add_argument("--new", type=Path, default=ROOT, help="checkout timed (this one)")
    ap.add_argument("--pairs", type=int, default=9)
    a = ap.parse_args(argv)
    me = Path(__file__).resolve()
    base = Worker(a.base, me, "--worker", str(SCENE))
    new = Worker(a.new, me, "--worker", str(SCENE))
    rows = []
    for k in range(a.pairs):
        order = (base, new) if k % 2 == 0 else (new, base)
        t = {id(w): w.ask("run") for w in order}
        rows.append((t[id(base)], t[id(new)]))
    base.close()
    new.close()
    per = 1e3 / len(POSES)
    for label, f in (
        ("ray stages", rays_part),
        ("trace_pose less diffraction", lambda t: t["trace_pose"] - t["edge_diffraction"]),
        ("trace_pose", lambda t: t["trace_pose"]),
    ):
        b = np.array([f(x) for x, _ in rows])
        n = np.array([f(y) for _, y in rows])
        print(
            f"{label}: base {np.median(b) * per:.2f} ms, new {np.median(n) * per:.2f} ms CPU "
            f"per pose; median of {a.pairs} paired ratios {np.median(b / n):.2f}x"
        )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--worker"]:
        worker(sys.argv[2])
    else:
        main()
