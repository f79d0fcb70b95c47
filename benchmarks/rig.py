"""A rig of four uRTIS on one body (``scenes/corridor_rig.toml``): what preparing the
world once saves, and what the crosstalk costs per firing."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from acousim.bundled import find_scene
from acousim.rig import RigSimulator
from acousim.scene import load_scene
from acousim.simulator import Simulator

#: firings timed: two rounds of the four sonars, mid-drive
FIRINGS = list(range(40, 48))
REPEAT = 5


def _firing_times(sim: RigSimulator) -> float:
    """Seconds for :data:`FIRINGS`, every trace paid (the tracer's cache emptied)."""
    sim.tracer.forget()
    t0 = time.perf_counter()
    for i in FIRINGS:
        sim.simulate(i)
    return time.perf_counter() - t0


def run() -> str:
    scene = load_scene(find_scene("corridor_rig"))
    quiet = dataclasses.replace(scene, rig=dataclasses.replace(scene.rig, crosstalk=False))
    n = len(scene.rig.sonars)
    # preparing: the rig's world once, against one sonar's simulator
    t0 = time.perf_counter()
    on = RigSimulator(scene, threads=1)
    for k in range(n):
        on.pair(k, k)
    prep_rig = time.perf_counter() - t0
    t0 = time.perf_counter()
    Simulator(on.pair(0, 0).scene, threads=1)
    prep_one = time.perf_counter() - t0
    off = RigSimulator(quiet, threads=1)
    _firing_times(on), _firing_times(off)  # warm: every pair made, kernels compiled
    ratios, t_on, t_off = [], [], []
    for r in range(REPEAT):  # paired, alternating
        if r % 2 == 0:
            a = _firing_times(on)
            b = _firing_times(off)
        else:
            b = _firing_times(off)
            a = _firing_times(on)
        t_on.append(a)
        t_off.append(b)
        ratios.append(a / b)
    heard = [len(on.simulate(i).metadata["crosstalk"]) for i in FIRINGS]
    per_off = np.median(t_off) / len(FIRINGS)
    per_on = np.median(t_on) / len(FIRINGS)
    return "\n".join(
        [
            "## Rig: four uRTIS on one body, the corridor drive, round robin at 10 Hz each",
            "",
            f"`scenes/corridor_rig.toml` ({len(on.measurements)} firings), firings "
            f"{FIRINGS[0]}-{FIRINGS[-1]} (two rounds of the {n} sonars), one thread, every "
            f"trace paid; {REPEAT} paired, alternating runs, medians.",
            "",
            "| what | time |",
            "|---|---|",
            f"| preparing the rig (its firings' poses, one world, the {n} sonars' "
            f"simulators) | {prep_rig:.2f} s |",
            f"| preparing one sonar's simulator alone (its own world) | {prep_one:.2f} s |",
            f"| a firing, crosstalk off (= one sonar's measurement) | {per_off:.2f} s |",
            f"| a firing, crosstalk on ({np.mean(heard):.1f} other firings heard) "
            f"| {per_on:.2f} s |",
            f"| crosstalk on / off (median of paired ratios) | {np.median(ratios):.2f}x |",
            "",
            f"Without crosstalk a rig of {n} sonars costs {n} measurements per round and "
            "one world (the rig's preparation is mostly its firings' poses, 2 ms each); "
            "each firing heard by another sonar adds a bistatic trace and a render, the "
            "one emitted during the window traced only as far as it can be heard (the "
            "rays shot from an emitter are not shared between its receivers: the "
            "budget and the paths depend on the receiver).",
        ]
    )


if __name__ == "__main__":  # pragma: no cover
    print(run())
