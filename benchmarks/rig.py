"""A rig of four uRTIS on one body (``scenes/corridor_rig.toml``): what preparing the
world once saves, and what a rig of N sonars costs against N times one sonar's
measurement (the crosstalk's share)."""

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
REPEAT = 7


def _firings(sim: RigSimulator) -> float:
    """CPU seconds for :data:`FIRINGS` one by one, every trace paid (the tracer's
    cache emptied)."""
    sim.tracer.forget()
    t0 = time.process_time()
    for i in FIRINGS:
        sim.simulate(i)
    return time.process_time() - t0


def _run(sim: RigSimulator) -> float:
    """CPU seconds for the rig's run of :data:`FIRINGS` (their recordings and the
    LiDARs' scans), every trace paid."""
    sim.tracer.forget()
    t0 = time.process_time()
    sim.run(FIRINGS)
    return time.process_time() - t0


def _unshared(sim: RigSimulator) -> float:
    """:func:`_firings` with each trace shooting its own rays (the rays of a call
    not shared between the sonars that hear it), then shared again."""
    sim.tracer.share_emissions(0)
    try:
        return _firings(sim)
    finally:
        sim.tracer.share_emissions()


def _rays_cast(sim: RigSimulator, share: int) -> float:
    """Rays cast per firing of :data:`FIRINGS` (every stage's, and the LiDAR's) with
    the emissions' rays shared (`share` > 0: that many kept) or not (0)."""
    sim.tracer.share_emissions(share)
    sim.tracer.forget()
    before = sim.tracer.caster.rays_cast
    for i in FIRINGS:
        sim.simulate(i)
    sim.tracer.share_emissions()
    return (sim.tracer.caster.rays_cast - before) / len(FIRINGS)


def _paired(a, b) -> tuple[list[float], list[float]]:
    """:data:`REPEAT` paired runs of the callables `a` and `b`, alternating which goes
    first: their times."""
    ta, tb = [], []
    for r in range(REPEAT):
        if r % 2 == 0:
            ta.append(a())
            tb.append(b())
        else:
            tb.append(b())
            ta.append(a())
    return ta, tb


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
    _firings(on), _firings(off)  # warm: every pair made, kernels compiled
    t_on, t_off = _paired(lambda: _firings(on), lambda: _firings(off))
    r_on, r_off = _paired(lambda: _run(on), lambda: _run(off))
    t_shared, t_own = _paired(lambda: _firings(on), lambda: _unshared(on))
    firing = np.median(np.divide(t_on, t_off))
    sharing = np.median(np.divide(t_shared, t_own))
    whole = np.median(np.divide(r_on, t_off))
    heard = [len(on.simulate(i).metadata["crosstalk"]) for i in FIRINGS]
    cast_own, cast_shared = _rays_cast(on, 0), _rays_cast(on, 8)
    per = len(FIRINGS) / 1e3  # ms per firing
    return "\n".join(
        [
            "## Rig: four uRTIS on one body, the corridor drive, round robin at 10 Hz each",
            "",
            f"`scenes/corridor_rig.toml` ({len(on.measurements)} firings), firings "
            f"{FIRINGS[0]}-{FIRINGS[-1]} (two rounds of the {n} sonars), one thread, every "
            f"trace paid; CPU time, {REPEAT} paired, alternating runs in one process, "
            "medians.  One sonar's measurement is a firing of the rig with crosstalk off "
            "(its own call, its LiDAR scan).",
            "",
            "| what | time |",
            "|---|---|",
            f"| preparing the rig (its firings' poses, one world, the {n} sonars' "
            f"simulators) | {prep_rig:.2f} s |",
            f"| preparing one sonar's simulator alone (its own world) | {prep_one:.2f} s |",
            f"| a firing, crosstalk off (= one sonar's measurement) "
            f"| {np.median(t_off) / per:.0f} ms |",
            f"| a firing, crosstalk on ({np.mean(heard):.1f} other firings heard) "
            f"| {np.median(t_on) / per:.0f} ms |",
            f"| the rig's run, per firing (crosstalk on, the LiDAR's scans) "
            f"| {np.median(r_on) / per:.0f} ms |",
            f"| the rig's run, per firing, crosstalk off | {np.median(r_off) / per:.0f} ms |",
            f"| a firing with crosstalk, each trace shooting its own rays "
            f"| {np.median(t_own) / per:.0f} ms |",
            f"| a firing with crosstalk / one sonar's measurement (paired) | {firing:.2f}x |",
            f"| a firing with crosstalk, the rays shared / each trace's own (paired) "
            f"| {sharing:.2f}x |",
            f"| rays cast per firing (every stage's and the LiDAR's), each trace's own "
            f"rays -> shared | {cast_own:,.0f} -> {cast_shared:,.0f} |",
            f"| the rig's run / (N x one sonar's measurement) (paired) | {whole:.2f}x |",
            "",
            f"Without crosstalk a rig of {n} sonars costs {n} measurements per round and "
            "one world (the rig's preparation is mostly its firings' poses, 2 ms each).  "
            "Each firing heard by another sonar adds a bistatic trace (the emitter's "
            "paths to that sonar's microphones), their kinematics and their render.  "
            "What the traces share: a call's rays are shot once for the three sonars "
            "that trace it (its own, and the two whose windows it reaches; "
            "`acousim.trace.rays.emission`: the batches followed to the longest path, "
            "cut exactly to each trace's budget, the same paths byte for byte): about "
            "one ray in ten cast per firing is saved, a few ms of a firing's 200, "
            "within the machine's spread between paired runs.  What "
            "they leave out: a call emitted during the window is traced only as far as "
            "it can be heard (the specular sequences out of reach take no work); of a "
            "call emitted before it, the paths too short to reach the window go no "
            "further than the trace, and its diffraction leaves out the edges and "
            "pairs of edges whose every path is too short and whose bound is under "
            "the strongest echo found before it (the same paths reach the window).  "
            "What is left is receiver-dependent by nature: the specular points "
            "(validated from the receiver back), the glints, the diffraction and the "
            "scattering towards the receiver, then the crosstalk's paths themselves "
            "(about half as many as the sonar's own: their kinematics and their "
            "render), so a firing heard costs most of a measurement and the rig of "
            f"{n} sonars stays above {n} measurements per round.",
        ]
    )


if __name__ == "__main__":  # pragma: no cover
    print(run())
