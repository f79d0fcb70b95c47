"""A worker of :mod:`benchmarks.paired`: one checkout's `Simulator` kept in one process.

Run as a script with the checkout to time first on PYTHONPATH; reads commands from
stdin, one a line, answers one JSON line each:
``run``: `Simulator.run` over the poses (every trace paid): wall and CPU seconds
(its forked worker's included);
``save PATH``: the recordings' samples of the poses (noise-free if asked) to PATH (.npy).
Arguments: scene file, first pose, number of poses, JSON of simulation overrides
(``diffraction`` a table of :class:`acousim.Diffraction`'s fields).
"""

from __future__ import annotations

import dataclasses
import json
import resource
import sys
import time

import numpy as np


def main() -> None:
    from acousim.process import configure

    configure()  # the process's policy, as the command line sets it (both sides alike)
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    path, first, count, overrides = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    scene = load_scene(path)
    extra = json.loads(overrides)
    if isinstance(extra.get("diffraction"), dict):  # a table: acousim.Diffraction's fields
        from acousim.scene.model import Diffraction

        extra["diffraction"] = Diffraction(**extra["diffraction"])
    if extra:
        scene = dataclasses.replace(
            scene, simulation=dataclasses.replace(scene.simulation, **extra)
        )
    sim = Simulator(scene)
    poses = list(range(first, min(first + count, len(scene.sensor.poses))))
    sim.run(poses[:2])  # warm-up: compiled kernels, caches
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        cmd = line.split()
        if not cmd:
            continue
        if cmd[0] == "run":
            sim.tracer.forget()
            t, c = time.perf_counter(), _cpu()
            sim.run(poses)
            out = {"wall": time.perf_counter() - t, "cpu": _cpu() - c}
        elif cmd[0] == "save":
            sim.tracer.forget()
            recs = sim.run(poses)
            np.save(cmd[1], np.stack([r.samples for r in recs]))
            out = {"saved": cmd[1]}
        else:
            out = {"error": line}
        print(json.dumps(out), flush=True)


def _cpu() -> float:
    """CPU seconds of this process and of its children that have ended (the worker
    `Simulator.run` forks, waited for here): ``benchmarks.timing.cpu_seconds``,
    written again here because this script runs with another checkout on its path."""
    try:  # a worker ends after the run returns (where it is waited for: this tree's)
        from acousim.core.forked import wait_for_workers
    except ImportError:
        pass
    else:
        wait_for_workers()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


if __name__ == "__main__":
    main()
