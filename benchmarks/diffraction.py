"""Edge diffraction: the edge-element step against error and time, and the corridor
with diffraction on."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from acousim.scene import load_scene
from acousim.simulator import Simulator
from acousim.trace import KIND
from acousim.trace.btm import DEFAULT_STEP_M, edge_elements

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"
POSES = list(range(10, 30))  # two seconds of the drive, as in the corridor section
STEPS_M = [0.25e-3, 0.5e-3, 1e-3, 2e-3, 4e-3]
FREQS = np.linspace(20e3, 85e3, 14)
C = 343.0


def _cyl(r, th, z):
    return np.array([r * np.cos(th), r * np.sin(th), z])


def _screen(step: float, th_r: float) -> tuple[np.ndarray, int, float]:
    """Diffracted spectrum (FREQS) of a thin screen: source 0.15 m from the edge at
    60 deg, receiver 0.10 m from it, 5 cm along it; elements; seconds per edge."""
    k = 2 * np.pi * FREQS / C
    t0 = time.perf_counter()
    el = edge_elements(
        np.array([0.0, 0, -10]),
        np.array([0.0, 0, 10]),
        np.array([1.0, 0, 0]),
        np.array([0.0, 1, 0]),
        2 * np.pi,
        _cyl(0.15, np.deg2rad(60), 0),
        _cyl(0.10, th_r, 0.05),
        step,
    )
    dt = time.perf_counter() - t0
    path = el.first_leg_m + el.second_leg_m
    h = (el.amplitude[None, :] * np.exp(-1j * k[:, None] * path[None, :])).sum(axis=1)
    return h, len(el), dt


def _element_table() -> list[str]:
    angles = np.deg2rad([150.0, 120 + 1e-5, 240 + 1e-5, 300.0])  # lit, boundaries, shadow
    ref = [_screen(0.02e-3, a)[0] for a in angles]  # converged: 20 um steps
    incident = [
        1 / np.linalg.norm(_cyl(0.15, np.deg2rad(60), 0) - _cyl(0.1, a, 0.05)) for a in angles
    ]
    rows = []
    for step in STEPS_M:
        errs, n, times = [], [], []
        for a, r, inc in zip(angles, ref, incident):
            best = np.inf
            for _ in range(5):
                h, count, dt = _screen(step, a)
                best = min(best, dt)
            times.append(best)
            n.append(count)
            # error relative to the incident wave: what the step changes in the total
            errs.append(np.max(np.abs(h - r)) / inc)
        mark = " (default)" if step == DEFAULT_STEP_M else ""
        rows.append(
            f"| {step * 1e3:g}{mark} | {np.mean(n):.0f} | {np.mean(times) * 1e6:.0f} | "
            f"{20 * np.log10(max(errs)):.1f} |"
        )
    return rows


def _corridor(step: float | None, poses: list[int]) -> tuple[float, float]:
    sc = load_scene(SCENE)
    sim_settings = dataclasses.replace(
        sc.simulation, diffraction=step is not None, diffraction_step_m=step or DEFAULT_STEP_M
    )
    sim = Simulator(dataclasses.replace(sc, simulation=sim_settings))
    sim.run([0])
    per = np.inf
    for _ in range(3):  # best of 3: this shared machine's neighbours vary
        t0 = time.perf_counter()
        sim.run(poses)
        per = min(per, (time.perf_counter() - t0) / len(poses))
    n = np.mean(
        [np.sum(sim.paths(sim.scene.sensor.poses[i]).kind == KIND["diffraction"]) for i in poses]
    )
    return per, float(n)


def run(poses: list[int] | None = None) -> str:
    poses = POSES if poses is None else poses
    rows = []
    for step in (None, 4e-3, 2e-3, 1e-3):
        per, n = _corridor(step, poses)
        name = "off" if step is None else f"on, step {step * 1e3:g} mm"
        if step == DEFAULT_STEP_M:
            name += " (default step)"
        rows.append(f"| {name} | {per * 1e3:.0f} | {1 / per:.1f} | {n:.0f} |")
    return "\n".join(
        [
            "## Edge diffraction (BTM): element step, and the corridor with diffraction on",
            "",
            "Element step against error and time: a thin rigid screen (source 0.15 m from "
            "the edge, receiver 0.10 m, 5 cm along it; receiver lit, on the reflection and "
            "shadow boundaries and in the shadow), diffracted spectrum at 20-85 kHz "
            "against the same model converged (20 µm steps); error = worst difference over "
            "the four receivers and 14 frequencies, relative to the incident wave "
            "(against the exact wedge solution the converged model is within 0.03 dB: "
            "tests/test_diffraction.py). Time: one 20 m edge, best of 5.",
            "",
            "| step (mm) | elements per edge | µs per edge | worst error (dB re incident) |",
            "|---|---|---|---|",
            *_element_table(),
            "",
            f"Corridor at its default settings, `Simulator.run` over {len(poses)} poses (best "
            "of 3), with edge diffraction off and on (`simulation.diffraction`). "
            "Target: 15 measurements/s.",
            "",
            "| diffraction | ms per measurement | measurements/s | diffraction paths per pose |",
            "|---|---|---|---|",
            *rows,
            "",
        ]
    )
