"""Paired, alternating CPU time of the Doppler render's plan and gain-set compression
of corridor poses, in two checkouts: :func:`acousim.synth.doppler.plan_doppler` and
:func:`acousim.synth.compress.compress` (step 4 of ``render_planned``), the poses'
echoes and Doppler factors computed once beforehand (trace and kinematics not timed).

Each side is a worker process with its checkout first on its path (this file run as
a script with ``worker``); the driver asks them in turn, so a loaded machine's drift
falls on both sides of a pair alike.  Reported: per pair the CPU seconds of plan and
compress summed over the poses, and the median of the pairs' ratios; with
``--check``, the noise-free rendered signals of both sides compared (dB re the
base's energy, all microphones, all poses).

    python -m benchmarks.plan_stage --base /path/to/old/checkout [--pairs 7] [--check]
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


def _worker(scene_path: str) -> None:
    from acousim.process import configure

    configure()
    from acousim.scene import load_scene
    from acousim.simulator import SCENE_MOTION, Simulator
    from acousim.synth.compress import compress
    from acousim.synth.doppler import plan_doppler, render_planned

    sim = Simulator(load_scene(scene_path))
    sim.run([0, 1])  # compiled kernels, caches
    preps = [sim._prepare(sim.scene.sensor.poses[i], i, None, SCENE_MOTION) for i in POSES]

    def plan(prep):
        sensor = sim.scene.sensor
        return plan_doppler(
            prep.echoes,
            prep.rate,
            sensor.call,
            sensor.sample_rate_hz,
            prep.n_samples,
            options=sim.options,
            response=sim.response,
            cache=sim.doppler_cache,
        )

    def squeeze(p):
        return compress(
            p.terms,
            p.responses,
            p.templates,
            p.products,
            p.response_spectra,
            p.direct_paths,
            p.direct_terms,
            p.options.compress_tolerance,
        )

    for prep in preps[:2]:
        squeeze(plan(prep))
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        cmd = line.split()
        if cmd[0] == "run":
            tp = tc = 0.0
            for prep in preps:
                t0 = time.process_time()
                p = plan(prep)
                t1 = time.process_time()
                squeeze(p)
                t2 = time.process_time()
                tp, tc = tp + t1 - t0, tc + t2 - t1
            out = {"plan": tp, "compress": tc}
        elif cmd[0] == "save":
            np.save(cmd[1], np.stack([render_planned(plan(prep)) for prep in preps]))
            out = {"saved": cmd[1]}
        else:
            out = {"error": line}
        print(json.dumps(out), flush=True)


def main(argv: list[str] | None = None) -> None:
    from benchmarks.paired import Worker

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, required=True, help="checkout to compare against")
    ap.add_argument("--new", type=Path, default=ROOT, help="checkout timed (this one)")
    ap.add_argument("--pairs", type=int, default=7)
    ap.add_argument("--check", type=Path, default=None, help="save both sides' signals here")
    a = ap.parse_args(argv)
    script = Path(__file__).resolve()
    base = Worker(a.base, script, "worker", str(SCENE))
    new = Worker(a.new, script, "worker", str(SCENE))
    if a.check is not None:
        a.check.mkdir(parents=True, exist_ok=True)
        base.ask(f"save {a.check / 'base.npy'}")
        new.ask(f"save {a.check / 'new.npy'}")
        b, n = np.load(a.check / "base.npy"), np.load(a.check / "new.npy")
        res = 10 * np.log10(max(np.sum((n - b) ** 2), 1e-300) / np.sum(b**2))
        same = np.array_equal(b, n)
        print(
            f"{len(POSES)} poses, noise-free, all microphones: residual {res:.1f} dB "
            f"({'bit-identical' if same else 'not bit-identical'})",
            flush=True,
        )
    ratios = {"plan": [], "compress": [], "both": []}
    for k in range(a.pairs):
        order = (base, new) if k % 2 == 0 else (new, base)
        t = {id(w): w.ask("run") for w in order}
        tb, tn = t[id(base)], t[id(new)]
        tb["both"], tn["both"] = tb["plan"] + tb["compress"], tn["plan"] + tn["compress"]
        for key in ratios:
            ratios[key].append(tb[key] / tn[key])
        print(
            f"pair {k}: "
            + ", ".join(
                f"{key} {tb[key] * 1e3 / len(POSES):.2f} -> {tn[key] * 1e3 / len(POSES):.2f} ms"
                for key in ratios
            )
            + " (CPU per pose)",
            flush=True,
        )
    base.close()
    new.close()
    print(
        f"median of {a.pairs} pairs, CPU speed-up: "
        + ", ".join(f"{key} {np.median(v):.2f}x" for key, v in ratios.items())
    )


if __name__ == "__main__":
    if sys.argv[1:2] == ["worker"]:
        _worker(sys.argv[2])
    else:
        main()
