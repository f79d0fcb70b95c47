"""Paired, alternating CPU time of the moving render's two stages, plan
(:func:`acousim.synth.doppler.plan_doppler`) and render
(:func:`acousim.synth.doppler.render_planned`), in two checkouts, each with its own
code from the same echoes: what a corridor pose costs after its trace and
kinematics.

``dump PATH``: the echoes, Doppler factors and settings of 20 corridor poses
(``benchmarks.stages``' poses) pickled to PATH.  ``compare BASE PATH [pairs]``: a
worker process per checkout (this one and BASE, each configured as the command
line configures it: :func:`acousim.process.configure`) loads them and, told in
turn, plans and renders them all; reported per pair and as the median of the
pairs' ratios (base / this): the CPU ms per pose of plan, render and both; then
the residual of this checkout's noise-free signals against the base's, all
microphones, over the whole recording and from 2.5 ms on (after the direct
path), dB re the base's energy there.

    python -m benchmarks.render_stage dump /tmp/args.pkl
    python -m benchmarks.render_stage compare /tmp/base_d10 /tmp/args.pkl 7
"""

from __future__ import annotations

import json
import pickle
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
#: where the direct path has passed (s): the residual re the echoes starts here
ECHOES_FROM_S = 2.5e-3


def dump(path: str) -> None:
    """The plan's arguments for the corridor's POSES pickled to `path`."""
    from acousim.scene import load_scene
    from acousim.simulator import SCENE_MOTION, Simulator
    from benchmarks.stages import POSES, SCENE

    sim = Simulator(load_scene(SCENE))
    sensor, poses = sim.scene.sensor, []
    for i in POSES:
        prep = sim._prepare(sensor.poses[i], i, None, SCENE_MOTION)
        poses.append((prep.echoes, prep.rate, prep.n_samples))
    args = {"poses": poses, "call": sensor.call, "fs": sensor.sample_rate_hz}
    args |= {"options": sim.options, "response": sim.response}
    Path(path).write_bytes(pickle.dumps(args))


def serve(path: str) -> None:
    """A worker: plans and renders the poses of `path` when told ``run`` (CPU s of
    each stage answered) or ``save OUT`` (the signals stacked to OUT, .npy)."""
    from acousim.process import configure

    configure()
    from acousim.synth.doppler import DopplerCache, plan_doppler, render_planned

    a = pickle.loads(Path(path).read_bytes())
    cache = DopplerCache()

    def plan(echoes, rate, n):
        kw = {"options": a["options"], "response": a["response"], "cache": cache}
        return plan_doppler(echoes, rate, a["call"], a["fs"], n, **kw)

    for pose in a["poses"][:2]:  # compiled kernels, the drive's templates
        render_planned(plan(*pose))
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        cmd = line.split()
        if cmd[0] == "run":
            tp = tr = 0.0
            for pose in a["poses"]:
                t0 = time.process_time()
                p = plan(*pose)
                t1 = time.process_time()
                render_planned(p)
                tp, tr = tp + t1 - t0, tr + time.process_time() - t1
            out = {"plan": tp, "render": tr, "n": len(a["poses"])}
        else:
            np.save(cmd[1], np.stack([render_planned(plan(*pose)) for pose in a["poses"]]))
            out = {"saved": cmd[1], "fs": a["fs"]}
        print(json.dumps(out), flush=True)


def residuals(base: np.ndarray, new: np.ndarray, first: int) -> tuple[float, float]:
    """dB of ``sum (new - base)^2 / sum base^2`` over all samples and from sample
    `first` on (-inf where identical)."""

    def db(b, n):
        e = float(np.sum((n - b) ** 2))
        return 10 * np.log10(e / float(np.sum(b**2))) if e > 0 else -np.inf

    return db(base, new), db(base[..., first:], new[..., first:])


def compare(base: str, path: str, pairs: int) -> None:
    """Paired, alternating CPU time of the two checkouts' plans and renders."""
    from benchmarks.paired import Worker

    me = Path(__file__).resolve()
    sides = [Worker(Path(base), me, "serve", path), Worker(ROOT, me, "serve", path)]
    ratios: dict[str, list[float]] = {"plan": [], "render": [], "both": []}
    for k in range(pairs):
        order = sides if k % 2 == 0 else sides[::-1]
        t = {id(w): w.ask("run") for w in order}
        b, n = t[id(sides[0])], t[id(sides[1])]
        for side in (b, n):
            side["both"] = side["plan"] + side["render"]
        ms = {key: (b[key] * 1e3 / b["n"], n[key] * 1e3 / n["n"]) for key in ratios}
        for key in ratios:
            ratios[key].append(b[key] / n[key])
        cells = ", ".join(f"{key} {v[0]:.2f} -> {v[1]:.2f} ms" for key, v in ms.items())
        print(f"pair {k}: {cells} (CPU per pose)", flush=True)
    saved = (f"{path}.base.npy", f"{path}.new.npy")
    fs = sides[0].ask(f"save {saved[0]}")["fs"]
    sides[1].ask(f"save {saved[1]}")
    for w in sides:
        w.close()
    b, n = np.load(saved[0]), np.load(saved[1])
    whole, echoes = residuals(b, n, int(round(ECHOES_FROM_S * fs)))
    speed = ", ".join(f"{key} {np.median(v):.3f}x" for key, v in ratios.items())
    print(f"median of {pairs} pairs, CPU base / new: {speed}")
    print(
        f"residual (noise-free, all microphones, {b.shape[0]} poses): {whole:.1f} dB re the "
        f"recording, {echoes:.1f} dB re the echoes (from {ECHOES_FROM_S * 1e3:.1f} ms); "
        f"identical bytes: {np.array_equal(b, n)}"
    )


if __name__ == "__main__":
    if sys.argv[1] == "dump":
        dump(sys.argv[2])
    elif sys.argv[1] == "serve":
        serve(sys.argv[2])
    else:
        compare(sys.argv[2], sys.argv[3], int(sys.argv[4]) if len(sys.argv) > 4 else 7)
