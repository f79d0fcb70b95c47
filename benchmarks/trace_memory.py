"""Peak memory of the ray tracer per ray and bounce (docs/scene-format.md, "Memory").

One process per ray count simulates the first pose of the bundled corridor with
``rays = N`` and ``max_range_m = 50`` (the recordings small against the trace) and
reports its peak resident memory (``resource.getrusage``, ru_maxrss); the least-squares
line through (N (bounces + 1), peak) gives the bytes per ray-bounce. Measured (2026-11,
a loaded 2-core machine): 3 bounces, 0.4/0.8/1.6 M rays: 0.898/1.404/2.456 GB, 325 B
per ray-bounce (1315 B per ray); 1 bounce, 0.8/1.6 M rays: 0.778/1.013 GB, 146 B per
ray-bounce (293 B per ray). Per ray the cost grows as (bounces + 1)**2 (82 and 73 B):
``acousim.scene.model.TRACE_BYTES_PER_RAY`` = 85 B x (bounces + 1)**2.

    python -m benchmarks.trace_memory [--rays 50000 200000 400000] [--bounces 3]
"""

from __future__ import annotations

import argparse
import subprocess
import sys

import numpy as np


def peak_bytes(rays: int, bounces: int) -> float:
    """Peak RSS (bytes) of a process simulating the corridor's first pose."""
    code = (
        "import dataclasses, resource, sys\n"
        "from acousim.bundled import find_scene\n"
        "from acousim.scene import load_scene\n"
        "from acousim.simulator import Simulator\n"
        "s = load_scene(find_scene('corridor'))\n"
        f"sim = dataclasses.replace(s.simulation, rays={rays}, bounces={bounces},"
        " max_range_m=50.0, max_memory_gb=1000.0)\n"
        "Simulator(dataclasses.replace(s, simulation=sim)).run([0])\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return float(out.stdout.split()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, nargs="+", default=[50_000, 200_000, 400_000])
    ap.add_argument("--bounces", type=int, default=3)
    a = ap.parse_args()
    x, y = [], []
    for n in a.rays:
        peak = peak_bytes(n, a.bounces)
        x.append(n * (a.bounces + 1))
        y.append(peak)
        print(f"rays {n:>9}  bounces {a.bounces}  peak {peak / 1e9:.3f} GB", flush=True)
    slope, icept = np.polyfit(x, y, 1)
    print(f"fit: peak = {icept / 1e9:.3f} GB + {slope:.0f} B x rays x (bounces + 1)")


if __name__ == "__main__":
    main()
