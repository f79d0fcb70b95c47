"""A rig of four uRTIS on one body (``scenes/corridor_rig.toml``): what preparing the
world once saves, and what a rig of N sonars costs against N times one sonar's
measurement (the crosstalk's share)."""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import time

import numpy as np

from acousim.bundled import find_scene
from acousim.rig import RigSimulator
from acousim.scene import load_scene
from acousim.scene.rig import Mount, RigSonar, sonar_scene
from acousim.simulator import Simulator
from acousim.trace import tracer as tracer_module
from acousim.trace.rays.emission import Emission
from acousim.trace.tracer import Tracer

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


def _wall_rig(sim: RigSimulator) -> float:
    """Wall seconds for the rig's run of :data:`FIRINGS` as a user runs it (its
    firings in two processes, this one and a forked worker), every trace paid."""
    sim.tracer.forget()
    t0 = time.perf_counter()
    sim.run(FIRINGS)
    return time.perf_counter() - t0


def _wall_alone(sim: Simulator, poses: list[int]) -> float:
    """Wall seconds for one sonar alone (no rig: its own scene) simulating as many
    poses of its drive as :data:`FIRINGS` with `Simulator.run` (two processes)."""
    sim.tracer.forget()
    t0 = time.perf_counter()
    sim.run(poses)
    return time.perf_counter() - t0


def _alone(scene) -> tuple[float, float]:
    """Each of :data:`FIRINGS` computed on its own: a :class:`RigSimulator` of its
    own (its own world; its calls' rays shot for it alone) simulating that firing
    only.  CPU seconds for the firings, and wall seconds preparing their simulators."""
    spent = prepared = 0.0
    for i in FIRINGS:
        t0 = time.perf_counter()
        sim = RigSimulator(scene, threads=1)
        prepared += time.perf_counter() - t0
        t0 = time.process_time()
        sim.simulate(i)
        spent += time.process_time() - t0
    return spent, prepared


#: the rigs of the scaling rows: the bundled rig's sonar on the first N of these
#: mounts of its body ((x, y) m, yaw degrees): its four corners, then the middles of
#: its sides
_MOUNTS = (
    ((0.3, 0.2), 45), ((0.3, -0.2), -45), ((-0.3, -0.2), -135), ((-0.3, 0.2), 135),
    ((0.3, 0.0), 0), ((0.0, -0.2), -90), ((-0.3, 0.0), 180), ((0.0, 0.2), 90),
)  # fmt: skip
SCALING = (1, 2, 4, 8)
#: the scaling rigs fire round robin this far apart (s): each sonar at 1 / (N x it)
INTERVAL_S = 0.025


def _rig_of(scene, n: int):
    """The bundled rig with its sonar on the first `n` of :data:`_MOUNTS`, firing
    round robin :data:`INTERVAL_S` apart (the calls in the air the same for any n)."""
    sensor = scene.rig.sonars[0].sensor
    sonars = tuple(
        RigSonar(f"s{k}", sensor, Mount(np.array([*xy, 0.0]), yaw_rad=np.deg2rad(yaw)))
        for k, (xy, yaw) in enumerate(_MOUNTS[:n])
    )
    rig = dataclasses.replace(scene.rig, sonars=sonars, rate_hz=1 / (INTERVAL_S * n))
    return dataclasses.replace(scene, rig=rig)


def _scaling(scene, on: RigSimulator) -> list[str]:
    """The rows of the scaling table: per firing, rigs of :data:`SCALING` sonars
    against the bundled rig (paired CPU times of :data:`FIRINGS`)."""
    rows = []
    for n in SCALING:
        sim = RigSimulator(_rig_of(scene, n), threads=1)
        heard = np.mean([len(sim.simulate(i).metadata["crosstalk"]) for i in FIRINGS])
        t_n, t_on = _paired(lambda sim=sim: _firings(sim), lambda: _firings(on))
        ratio = np.median(np.divide(t_n, t_on))
        rows.append(
            f"| {n} | {1 / (INTERVAL_S * n):g} Hz | {heard:.1f} | "
            f"{np.median(t_n) / len(FIRINGS) * 1e3:.0f} ms | {ratio:.2f}x |"
        )
    return rows


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


#: the tracer's stages timed in :func:`_split` (functions of acousim.trace.tracer)
_STAGES = {
    "refine_sequences": "specular validation",
    "glints": "glints",
    "edge_diffraction": "diffraction",
    "_ray_work": "rays and scattering",
    "cluster": "clustering",
}
_CALLS = ("own", "previous", "next")


class _Split:
    """CPU seconds spent per (call, part) while :data:`FIRINGS` are simulated: the
    call is the sonar's own, or another sonar's call heard before its emission
    (previous) or during its window (next); the methods and the tracer's stage
    functions are wrapped for the duration (restored after)."""

    def __init__(self) -> None:
        self.call = "own"
        self.spent: dict[tuple[str, str], float] = collections.defaultdict(float)
        self.paths: dict[str, int] = collections.defaultdict(int)

    def _timed(self, fn, part: str, call=None):
        """`fn` timed as `part` of the current call (or of the call that `call`, a
        function of fn's arguments, names)."""

        def wrapper(*args, **kwargs):
            before = self.call
            if call is not None:
                self.call = call(*args)
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.spent[self.call, part] += time.process_time() - t0
                self.call = before

        return wrapper

    @contextlib.contextmanager
    def wrapped(self):
        def heard_call(_sim, f, m, _n):
            return "previous" if f.time_s < m.time_s else "next"

        targets = [
            (RigSimulator, "simulate", "firing", None),
            (RigSimulator, "_heard_from", "call heard", heard_call),
            (RigSimulator, "_rendered", "render apart", lambda *a: "own"),
            (Simulator, "heard", "heard", None),
            (Simulator, "_record", "render", None),
            (Simulator, "lidar_scan", "lidar", None),
            (Tracer, "traced", "trace", None),
            (Emission, "_follow", "rays shot", None),
        ] + [(tracer_module, name, part, None) for name, part in _STAGES.items()]
        old = [(where, name, where.__dict__[name]) for where, name, _, _ in targets]
        try:
            for where, name, part, call in targets:
                fn = getattr(where, name)
                wrapper = self._timed(fn, part, call)
                setattr(where, name, staticmethod(wrapper) if name == "_rendered" else wrapper)
            yield self
        finally:
            for where, name, value in old:
                setattr(where, name, value)

    def firings(self, sim: RigSimulator) -> None:
        """Simulate :data:`FIRINGS` (the tracer's cache emptied), counting the paths
        of each call heard."""
        sim.tracer.forget()
        with self.wrapped():
            for i in FIRINGS:
                rec = sim.simulate(i)
                for heard in rec.metadata["crosstalk"]:
                    call = "previous" if heard["delay_s"] < 0 else "next"
                    self.paths[call] += heard["n_paths"]
                self.paths["own"] += rec.metadata.get("n_paths", len(rec.truth))


def _split(on: RigSimulator, off: RigSimulator, runs: int = 5) -> tuple[dict, dict, dict]:
    """ms per firing by (call, part), crosstalk on and off (the median of `runs`
    alternating runs of :data:`FIRINGS`), and the paths heard per firing by call."""
    per_on, per_off = [], []
    paths = {}
    for r in range(runs):
        for sim, out in ((on, per_on), (off, per_off))[:: 1 if r % 2 == 0 else -1]:
            s = _Split()
            s.firings(sim)
            out.append(s.spent)
            if sim is on:
                paths = {k: v / len(FIRINGS) for k, v in s.paths.items()}

    def median(runs_):
        keys = set().union(*runs_)
        return {k: 1e3 * np.median([r.get(k, 0.0) for r in runs_]) / len(FIRINGS) for k in keys}

    return median(per_on), median(per_off), paths


def _split_table(on: dict, off: dict, paths: dict) -> list[str]:
    """The rows of :func:`_split`'s table (ms per firing)."""

    def cell(d, call, part):
        return f"{d.get((call, part), 0.0):.1f}"

    def row(name, parts, calls=_CALLS, off_too=True):
        cells = [cell(off, "own", parts) if off_too else ""]
        cells += [cell(on, c, parts) if c in calls else "" for c in _CALLS]
        return f"| {name} | " + " | ".join(cells) + " |"

    def kinematics(d, call):  # what the paths heard take beyond their trace
        return f"{d.get((call, 'heard'), 0.0) - d.get((call, 'trace'), 0.0):.1f}"

    lines = [
        "| ms per firing | own call, crosstalk off | own call | previous call heard "
        "| next call heard |",
        "|---|---|---|---|---|",
        row("trace (paths at the emission pose)", "trace"),
        *(row(f"&nbsp;&nbsp;{part}", part) for part in _STAGES.values()),
        row(
            "&nbsp;&nbsp;&nbsp;&nbsp;of which rays shot (once per call)", "rays shot", off_too=False
        ),
        "| kinematics (echoes and Doppler at the microphones) | "
        + " | ".join([kinematics(off, "own")] + [kinematics(on, c) for c in _CALLS])
        + " |",
        f"| paths heard | {paths.get('own', 0):,.0f} | {paths.get('own', 0):,.0f} | "
        f"{paths.get('previous', 0):,.0f} | {paths.get('next', 0):,.0f} |",
        row("render (its own and the calls' echoes in one pass), noise", "render", ("own",)),
        row("render apart (the calls' direct paths)", "render apart", ("own",)),
        row("LiDAR scan", "lidar", ("own",)),
        f"| the firing | {off.get(('own', 'firing'), 0.0):.0f} "
        f"| {on.get(('own', 'firing'), 0.0):.0f} | | |",
    ]
    return lines


def _earlier_calls_error(on, later, off) -> tuple[float, float]:
    """The largest energy (dB) over :data:`FIRINGS` of the recordings with the earlier
    calls left out less those with every call heard, re the recording and re its
    crosstalk (the recording less the one without crosstalk)."""
    worst = [-np.inf, -np.inf]
    for i in FIRINGS:
        every = on.simulate(i).samples
        diff = np.sum((later.simulate(i).samples - every) ** 2)
        ref = (np.sum(every**2), np.sum((every - off.simulate(i).samples) ** 2))
        for k in (0, 1):
            worst[k] = max(worst[k], 10 * np.log10(max(diff, 1e-300) / ref[k]))
    return worst[0], worst[1]


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
    t_shared, t_own = _paired(lambda: _firings(on), lambda: _unshared(on))
    # each sensor's measurement (its recording: its own call and the calls it hears)
    # computed on its own, against the rig's
    t_rig, own_runs = _paired(lambda: _firings(on), lambda: _alone(scene))
    t_apart = [a for a, _ in own_runs]
    prep_apart = np.median([p for _, p in own_runs]) / len(FIRINGS)
    apart = np.median(np.divide(t_rig, t_apart))
    scaling = _scaling(scene, on)
    # as a user runs them (their threads, wall time): the rig's run (the LiDAR's scans
    # of the body's poses too), crosstalk on and off, against one sonar alone
    user, user_off = RigSimulator(scene), RigSimulator(quiet)
    alone = Simulator(sonar_scene(scene, scene.rig.sonars[0].name))
    poses = list(range(FIRINGS[0] // n, FIRINGS[0] // n + len(FIRINGS)))
    _wall_rig(user), _wall_rig(user_off), _wall_alone(alone, poses)  # warm
    w_rig, w_alone = _paired(lambda: _wall_rig(user), lambda: _wall_alone(alone, poses))
    w_off, w_alone2 = _paired(lambda: _wall_rig(user_off), lambda: _wall_alone(alone, poses))
    w_ratio = np.median(np.divide(w_rig, w_alone))
    w_ratio_off = np.median(np.divide(w_off, w_alone2))
    # the approximation: the calls emitted before a recording's emission left out
    later = RigSimulator(
        dataclasses.replace(scene, rig=dataclasses.replace(scene.rig, earlier_calls=False)),
        threads=1,
    )
    _firings(later)
    t_later, t_off2 = _paired(lambda: _firings(later), lambda: _firings(off))
    later_ratio = np.median(np.divide(t_later, t_off2))
    error = _earlier_calls_error(on, later, off)
    firing = np.median(np.divide(t_on, t_off))
    sharing = np.median(np.divide(t_shared, t_own))
    heard = [len(on.simulate(i).metadata["crosstalk"]) for i in FIRINGS]
    cast_own, cast_shared = _rays_cast(on, 0), _rays_cast(on, 8)
    split_on, split_off, paths = _split(on, off)
    per = len(FIRINGS) / 1e3  # ms per firing
    ms_on, ms_off = np.median(t_on) / per, np.median(t_off) / per
    crosstalk = {c: split_on.get((c, "call heard"), 0.0) for c in ("previous", "next")}
    shot = sum(split_on.get((c, "rays shot"), 0.0) for c in ("previous", "next"))
    render = split_on.get(("own", "render"), 0.0) - split_off.get(("own", "render"), 0.0)
    render += split_on.get(("own", "render apart"), 0.0)
    more = split_on.get(("own", "firing"), 0.0) - split_off.get(("own", "firing"), 0.0)
    return "\n".join(
        [
            "## Rig: four uRTIS on one body, the corridor drive, round robin at 10 Hz each",
            "",
            f"`scenes/corridor_rig.toml` ({len(on.measurements)} firings), firings "
            f"{FIRINGS[0]}-{FIRINGS[-1]} (two rounds of the {n} sonars), every trace "
            f"paid, {REPEAT} paired, alternating runs in one process, medians.  The "
            "firings one by one on one thread, CPU time: one sonar's measurement is a "
            "firing of the rig with crosstalk off (its own call, its LiDAR scan).  As a "
            "user runs them, with their threads, wall time: the rig's run of those "
            "firings against one sonar alone (its scene without the rig) simulating as "
            "many poses of its drive.",
            "",
            "| what | time |",
            "|---|---|",
            f"| preparing the rig (its firings' poses, one world, the {n} sonars' "
            f"simulators) | {prep_rig:.2f} s |",
            f"| preparing one sonar's simulator alone (its own world) | {prep_one:.2f} s |",
            f"| a firing, crosstalk off (= one sonar's measurement) | {ms_off:.0f} ms |",
            f"| a firing, crosstalk on ({np.mean(heard):.1f} other firings heard) "
            f"| {ms_on:.0f} ms |",
            f"| a firing with crosstalk, each trace shooting its own rays "
            f"| {np.median(t_own) / per:.0f} ms |",
            f"| a firing with crosstalk / one sonar's measurement (paired) | {firing:.2f}x |",
            f"| a firing with crosstalk, the rays shared / each trace's own (paired) "
            f"| {sharing:.2f}x |",
            f"| rays cast per firing (every stage's and the LiDAR's), each trace's own "
            f"rays -> shared | {cast_own:,.0f} -> {cast_shared:,.0f} |",
            "| one sensor's measurement computed on its own: a firing's recording (its "
            "own call and the calls it hears) from a simulator of its own (its world "
            f"prepared apart, {prep_apart:.2f} s each) | {np.median(t_apart) / per:.0f} ms |",
            "| **a firing of the rig / one sensor's measurement computed on its own "
            f"(paired)** | **{apart:.2f}x** |",
            "| as a user runs them, wall time: one sonar alone on its drive (its scene "
            "without the rig, `Simulator.run`: its poses in two processes, this one "
            f"and a forked worker), per measurement | {np.median(w_alone) / per:.0f} ms |",
            "| as a user runs them, wall time: the rig's run (`RigSimulator.run`: its "
            "firings in two processes; the LiDAR's scans of the body's "
            f"poses), per firing | {np.median(w_rig) / per:.0f} ms |",
            f"| the same, crosstalk off | {np.median(w_off) / per:.0f} ms |",
            "| the rig's run / (N x one sonar alone), wall time (paired): crosstalk on "
            f"/ off | {w_ratio:.2f}x / {w_ratio_off:.2f}x |",
            "| a firing with crosstalk, the earlier calls left out (`earlier_calls = "
            f"false`, an approximation) / one sonar's measurement (paired) "
            f"| {later_ratio:.2f}x |",
            "| its error: the recordings less those with every call heard, re the "
            f"recording / re the crosstalk alone (the worst firing) | {error[0]:.0f} dB / "
            f"{error[1]:.0f} dB |",
            "",
            "A rig of N sonars, per firing: the bundled rig's sonar on N mounts of its "
            "body (its corners, then the middles of its sides), firing round robin "
            f"{INTERVAL_S * 1e3:.0f} ms apart (each sonar at 1 / (N x "
            f"{INTERVAL_S * 1e3:.0f} ms)), crosstalk on; CPU time of firings "
            f"{FIRINGS[0]}-{FIRINGS[-1]} on one thread, {REPEAT} runs paired with the "
            "bundled rig's (4 sonars at 10 Hz).  A rig of one hears its own earlier "
            "and later calls.",
            "",
            "| sonars | each fires at | calls heard per firing | a firing "
            "| re the bundled rig (paired) |",
            "|---|---|---|---|---|",
            *scaling,
            "",
            "Where a firing's time goes: CPU ms per firing, each part timed as the "
            "firings run (its methods and the tracer's stages wrapped; the median of 5 "
            "alternating runs with crosstalk on and off).  Own call: the sonar's own "
            "call (its trace, its kinematics with the ground truth's fields of what "
            "the sensor sees); previous call heard: the call of the sonar that fired "
            "25 ms before, whose paths long enough reach the window; next call heard: "
            "the call of the sonar that fires 25 ms into the window, traced as far as "
            "it can be heard.  The stages are parts of the trace; the rays shot are "
            'part of "rays and scattering" (shot once per call, by the first trace '
            "that asks for them).",
            "",
            *_split_table(split_on, split_off, paths),
            "",
            f"Without crosstalk a rig of {n} sonars costs {n} measurements per round and "
            "one world (the rig's preparation is mostly its firings' poses, 2 ms each).  "
            "Each firing heard by another sonar adds a bistatic trace (the emitter's "
            "paths to that sonar's microphones), their kinematics and their render: "
            f"here {crosstalk['previous']:.0f} ms for the call heard before the window, "
            f"{crosstalk['next']:.0f} ms for the call heard during it, and "
            f"{render:.0f} ms more render, of the {more:.0f} ms a firing with "
            "crosstalk costs more.  What the traces share: a call's rays are shot once "
            "for the three sonars that trace it (its own, and the two whose windows it "
            "reaches; `acousim.trace.rays.emission`: the batches followed to the "
            "longest path, cut exactly to each trace's budget, the same paths byte for "
            f"byte; {shot:.1f} ms of the crosstalk's traces, the call heard before the "
            "window asking for more batches than its own trace: its automatic budget "
            "watches a longer tail converge).  What they leave out, the recordings "
            "unchanged byte for byte: a call emitted during the window is traced only as "
            "far as it can be heard (the specular sequences out of reach take no "
            "work); of a call emitted before it, the paths too short to reach the "
            "window go no further than the trace, and its diffraction leaves out the "
            "edges and pairs of edges whose every path is too short and whose bound is "
            "under the strongest echo found before it, and, of the other pairs under "
            "that echo, the bins of paths too short (the same paths reach the "
            "window).  What is left is receiver-dependent by nature: all of the two "
            f"crosstalk columns but the rays shot ({shot:.1f} of "
            f"{sum(crosstalk.values()):.0f} ms) depends on where the hearing "
            "microphones are: the specular points (validated from the receiver back: "
            "the strongest echo, which sets the energy floor, is known only once the "
            "sequences too short to be heard are validated too), the glints (the "
            "specular points of the ceiling's pipes, per emitter and receiver), the "
            "diffraction and the scattering towards the receiver (its clusters are "
            "anchored at each group's nearest contribution and the automatic budget "
            "watches the whole tail converge: the short contributions cannot be left "
            "out without moving the others), then the crosstalk's paths themselves "
            f"({paths.get('previous', 0) + paths.get('next', 0):,.0f} a firing against "
            f"the sonar's own {paths.get('own', 0):,.0f}: their kinematics, and their "
            "render, which joins the sonar's own pass: one set of FFTs per microphone, "
            "its cost growing with the paths).  So a call heard costs most of a "
            f"measurement: a recording with crosstalk costs {firing:.2f}x one without.  "
            "A sensor's measurement in a rig is its recording, its own call and the "
            "calls it hears: the rig computes each for "
            f"{apart:.2f}x what it costs computed on its own (the world prepared once, "
            "each call's rays shot once for every sonar that hears it), and a firing "
            "costs the same whatever the number of sonars (the table of N above: what "
            "a firing costs follows the calls heard in its window, not the sonars on "
            f"the body), so a rig of N sonars costs at most N of them per round.  "
            "Leaving out the calls emitted before each recording's emission "
            "(`[rig] earlier_calls = false`, an approximation: the previous call's "
            f"column) a firing costs {later_ratio:.2f}x one sonar's measurement, the "
            f"recordings' change at most {error[0]:.0f} dB re the recording "
            f"({error[1]:.0f} dB re the crosstalk alone) on this drive, where what "
            "reaches the window of a call emitted 25 ms before is its weak tail (its "
            "paths longer than about 7.6 m: diffraction and the diffuse tail); in a small "
            "reverberant room its later echoes can be much stronger.",
        ]
    )


if __name__ == "__main__":  # pragma: no cover
    print(run())
