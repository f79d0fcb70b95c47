"""What the ground truth of what the sensor sees costs (issue 35): the corridor drive
at its defaults, this code against an older checkout, in alternating subprocesses.

    python -m benchmarks.truth_cost /path/to/old/checkout [pairs]
    python -m benchmarks.truth_cost --in-process [pairs]
    python -m benchmarks.truth_cost --per-pose

Each worker imports acousim from its checkout, builds the corridor's simulator, runs
pose 0 (caches, compilation), then ``Simulator.run`` over 20 poses of the drive with
every trace paid (``tracer.forget()``), twice, and reports the best time per
measurement; then writes those 20 recordings (the default float32 + fletcher32
file) and reports the file's size.  The parent alternates old and new `pairs`
times and prints the medians of the per-pair ratios.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

POSES = list(range(10, 30))  # as benchmarks/corridor.py: two seconds of the drive
HERE = Path(__file__).resolve().parent.parent


def worker(code: str) -> dict:
    """Measurements/s and file bytes of the code at `code` (run in a subprocess)."""
    sys.path.insert(0, code)
    import processing as P
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    assert Path(P.__file__).resolve().is_relative_to(Path(code).resolve()), P.__file__
    scene = load_scene(Path(code) / "scenes" / "corridor.toml")
    sim = Simulator(scene)
    sim.run([0])
    best = np.inf
    for _ in range(2):
        sim.tracer.forget()
        t = time.perf_counter()
        recs = sim.run(POSES)
        best = min(best, time.perf_counter() - t)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "drive.h5"
        P.save_recordings(path, recs)
        size = path.stat().st_size
    paths = int(np.mean([len(r.truth) for r in recs]))
    return {"per_s": len(POSES) / best, "bytes": size, "paths": paths}


def _run(code: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks.truth_cost", "--worker", code],
        cwd=HERE,
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(old: str, pairs: int = 3) -> str:
    speed, size, rows = [], [], []
    for _ in range(pairs):
        a, b = _run(old), _run(str(HERE))
        speed.append(b["per_s"] / a["per_s"])
        size.append(b["bytes"] / a["bytes"])
        rows.append((a, b))
    lines = [f"old {a} new {b}" for a, b in rows]
    lines.append(
        f"{pairs} alternating pairs, corridor drive (20 poses, defaults): new/old "
        f"measurements/s median {np.median(speed):.3f} (pairs {np.round(speed, 3).tolist()}), "
        f"file size median {np.median(size):.3f} (pairs {np.round(size, 3).tolist()})"
    )
    return "\n".join(lines)


class _Nothing:
    def fields(self):
        return {}


def _switch():
    """The corridor's simulator (pose 0 run: caches, compilation) and the simulator's
    calls that make what the sensor sees: as they are, and replaced by ones that
    return nothing (the old ground truth)."""
    import acousim.simulator as S
    from acousim.scene import load_scene

    sim = S.Simulator(load_scene(HERE / "scenes" / "corridor.toml"))
    sim.run([0])
    real = (S.seen_moving, S.seen_static, S.Simulator._chains)
    off = (lambda *a, **k: _Nothing(), lambda *a, **k: _Nothing(), lambda *a, **k: {})
    return sim, real, off


def in_process(pairs: int = 7) -> str:
    """This code with and without what the sensor sees (the simulator's calls that
    make it replaced by ones that return nothing: the old ground truth), alternating
    in one process: `Simulator.run` over POSES, every trace paid; the median of the
    per-pair ratios of measurements/s."""
    import acousim.simulator as S

    sim, real, off = _switch()
    spent = [0.0]

    def clocked(f):  # the time spent in f (any thread), summed
        def run(*a, **k):
            t = time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                spent[0] += time.perf_counter() - t

        return run

    on = tuple(clocked(f) for f in real)

    def timed(funcs) -> tuple[float, float]:
        S.seen_moving, S.seen_static, S.Simulator._chains = funcs
        sim.tracer.forget()
        t, c = time.perf_counter(), time.process_time()
        sim.run(POSES)
        return time.perf_counter() - t, time.process_time() - c

    wall, cpu, share = [], [], []
    try:
        for _ in range(pairs):
            spent[0] = 0.0
            (w0, c0), (w1, c1) = timed(off), timed(on)
            wall.append(w1 / w0)
            cpu.append(c1 / c0)
            share.append(spent[0] / w1)
    finally:
        S.seen_moving, S.seen_static, S.Simulator._chains = real
    return (
        f"in one process, {pairs} alternating pairs of run() over {len(POSES)} poses, "
        f"without and with what the sensor sees: time with / without, medians of the "
        f"pairs: wall {np.median(wall):.3f} (pairs {np.round(wall, 3).tolist()}), CPU "
        f"{np.median(cpu):.3f} (pairs {np.round(cpu, 3).tolist()}); time inside the "
        f"added calls / the run's wall time: median {np.median(share):.3f} "
        f"(pairs {np.round(share, 3).tolist()})"
    )


def per_pose(rounds: int = 2) -> str:
    """CPU time of `Simulator.simulate_pose` (one thread: no preparation ahead) per
    pose of POSES, without and with what the sensor sees, the order alternating
    from pose to pose; the median of the per-pose ratios."""
    import acousim.simulator as S

    sim, real, off = _switch()
    poses = sim.scene.sensor.poses
    ratios, cpu = [], {False: [], True: []}
    try:
        for r in range(rounds):
            for i in POSES:
                took = {}
                for funcs in (off, real) if (i + r) % 2 == 0 else (real, off):
                    S.seen_moving, S.seen_static, S.Simulator._chains = funcs
                    sim.tracer.forget()
                    c = time.process_time()
                    sim.simulate_pose(poses[i], i)
                    took[funcs is real] = time.process_time() - c
                ratios.append(took[True] / took[False])
                for k in took:
                    cpu[k].append(took[k])
    finally:
        S.seen_moving, S.seen_static, S.Simulator._chains = real
    q = np.percentile(ratios, [25, 50, 75])
    return (
        f"simulate_pose CPU per pose, median: {np.median(cpu[False]) * 1e3:.0f} ms without, "
        f"{np.median(cpu[True]) * 1e3:.0f} ms with; with / without over {len(ratios)} "
        f"paired poses: median {q[1]:.3f} (quartiles {q[0]:.3f}-{q[2]:.3f})"
    )


if __name__ == "__main__":
    if sys.argv[1] == "--worker":
        print(json.dumps(worker(sys.argv[2])))
    elif sys.argv[1] == "--per-pose":
        print(per_pose())
    elif sys.argv[1] == "--in-process":
        print(in_process(int(sys.argv[2]) if len(sys.argv) > 2 else 7))
    else:
        print(main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 3))
