"""CPU time of the edge-diffraction stage alone on the corridor drive, paired and
alternating against another checkout (or the same one), and the difference of its
paths.

Each side is a worker process (:mod:`benchmarks.paired`'s :class:`Worker`, this file
run as a script with its checkout first on the path) that builds the corridor's
`Simulator`, runs the poses once while recording the arguments of every call of the
tracer's stage 3 (:func:`acousim.trace.diffraction.edge_diffraction`), then, when
told, calls the stage again on those arguments (its per-world caches warm, as in a
run): CPU seconds (process time: the tracer's threads counted) and wall seconds.
The driver asks the two sides in turn; reported: the median of the pairs' ratios,
and how far the new side's paths are from the base's (the largest relative
difference of their gains, delays and points; "identical" when every array is).

    python -m benchmarks.diffraction_stage --base /tmp/base_e58 [--pairs 9]
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
FIELDS = ("anchor_m", "first_leg_m", "strength", "position_m", "departure")


def _worker(scene_path: str, first: int, count: int, repeats: int) -> None:
    from acousim.process import configure

    configure()
    import acousim.trace.tracer as tracer
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    sim = Simulator(load_scene(scene_path))
    poses = list(range(first, min(first + count, len(sim.scene.sensor.poses))))
    sim.run(poses[:2])  # warm-up: compiled kernels, caches
    calls: list[tuple] = []
    stage = tracer.edge_diffraction

    def recording(*args):
        calls.append(args)
        return stage(*args)

    tracer.edge_diffraction = recording
    try:
        sim.tracer.forget()
        try:  # every pose in this process (a forked worker's calls are not seen here)
            sim.run(poses, processes=1)
        except TypeError:  # a checkout before Simulator.run's processes
            sim.run(poses)
    finally:
        tracer.edge_diffraction = stage
    # in the order of their poses (a run may trace poses in parallel)
    calls.sort(key=lambda a: (tuple(a[2]), tuple(a[3])))
    print(json.dumps({"ready": True, "calls": len(calls)}), flush=True)
    for line in sys.stdin:
        cmd = line.split()
        if cmd and cmd[0] == "run":
            t, c = time.perf_counter(), time.process_time()
            for _ in range(repeats):
                for args in calls:
                    stage(*args)
            out = {"wall": time.perf_counter() - t, "cpu": time.process_time() - c}
        elif cmd and cmd[0] == "save":
            got = [stage(*args) for args in calls]
            arrays = {
                f"{name}_{i}": np.asarray(getattr(p, name)) for i, p in enumerate(got)
                for name in FIELDS
            }  # fmt: skip
            np.savez(cmd[1], **arrays)
            out = {"saved": cmd[1]}
        else:
            out = {"error": line}
        print(json.dumps(out), flush=True)


def _difference(base: Path, new: Path) -> str:
    """The largest difference of the two sides' paths, relative to each array's
    largest magnitude (or "identical")."""
    b, n = np.load(base), np.load(new)
    if sorted(b.files) != sorted(n.files):
        return "different calls"
    worst, same = 0.0, True
    for key in b.files:
        x, y = b[key], n[key]
        if x.shape != y.shape:
            return f"{key}: {x.shape} paths against {y.shape}"
        if not np.array_equal(x, y):
            same = False
            scale = max(float(np.max(np.abs(x), initial=0.0)), 1e-300)
            worst = max(worst, float(np.max(np.abs(x - y))) / scale)
    return "identical" if same else f"largest relative difference {worst:.2e}"


def main(argv: list[str] | None = None) -> None:
    from benchmarks.paired import Worker

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, required=True)
    ap.add_argument("--new", type=Path, default=ROOT)
    ap.add_argument("--first", type=int, default=10)
    ap.add_argument("--poses", type=int, default=20)
    ap.add_argument("--pairs", type=int, default=9)
    ap.add_argument("--repeats", type=int, default=3, help="passes over the poses per run")
    ap.add_argument("--save", type=Path, default=Path("/tmp/diffraction_stage"))
    a = ap.parse_args(argv)
    args = (str(SCENE), str(a.first), str(a.poses), str(a.repeats))
    script = Path(__file__).resolve()
    base = Worker(a.base, script, "--worker", *args)
    new = Worker(a.new, script, "--worker", *args)
    a.save.mkdir(parents=True, exist_ok=True)
    base.ask(f"save {a.save / 'base.npz'}")
    new.ask(f"save {a.save / 'new.npz'}")
    cpu, wall, ms = [], [], []
    calls = a.poses * a.repeats
    for k in range(a.pairs):
        order = (base, new) if k % 2 == 0 else (new, base)
        t = {id(w): w.ask("run") for w in order}
        tb, tn = t[id(base)], t[id(new)]
        cpu.append(tb["cpu"] / tn["cpu"])
        wall.append(tb["wall"] / tn["wall"])
        ms.append((tb["cpu"] / calls * 1e3, tn["cpu"] / calls * 1e3))
        print(
            f"pair {k}: CPU per call base {ms[-1][0]:.2f} ms, new {ms[-1][1]:.2f} ms: "
            f"{cpu[-1]:.2f}x CPU, {wall[-1]:.2f}x wall",
            flush=True,
        )
    base.close()
    new.close()
    m = np.median(np.array(ms).reshape(-1, 2), axis=0)
    print(
        f"median of {a.pairs} pairs: {np.median(cpu):.2f}x CPU, {np.median(wall):.2f}x wall; "
        f"CPU per stage call base {m[0]:.2f} ms, new {m[1]:.2f} ms"
    )
    print("paths of the new side against the base:", _difference(
        a.save / "base.npz", a.save / "new.npz"))  # fmt: skip


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        _worker(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]))
    else:
        main()
