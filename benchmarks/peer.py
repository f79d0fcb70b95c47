"""Beside a peer: the bundled shoebox against pyroomacoustics' image-source model.

The same room (scenes/shoebox.toml: 4.2 x 3.5 x 2.6 m, walls of pressure reflection
0.9), the same array (uRTIS, 30 microphones; an 8 x 8 and a 32 x 32 array at 5 mm
for 64 and 1024), the same call (the default 25-50 kHz chirp at 450 kHz) and the
same speed of sound; air absorption off on both sides, and our rays (were any
needed) over the whole sphere, as for pyroomacoustics' omnidirectional source.
Each call is timed as a user pays for it, from the scene (or the room) to the
microphone signals: our `Simulator(scene)` (the world prepared) and
`simulate_pose` (trace and render) against pyroomacoustics' room, source,
microphones and `simulate()` (image sources, impulse responses, convolution).
Paired: the two alternate, the ratio is the median of the pairs' ratios.  Also the
same job in a fresh process each (:func:`_fresh`): the interpreter, the imports,
numba's cached kernels loaded, the scene file read, the first build and the signals.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import processing as P
from acousim.scene import load_scene
from acousim.simulator import Simulator

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "shoebox.toml"
ROOM = np.array([[-1.0, 3.2], [-1.6, 1.9], [-1.1, 1.5]])  # scenes/build_scenes.py
PAIRS = 9
FRESH_PAIRS = 5

# a fresh process's job, ours: the scene file read, the simulator built, the signals
_OURS = """
import dataclasses, sys
from acousim.scene import load_scene
from acousim.simulator import Simulator
sc = load_scene(sys.argv[1])
sim = dataclasses.replace(
    sc.simulation, bounces=int(sys.argv[2]), absorption=False, beam_deg=180.0
)
sc = dataclasses.replace(sc, simulation=sim)
Simulator(sc).simulate_pose(sc.sensor.poses[0])
"""
# and pyroomacoustics': the room, the source, the microphones, simulate()
_THEIRS = """
import sys
import numpy as np
import pyroomacoustics as pra
d = np.load(sys.argv[1])
pra.constants.set("c", float(d["c"]))
room = pra.ShoeBox(
    d["size"], fs=int(d["fs"]), max_order=int(d["order"]),
    materials=pra.Material(float(d["absorption"])), air_absorption=False, ray_tracing=False,
)
room.add_source(d["source"], signal=d["signal"])
room.add_microphone_array(d["mics"])
room.simulate()
"""


def _scene(order: int, array: P.Array):
    sc = load_scene(SCENE)
    sim = dataclasses.replace(sc.simulation, bounces=order, absorption=False, beam_deg=180.0)
    return dataclasses.replace(
        sc, simulation=sim, sensor=dataclasses.replace(sc.sensor, array=array)
    )


def _pra_call(pra, scene, order: int, mics: np.ndarray, emitter: np.ndarray) -> np.ndarray:
    """pyroomacoustics' microphone signals (M, N) for the shoebox, the call emitted."""
    R = scene.materials["wall"].reflection
    room = pra.ShoeBox(
        ROOM[:, 1] - ROOM[:, 0],
        fs=int(scene.sensor.sample_rate_hz),
        max_order=order,
        materials=pra.Material(1 - R**2),  # energy absorption: amplitude R per bounce
        air_absorption=False,
        ray_tracing=False,
    )
    room.add_source(emitter - ROOM[:, 0], signal=scene.sensor.call.sampled(room.fs))
    room.add_microphone_array((mics - ROOM[:, 0]).T)
    room.simulate()
    return room.mic_array.signals


def _compare(ours: P.Recording, theirs: np.ndarray, first_echo_s: float, pra) -> tuple:
    """Correlation over every channel from the first echo on, and the least-squares
    gain of ours over theirs, the samples aligned by pyroomacoustics' known delay
    (half its fractional-delay filter)."""
    shift = ours.emission_index - pra.constants.get("frac_delay_length") // 2
    start = ours.emission_index + int(first_echo_s * ours.sample_rate_hz) - 40
    n = min(ours.samples.shape[1], theirs.shape[1] + shift) - start
    a = ours.samples[:, start : start + n]
    b = theirs[:, start - shift : start - shift + n]
    corr = float(np.sum(a * b) / np.sqrt(np.sum(a * a) * np.sum(b * b)))
    return corr, float(np.sum(a * b) / np.sum(b * b))


def _row(pra, order: int, array: P.Array) -> str:
    scene = _scene(order, array)
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    mics = pose.to_world(array.positions_m)
    emitter = pose.to_world(array.emitter_m)
    ours = sim.simulate_pose(pose)
    theirs = _pra_call(pra, scene, order, mics, emitter)
    paths = sim.paths(pose)
    first = float(np.min(paths.first_leg_m + np.linalg.norm(paths.anchor_m - mics.mean(0), axis=1)))
    corr, level = _compare(ours, theirs, first / sim.c, pra)
    t_ours, t_prep, t_pra = [], [], []
    for _ in range(PAIRS):
        del sim  # one world held, as in use
        t = time.perf_counter()
        sim = Simulator(scene)
        t_prep.append(time.perf_counter() - t)
        sim.simulate_pose(pose)
        t_ours.append(time.perf_counter() - t)
        t = time.perf_counter()
        _pra_call(pra, scene, order, mics, emitter)
        t_pra.append(time.perf_counter() - t)
    ratio = np.median(np.array(t_pra) / np.array(t_ours))
    return (
        f"| {order} | {array.n_mics} | {len(paths)} | {ours.metadata['rays']} | "
        f"{np.median(t_ours) * 1e3:.1f} | {np.median(t_pra) * 1e3:.1f} | **{ratio:.2f}x** | "
        f"{corr:.7f} | {(level - 1) * 100:+.3f} % | {np.median(t_prep) * 1e3:.1f} |"
    )


def _fresh(pra, order: int) -> str:
    """A row of the fresh-process table: the whole job in a new interpreter each,
    FRESH_PAIRS alternating pairs (wall time of each process, the same interpreter
    start-up on both sides)."""
    scene = _scene(order, P.preset("urtis_v1"))
    array, pose = scene.sensor.array, scene.sensor.poses[0]
    R = scene.materials["wall"].reflection
    fs = int(scene.sensor.sample_rate_hz)
    with tempfile.TemporaryDirectory() as tmp:
        room = Path(tmp) / "room.npz"
        np.savez(
            room,
            c=scene.environment.speed_of_sound_m_s,
            size=ROOM[:, 1] - ROOM[:, 0],
            fs=fs,
            order=order,
            absorption=1 - R**2,
            source=pose.to_world(array.emitter_m) - ROOM[:, 0],
            signal=scene.sensor.call.sampled(fs),
            mics=(pose.to_world(array.positions_m) - ROOM[:, 0]).T,
        )
        ours = [sys.executable, "-c", _OURS, str(SCENE), str(order)]
        theirs = [sys.executable, "-c", _THEIRS, str(room)]
        t_ours, t_pra = [], []
        for _ in range(FRESH_PAIRS + 1):  # the first pair warms the file cache
            for cmd, times in ((ours, t_ours), (theirs, t_pra)):
                t = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True)
                times.append(time.perf_counter() - t)
    a, b = np.array(t_ours[1:]), np.array(t_pra[1:])
    return (
        f"| {order} | {array.n_mics} | {np.median(a):.2f} | {np.median(b):.2f} | "
        f"**{np.median(b / a):.2f}x** |"
    )


def run() -> str:
    import pyroomacoustics as pra

    c_before = pra.constants.get("c")
    c = load_scene(SCENE).environment.speed_of_sound_m_s
    pra.constants.set("c", c)  # its speed of sound, ours; restored below
    try:
        arrays = [P.preset("urtis_v1"), P.ura(8, 8, 0.005), P.ura(32, 32, 0.005)]
        rows = [_row(pra, order, a) for order in (2, 3) for a in arrays]
    finally:
        pra.constants.set("c", c_before)
    fresh = [_fresh(pra, order) for order in (2, 3)]
    return "\n".join(_table(pra, c, rows, fresh))


def _table(pra, c: float, rows: list[str], fresh: list[str]) -> list[str]:
    return [
        f"## Beside pyroomacoustics {pra.__version__}: the shoebox, image sources, orders 2 and 3",
        "",
        "The bundled shoebox at its defaults (the automatic budget: every plane "
        "sequence checked as an image source, no rays, as nothing in it scatters), air "
        f"absorption off, c = {c:.2f} m/s on both sides, no noise on either (the scene's "
        "SNR is infinite), the default 25-50 kHz call at "
        "450 kHz, the sensor at the room's origin.  Time from the scene to the "
        "microphone signals, the whole job a user pays for (ours: `Simulator(scene)`, "
        "whose part is in the last column, then `simulate_pose`: trace and render, "
        "Embree and the FFTs on two threads, as by default; "
        "pyroomacoustics: room, source, microphones and `simulate()`), after a "
        f"warm-up, medians of {PAIRS} alternating pairs; speed-up: the "
        "median of the pairs' ratios (theirs over ours).  Correlation: over every "
        "channel from the first echo on (our direct path is off; theirs ends before "
        "the first echo); level: the least-squares gain of ours over theirs, less "
        "one (both spread as 1 / r).  Target: at least 3x at orders 2 and 3, "
        "correlation at least 0.99999.",
        "",
        "| order | microphones | paths | rays | ours (ms) | pyroomacoustics (ms) | "
        "speed-up | correlation | level | of ours, `Simulator(scene)` (ms) |",
        "|---|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        "In a fresh process each (30 microphones): the wall time of a new interpreter "
        "that does the job once, imports included (ours: `acousim`, numba's compiled "
        "kernels loaded from its cache, the scene file read, `Simulator(scene)` and "
        "`simulate_pose`; pyroomacoustics: its import, the room and `simulate()`, the "
        f"call and microphones read from a file), {FRESH_PAIRS} alternating pairs after "
        "one that warms the file cache; speed-up: the median of the pairs' ratios.  A "
        "one-off job is paid mostly in imports.",
        "",
        "| order | microphones | ours (s) | pyroomacoustics (s) | speed-up |",
        "|---|---|---|---|---|",
        *fresh,
        "",
    ]
