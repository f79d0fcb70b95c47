"""Edge to edge (second-order diffraction) in the diffraction section: the element
step against error and time, what the per-pair selection skips in the corridor,
and the cost of diffraction at its defaults (corridor, wall, sphere) against
diffraction off, measured in turn in one process."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import trimesh

from acousim.scene import load_scene
from acousim.scene.model import Diffraction
from acousim.simulator import Simulator
from acousim.trace import KIND
from acousim.trace.diffraction.edge_to_edge import _selected, candidate_pairs
from acousim.trace.diffraction.pairs import pair_elements
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions
from acousim.trace.world.edges import find_edges
from acousim.trace.world.embree import RayCaster
from tests.acousim.trace.diffraction.test_edge_to_edge import plane_ids

SCENES = Path(__file__).resolve().parent.parent / "scenes"
POSES = list(range(10, 30))  # two seconds of the drive, as in the corridor section
C = 343.0


def _box_case():
    """The reciprocity test's turned box (6 x 5 x 4 cm at 0.5 m), bistatic."""
    box = trimesh.creation.box([0.06, 0.05, 0.04])
    box.apply_transform(trimesh.transformations.rotation_matrix(0.5, [0.3, 0.2, 1]))
    box.apply_translation([0.5, 0.02, 0])
    s, r = np.array([0, 0.05, 0.02]), np.array([0.1, -0.2, 0.1])
    geometry = DiffractingGeometry(
        find_edges(box), np.ones(len(box.faces)), face_plane=plane_ids(box)
    )
    ctx = StageContext(
        geometry,
        RayCaster(box.triangles, 1),
        s,
        r,
        DiffractionOptions(8.0, settings=Diffraction(order=2)),
    )
    return candidate_pairs(ctx)[0], s, r


def step_table() -> list[str]:
    """Edge-to-edge field of the box against the same at a 0.05 mm step: elements,
    time (compiled kernel, best of 3), worst error over 13 frequencies of 20-80 kHz
    relative to the field's peak."""
    rows, s, r = _box_case()
    k = 2 * np.pi * np.linspace(20e3, 80e3, 13) / C

    def field(step, use_kernel=True):
        t0 = time.perf_counter()
        el = pair_elements(rows, s, r, step_m=step, bin_m=step / 4, use_kernel=use_kernel)
        dt = time.perf_counter() - t0
        h = (el.amplitude * np.exp(-1j * k[:, None] * (el.first_leg_m + el.second_leg_m))).sum(1)
        return h, dt

    ref, _ = field(0.05e-3)
    out = []
    for step in (0.25e-3, 0.5e-3, 1e-3, 1.7e-3, 2e-3, 4e-3):
        h, _ = field(step)
        t = min(field(step)[1] for _ in range(3))
        t_np = min(field(step, False)[1] for _ in range(2))
        err = np.max(np.abs(h - ref)) / np.max(np.abs(ref))
        out.append(
            f"| {step * 1e3:g} | {t * 1e3:.1f} | {t_np * 1e3:.0f} | {100 * err:.1f} % "
            f"({20 * np.log10(1 + err):.2f} dB) |"
        )
    return out


def _corridor(**settings) -> Simulator:
    sc = load_scene(SCENES / "corridor.toml")
    sim = Simulator(
        dataclasses.replace(sc, simulation=dataclasses.replace(sc.simulation, **settings))
    )
    sim.run([0])
    return sim


def _paired(sims: dict[str, Simulator], poses: list[int], rounds: int) -> dict[str, np.ndarray]:
    """Seconds per measurement of each simulator, measured in turn (round by round,
    the tracer's cache emptied each time)."""
    times = {k: [] for k in sims}
    for _ in range(rounds):
        for name, sim in sims.items():
            sim.tracer.forget()
            t0 = time.perf_counter()
            sim.run(poses)
            times[name].append((time.perf_counter() - t0) / len(poses))
    return {k: np.array(v) for k, v in times.items()}


def corridor_table(rounds: int = 5) -> list[str]:
    """The corridor drive (as in the file: moving) and frozen, with diffraction off,
    first order only, at its defaults, and with reflections too."""
    out = []
    for frozen in (False, True):
        variants = {
            "off": dict(diffraction=Diffraction(enabled=False)),
            "first order only (`diffraction.order = 1`)": dict(diffraction=Diffraction(order=1)),
            "defaults (edge to edge where it matters)": {},
            "defaults + `diffraction.reflections`": dict(diffraction=Diffraction(reflections=True)),
        }
        sims = {}
        for name, kw in variants.items():
            sim = _corridor(**kw)
            if frozen:
                sc = sim.scene
                sim = Simulator(
                    dataclasses.replace(sc, sensor=dataclasses.replace(sc.sensor, motion=None))
                )
                sim.run([0])
            sims[name] = sim
        t = _paired(sims, POSES, rounds)
        for name, sim in sims.items():
            ratio = np.median(t[name] / t["off"])
            paths = [sim.paths(sim.scene.sensor.poses[i]) for i in POSES[::4]]
            d = np.mean([np.sum(p.kind == KIND["diffraction"]) for p in paths])
            d2 = np.mean([np.sum((p.kind == KIND["diffraction"]) & (p.order == 2)) for p in paths])
            out.append(
                f"| {'frozen' if frozen else 'moving (the file)'} | {name} | "
                f"{np.median(t[name]) * 1e3:.0f} | {1 / np.median(t[name]):.1f} | {ratio:.2f} | "
                f"{d:.0f} ({d2:.0f}) |"
            )
    return out


def skipped_table(poses=(5, 15, 25, 40)) -> list[str]:
    """Per corridor pose: the edge pairs that share a plane and are seen, those the
    selection keeps, those with a path at or above the floor when every pair is
    integrated, and the largest path of a skipped pair relative to the floor."""
    sim = _corridor()
    tracer = sim.tracer
    cap = {}
    import acousim.trace.diffraction.stage as stage

    original = stage.edge_to_edge

    def spy(ctx, floor):
        cap["ctx"], cap["floor"] = ctx, floor
        return original(ctx, floor)

    out = []
    stage.edge_to_edge = spy
    try:
        for i in poses:
            tracer.forget()
            tracer.trace(sim.scene.sensor.poses[i])
            ctx, floor = cap["ctx"], cap["floor"]
            rows, _, _ = candidate_pairs(ctx)
            opt = ctx.options
            el = pair_elements(
                rows, ctx.emitter, ctx.receiver, step_m=opt.pair_step_m, bin_m=opt.step_m / 4,
                max_path_m=opt.max_path_m,
            )  # fmt: skip
            largest = np.zeros(len(rows))
            np.maximum.at(largest, el.pair, np.abs(el.amplitude))
            keep, _, _ = _selected(ctx, rows, floor)
            skipped = np.setdiff1d(np.arange(len(rows)), keep)
            worst = largest[skipped].max() / floor if skipped.size else 0.0
            out.append(
                f"| {i} | {len(rows)} | {keep.size} | {(largest >= floor).sum()} | "
                f"{20 * np.log10(max(worst, 1e-30)):+.1f} dB |"
            )
    finally:
        stage.edge_to_edge = original
    return out


def scenes_table(rounds: int = 7) -> list[str]:
    """Bundled wall and sphere: diffraction off (the old default) against the new
    defaults, measured in turn."""
    out = []
    for name in ("wall", "sphere"):
        sc = load_scene(SCENES / f"{name}.toml")
        sims = {}
        for label, on in (("off", False), ("defaults", True)):
            s = Simulator(
                dataclasses.replace(
                    sc, simulation=dataclasses.replace(sc.simulation, diffraction=on)
                )
            )
            s.run([0])
            sims[label] = s
        poses = list(range(len(sc.sensor.poses))) * max(1, 10 // len(sc.sensor.poses))
        t = _paired(sims, poses, rounds)
        n = np.sum(sims["defaults"].paths(sc.sensor.poses[0]).kind == KIND["diffraction"])
        edges = len(sims["defaults"].tracer.edges.edges) if sims["defaults"].tracer.edges else 0
        out.append(
            f"| {name} | {edges} | {np.median(t['off']) * 1e3:.1f} | "
            f"{np.median(t['defaults']) * 1e3:.1f} | "
            f"{np.median(t['defaults'] / t['off']):.2f} | {n} |"
        )
    return out
