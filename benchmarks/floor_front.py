"""The energy floor's front on the corridor drive: per rule ("path", "sum") and level,
the paths per pose, the CPU time per measurement, the waveform residual (noise off,
the direct path left out of both: dB re the reference's echoes) against the same
settings with the floor at the ``reference`` preset's (the floor's own error) and
against the ``reference`` preset (every knob at its most accurate), and the DAS
image peaks against both (:func:`benchmarks.peaks_check.compare_peaks`: the scene's
noise and direct path; lost and added: those whose energy is gone or new;
``preset_peaks``: [peaks, lost, added, largest level change in dB] against the
``reference`` preset).

    python -m benchmarks.floor_front [--base '{"quality": "fast"}'] [--poses 5,10,...]
        [--points path,-80 sum,-60 ...] [--rounds 3]

A point "sum30,L" is the rule "sum" with its early pruning's count bound replaced by
1000 candidates (an early floor 33 dB under the final one instead of the provable
bound's): what a tighter bound would buy.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

import acousim.trace.tracer as tracer_module
from acousim.scene import load_scene
from acousim.simulator import Simulator
from benchmarks.peaks_check import compare_peaks
from benchmarks.timing import cpu_seconds

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"
POINTS = ("path,-80", "path,-70", "path,-60", "sum,-60", "sum,-50", "sum,-40", "sum,-30")


def _simulator(settings: dict, **sensor) -> Simulator:
    scene = load_scene(SCENE)
    sim = dataclasses.replace(scene.simulation, **settings)
    return Simulator(
        dataclasses.replace(
            scene, simulation=sim, sensor=dataclasses.replace(scene.sensor, **sensor)
        )
    )


def _cpu_ms(sim: Simulator, poses: list[int], rounds: int) -> float:
    """Median over `rounds` of the CPU ms per measurement of `sim.run(poses)`, every
    trace paid."""
    sim.run(poses[:1])
    out = []
    for _ in range(rounds):
        sim.tracer.forget()
        t = cpu_seconds()
        sim.run(poses)
        out.append((cpu_seconds() - t) / len(poses) * 1e3)
    return float(np.median(out))


def measure(point: str, base: dict, poses: list[int], rounds: int, ref) -> dict:
    """One point of the front: its numbers against `ref` (the reference's echoes and
    noisy recordings)."""
    rule, level = point.split(",")
    settings = {
        **base,
        "energy_floor_db": float(level),
        "energy_floor_rule": "sum" if rule.startswith("sum") else rule,
    }
    bound = tracer_module.diffraction_candidates
    if rule == "sum30":
        tracer_module.diffraction_candidates = lambda *a: 1000
    try:
        quiet = _simulator({**settings, "snr_db": np.inf}, direct_path=False)
        ms = _cpu_ms(quiet, poses, rounds)
        paths = [len(quiet.tracer.trace(quiet.scene.sensor.poses[i])) for i in poses]
        echoes = quiet.run(poses)
        noisy = _simulator(settings).run(poses)
    finally:
        tracer_module.diffraction_candidates = bound
    ref_echoes, ref_noisy, preset_echoes, preset_noisy = ref
    peaks = [compare_peaks(r, n) for r, n in zip(ref_noisy, noisy)]
    preset = [compare_peaks(r, n) for r, n in zip(preset_noisy, noisy)]
    return {
        "point": point,
        "paths": [min(paths), max(paths)],
        "cpu_ms": round(ms, 1),
        "residual_db": _residual_db(echoes, ref_echoes),
        "residual_preset_db": _residual_db(echoes, preset_echoes),
        "peaks": sum(p["peaks"] for p in peaks),
        "lost": sum(p["lost_energy"] for p in peaks),
        "added": sum(p["added_energy"] for p in peaks),
        "level_max_db": round(max(p["level_max_db"] for p in peaks), 2),
        "preset_peaks": _peak_counts(preset),
    }


def _peak_counts(peaks: list[dict]) -> list:
    """[peaks, lost, added, largest level change (dB)] summed over the poses."""
    return [
        sum(p["peaks"] for p in peaks),
        sum(p["lost_energy"] for p in peaks),
        sum(p["added_energy"] for p in peaks),
        round(max(p["level_max_db"] for p in peaks), 2),
    ]


def _residual_db(recs, refs) -> float:
    """The residual of `recs` against `refs` (all microphones), dB re `refs`' energy."""
    num = sum(np.sum((a.samples - b.samples) ** 2) for a, b in zip(recs, refs))
    den = sum(np.sum(b.samples**2) for b in refs)
    return round(float(10 * np.log10(num / den)), 1)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="{}", help="JSON of the other settings of every point")
    ap.add_argument("--poses", default="5,10,15,20,25,30,35,40")
    ap.add_argument("--points", nargs="*", default=list(POINTS))
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args(argv)
    poses = [int(x) for x in a.poses.split(",")]
    base = json.loads(a.base)
    floor = {**base, "energy_floor_db": -120.0, "energy_floor_rule": "path"}
    ref = (
        _simulator({**floor, "snr_db": np.inf}, direct_path=False).run(poses),
        _simulator(floor).run(poses),
        _simulator({"quality": "reference", "snr_db": np.inf}, direct_path=False).run(poses),
        _simulator({"quality": "reference"}).run(poses),
    )
    for point in a.points:
        print(json.dumps(measure(point, base, poses, a.rounds, ref)), flush=True)


if __name__ == "__main__":
    main()
