"""How the simulator's cost scales: with the faces of a mesh, the microphones, the
range and the poses, preparation (the world, Embree's tree, the tables every pose
uses) and per-pose cost apart; and what the automatic ray budget does in each
bundled scene."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import trimesh

import processing as P
from acousim.scene import load_scene
from acousim.simulator import Simulator
from acousim.trace.rays import budget
from acousim.trace.tracer import Tracer

SCENES = Path(__file__).resolve().parent.parent / "scenes"
CORRIDOR = SCENES / "corridor.toml"
POSES = list(range(5, 60, 7))  # 8 poses along the drive
PREP_PAIRS = 5  # alternating pairs of builds, ours and embreex's, at every size


def _embree_build(triangles: np.ndarray) -> float:
    """embreex's own scene build on these triangles (float32, centred), to its first
    ray (Embree builds its tree then), seconds."""
    import embreex.mesh_construction as mc
    import embreex.rtcore_scene as rtcs

    t = time.perf_counter()
    corners = triangles.reshape(-1, 3)
    origin = (corners.min(axis=0) + corners.max(axis=0)) / 2
    scene = rtcs.EmbreeScene()
    _mesh = mc.TriangleMesh(scene, (triangles - origin).astype(np.float32))
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    return time.perf_counter() - t


def _trace_ms(tracer: Tracer, poses) -> float:
    tracer.forget()
    t = time.perf_counter()
    for p in poses:
        tracer.trace(p)
    return (time.perf_counter() - t) / len(poses) * 1e3


def _faces() -> list[str]:
    scene = load_scene(CORRIDOR)
    mesh = trimesh.load(SCENES / "meshes" / "corridor.stl", force="mesh", process=False)
    poses = [scene.sensor.poses[i] for i in POSES]
    base = Tracer(scene)
    base_ms = _trace_ms(base, poses)
    rows = []
    for _ in range(6):
        item = dataclasses.replace(scene.meshes[0], mesh=mesh)
        fine = dataclasses.replace(scene, meshes=(item,))
        prep, own = [], []
        for _ in range(PREP_PAIRS):  # alternating: ours, then embreex's own
            sim = tracer = None  # the last world let go first: one world held, as in use
            t = time.perf_counter()
            sim = Simulator(fine)  # what a user builds
            prep.append(time.perf_counter() - t)
            tracer = sim.tracer
            own.append(_embree_build(tracer.world.triangles))
        ratio_prep = np.median(np.array(prep) / np.array(own))
        pairs = [(_trace_ms(tracer, poses), _trace_ms(base, poses)) for _ in range(3)]
        per = np.median([a for a, _ in pairs])
        ratio_pose = np.median([a / b for a, b in pairs])
        w = tracer.world
        planes = len(np.unique(w.plane[~w.curved]))
        rows.append(
            f"| {w.n_faces} | {planes} | {w.area[w.curved].sum():.2f} | "
            f"{np.median(prep):.2f} | {np.median(own):.2f} | **{ratio_prep:.2f}x** | "
            f"{per:.1f} | **{ratio_pose:.2f}x** |"
        )
        mesh = mesh.subdivide()
    return [
        "### Faces: the corridor's mesh subdivided 0 to 5 times (the same geometry)",
        "",
        "Preparation: `Simulator(scene)`, what a user builds (merge the mesh, group its "
        "faces into planes and curved patches, corner normals, the diffracting edges, "
        "Embree's indexed mesh and tree, the tables every pose uses, the path "
        "response) against embreex's own scene "
        "build on the same triangles to its first ray, alternating, median of the "
        f"ratios ({PREP_PAIRS} pairs at every size; the previous world let go before "
        "each build).  Per pose: a trace (automatic budget) of 8 poses of the drive, "
        f"against the original mesh ({base_ms:.1f} ms), 3 alternating pairs.  Targets: "
        "preparation at most 2x embreex's build, a pose at most 2x one in the original.",
        "",
        "| faces | planes | curved area (m²) | prepare (s) | embreex build (s) | ratio | "
        "trace per pose (ms) | against the original |",
        "|---|---|---|---|---|---|---|---|",
        *rows,
        "",
    ]


def _measure(scene, poses) -> tuple[float, float, float, float]:
    """(ms per measurement, trace ms per pose, rays, paths) over `poses`, after one
    warm-up; every trace paid."""
    sim = Simulator(scene)
    sim.simulate_pose(poses[0])
    sim.tracer.forget()
    t = time.perf_counter()
    recs = [sim.simulate_pose(p) for p in poses]
    total = (time.perf_counter() - t) / len(poses)
    sim.tracer.forget()
    t = time.perf_counter()
    paths = [sim.paths(p) for p in poses]
    trace = (time.perf_counter() - t) / len(poses)
    rays = np.median([r.metadata["rays"] for r in recs])
    return total * 1e3, trace * 1e3, rays, np.mean([len(p) for p in paths])


def _mics_and_range() -> list[str]:
    scene = load_scene(CORRIDOR)
    poses = [scene.sensor.poses[i] for i in POSES[:5]]
    arrays = [
        P.ura(5, 5, 0.005),
        P.preset("urtis_v1"),
        P.ura(8, 8, 0.005),
        P.ura(16, 16, 0.005),
        P.ura(32, 32, 0.005),
    ]
    rows = []
    for a in arrays:
        sc = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, array=a))
        total, trace, rays, paths = _measure(sc, poses)
        rows.append(
            f"| {a.n_mics} microphones, 6 m | {total:.0f} | {trace:.0f} | {rays:.0f} | "
            f"{paths:.0f} |"
        )
    for r in (3.0, 12.0):
        sc = dataclasses.replace(
            scene, simulation=dataclasses.replace(scene.simulation, max_range_m=r)
        )
        total, trace, rays, paths = _measure(sc, poses)
        rows.append(
            f"| 30 microphones, {r:g} m | {total:.0f} | {trace:.0f} | {rays:.0f} | {paths:.0f} |"
        )
    return [
        "### Microphones and range: the corridor at its defaults",
        "",
        "Per measurement (`simulate_pose`: trace, echoes, render, noise; 5 poses of the "
        "drive, every trace paid) and the trace alone; rays: the automatic budget's "
        "median; paths per pose.  The trace does not depend on the microphones (it ends "
        "at the array's centre); the render grows with microphones times paths times "
        "samples.",
        "",
        "| case | ms per measurement | trace ms | rays | paths |",
        "|---|---|---|---|---|",
        *rows,
        "",
    ]


def _poses() -> list[str]:
    scene = load_scene(CORRIDOR)
    rows = []
    for n in (1, 10, 60):
        t = time.perf_counter()
        sim = Simulator(scene)
        prep = time.perf_counter() - t
        t = time.perf_counter()
        sim.run(list(range(n)))
        run = time.perf_counter() - t
        rows.append(f"| {n} | {prep:.2f} | {run:.2f} | {run / n * 1e3:.0f} |")
    return [
        "### Poses: the corridor drive",
        "",
        "`Simulator(scene)` (preparation, once) and `run()` over the first n poses (in "
        "two processes, this one and a forked worker, where they take half a second or "
        "more; else in threads, each traced while the one before renders).",
        "",
        "| poses | prepare (s) | run (s) | per pose (ms) |",
        "|---|---|---|---|",
        *rows,
        "",
    ]


def _scenes() -> list[str]:
    rows = []
    for name in ("corridor", "ertis_sample", "panel_wall", "shoebox", "sphere", "wall"):
        scene = load_scene(SCENES / f"{name}.toml")
        tracer = Tracer(scene)
        enumerate_all, tail = budget.plan(tracer.world, tracer.settings)
        poses = scene.sensor.poses[:: max(1, len(scene.sensor.poses) // 10)]
        _trace_ms(tracer, poses)  # warm-up
        ms = _trace_ms(tracer, poses)
        rays = [tracer.rays_used(p) for p in poses]
        n_seq = budget.n_sequences(tracer.world, tracer.settings.bounces)
        specular = f"{n_seq} sequences enumerated" if enumerate_all else "found by the rays"
        spread = f"{min(rays)}" if min(rays) == max(rays) else f"{min(rays)} to {max(rays)}"
        rows.append(
            f"| {name} | {len(budget._planar_planes(tracer.world))} | {specular} | "
            f"{'yes' if tail else 'no'} | {spread} | {ms:.1f} |"
        )
    return [
        "### The path each bundled scene takes (automatic budget)",
        "",
        "Planar planes; how the specular stage gets its plane sequences (every one "
        f"enumerated as an image source up to {budget.ENUMERATE_MAX}, else from the "
        "rays); whether rays are needed for scattering (a diffuse material, or a curved "
        "surface after a first reflection); the rays per pose the budget settled on "
        "(over up to 10 poses) and the trace time per pose.",
        "",
        "| scene | planes | specular paths | scattering rays | rays per pose | trace ms |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
    ]


def run() -> str:
    parts = [
        "## Scaling: faces, microphones, range, poses; the ray budget per scene",
        "",
        *_scenes(),
        *_faces(),
        *_mics_and_range(),
        *_poses(),
    ]
    return "\n".join(parts)
