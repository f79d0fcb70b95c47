"""Each benchmark section's core work, this checkout against another, paired.

    python -m benchmarks.versus --base /path/to/old/checkout [--pairs 7] [--only doa,pdm]

One worker process per checkout (the checkout first on its path) prepares every
workload's inputs once (the same scene files, seeds and recordings on both sides),
warms up, then times a workload when told; the driver tells the two workers in turn,
alternating which goes first, so a loaded machine's drift falls on both sides of a
pair alike.  Reported per workload: the median of the pairs' ratios new / old of
wall and of CPU time, and the old side's median wall time (of ``REPEAT`` runs of a
short workload).  A ratio within about
±10 % of 1 is noise on a shared machine; the CPU ratio is the cross-check.

The workloads use only names both checkouts have (the public names of `processing`,
`acousim` and `hardware`), one per benchmark section that times work:

- ``doa``: a DAS and a MUSIC-FBSS image of a corridor recording (section "Imaging");
- ``broadband``: the DAS energyscape of that recording over the default fan;
- ``render``: the points scene (eq. 1, 64 microphones, no tracing) simulated;
- ``corridor``: `Simulator.run` over 10 corridor poses, every trace paid;
- ``shoebox``: the shoebox scene built and simulated (as a user runs it);
- ``pdm``: one measurement's PDM ticks decoded (32 channels);
- ``file``: 10 corridor recordings written and read back.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
WORKLOADS = ("doa", "broadband", "render", "corridor", "shoebox", "pdm", "file")
#: the short workloads timed this many times over (one timing: at least ~50 ms)
REPEAT = {"render": 5, "shoebox": 3, "pdm": 50}


def _inputs(root: Path) -> dict:
    """What the workloads take, made once in the worker (`root`: its checkout)."""
    import processing as P
    from acousim import Simulator, load_scene

    scenes = root / "scenes"
    corridor = Simulator(load_scene(scenes / "corridor.toml"))
    recs = corridor.run(list(range(10, 20)))
    rng = np.random.default_rng(0)
    ticks = rng.integers(0, 2**32, 163840, dtype=np.uint32)
    return {
        "P": P,
        "load_scene": load_scene,
        "Simulator": Simulator,
        "scenes": scenes,
        "corridor": corridor,
        "recs": recs,
        "ticks": ticks,
        "points": Simulator(load_scene(scenes / "points.toml")),
    }


def _run(name: str, x: dict, tmp: Path) -> None:
    """One workload (see the module's list)."""
    P = x["P"]
    if name == "doa":
        P.acoustic_image(x["recs"][0], "das")
        P.acoustic_image(x["recs"][0], "music-fbss")
    elif name == "broadband":
        P.energyscape(x["recs"][0], P.Grid.degrees((-40, 40), (-90, 90), 2.0), "das-bb")
    elif name == "render":
        x["points"].run()
    elif name == "corridor":
        x["corridor"].tracer.forget()
        x["corridor"].run(list(range(20, 30)))
    elif name == "shoebox":
        x["Simulator"](x["load_scene"](x["scenes"] / "shoebox.toml")).run()
    elif name == "pdm":
        import hardware

        hardware.decode(x["ticks"])
    elif name == "file":
        path = tmp / "drive.h5"
        P.save_recordings(path, x["recs"])
        P.load_recordings(path)
        path.unlink()


def worker() -> None:
    """A worker: prepare, warm up, then answer ``NAME`` lines with JSON times."""
    root = Path(os.getcwd())
    from acousim.process import configure

    configure()  # the process's policy, as the command line sets it (both sides alike)
    x = _inputs(root)
    with tempfile.TemporaryDirectory() as tmp:
        for name in WORKLOADS:  # warm-up: compiled kernels, caches, imports
            _run(name, x, Path(tmp))
        print(json.dumps({"ready": True}), flush=True)
        for line in sys.stdin:
            name = line.strip()
            if not name:
                continue
            t, c = time.perf_counter(), time.process_time()
            for _ in range(REPEAT.get(name, 1)):
                _run(name, x, Path(tmp))
            out = {"wall": time.perf_counter() - t, "cpu": time.process_time() - c}
            print(json.dumps(out), flush=True)


def main(base: Path, pairs: int, only: tuple[str, ...]) -> str:
    # here, not at the head: a worker runs this file as a script, without the package
    from benchmarks.paired import Worker

    new, old = (Worker(c, Path(__file__).resolve(), "--worker") for c in (ROOT, base))
    lines = [
        f"new: this checkout; old: {base}; {pairs} alternating pairs per workload; "
        "new/old medians of the pairs' ratios",
        "",
        "| workload | old wall (ms) | new/old wall | new/old CPU |",
        "| --- | ---: | ---: | ---: |",
    ]
    try:
        for name in only:
            wall, cpu, base_ms = [], [], []
            for k in range(pairs):
                first, second = (new, old) if k % 2 == 0 else (old, new)
                a, b = first.ask(name), second.ask(name)
                n, o = (a, b) if first is new else (b, a)
                wall.append(n["wall"] / o["wall"])
                cpu.append(n["cpu"] / max(o["cpu"], 1e-9))
                base_ms.append(o["wall"] * 1e3)
            lines.append(
                f"| {name} | {np.median(base_ms):.1f} | {np.median(wall):.3f} | "
                f"{np.median(cpu):.3f} |"
            )
    finally:
        new.close()
        old.close()
    return "\n".join(lines)


if __name__ == "__main__":
    if "--worker" in sys.argv:
        worker()
        sys.exit()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", required=True, type=Path, help="the other checkout")
    ap.add_argument("--pairs", type=int, default=7, help="pairs per workload")
    ap.add_argument("--only", default=",".join(WORKLOADS), help="workloads, comma-separated")
    a = ap.parse_args()
    print(main(a.base.resolve(), a.pairs, tuple(a.only.split(","))))
