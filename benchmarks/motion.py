"""Motion within a measurement: the Doppler renderer against its exact per-sample
reference (error beside time), the error of tracing once per measurement against
tracing at many instants, and the corridor drive in motion against the frozen drive."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

import acousim.simulator as _simulator
import acousim.synth.doppler as _doppler
import processing as P
from acousim.kinematics import TABLE_STEP_S, SensorKinematics, arrivals
from acousim.kinematics.reference import render_doppler_reference
from acousim.scene import Pose, load_scene
from acousim.scene.trajectory import Trajectory
from acousim.simulator import Simulator
from acousim.synth.doppler import (
    COMPRESS_TOLERANCE,
    DOPPLER_TOLERANCE,
    DopplerCache,
    doppler_nodes,
    render_doppler,
)
from acousim.synth.options import RenderOptions
from acousim.trace.motion.following import MovingPaths

from .timing import best_time

ROOT = Path(__file__).resolve().parent.parent / "scenes"
C = 343.0
FS = 450e3


def _render_cases(small: bool):
    arr = P.preset("urtis_v1")
    four = P.Array("4 mics", arr.positions_m[[0, 9, 20, 29]], np.array([0.0, 0, -0.012]))
    rng = np.random.default_rng(3)
    n_pts = 3 if small else 8
    pts = np.column_stack(
        [rng.uniform(1, 4, n_pts), rng.uniform(-1.5, 1.5, n_pts), rng.uniform(-0.5, 0.5, n_pts)]
    )
    vel = np.zeros_like(pts)
    vel[0] = [-1.0, 0.3, 0]  # a person walking towards the sensor
    # (a point 2.5 m ahead stands for a wall: a single path closing at v)
    wall = (np.array([[2.5, 0, 0]]), np.zeros((1, 3)))
    return [
        ("wall ahead, 1 m/s", four, wall, [1.0, 0, 0], [0, 0, 0]),
        ("points, 1 m/s, 90 deg/s", four, (pts, vel), [1.0, 0.2, 0], [0, 0, 90]),
        ("points, 2 m/s, 180 deg/s", four, (pts, vel), [2.0, 0.4, 0], [0, 0, 180]),
    ]


def _case(case, wf, n: int):
    """One renderer case: its arrivals, the exact reference's time (s) and samples."""
    _label, array, (pts, vel), v, w = case
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, v, np.deg2rad(w))
    paths = MovingPaths.points(pts, np.ones(len(pts)), vel, pose.to_world(array.emitter_m))
    kin = SensorKinematics(traj, pose, array, n / FS, TABLE_STEP_S)
    a = arrivals(paths, kin, wf.duration_s, C, np.array([1.0, 0, 0]))
    t0 = time.perf_counter()
    ref = render_doppler_reference(
        paths, SensorKinematics.exact(traj, pose, array), wf, FS, n, C, a.echoes.gain
    )
    return a, time.perf_counter() - t0, ref


def _renderer_table(small: bool) -> list[str]:
    wf = P.rtis_call("default_20_80")
    n = int(0.03 * FS)  # every echo inside the window
    rows = []
    for case in _render_cases(small):
        label, array, (pts, _vel), _v, _w = case
        a, ref_t, ref = _case(case, wf, n)
        nodes = doppler_nodes(a.rate.min(), a.rate.max(), wf, FS)
        cache = DopplerCache()  # as a simulator's: kept between calls
        fast_t = best_time(
            lambda a=a, c=cache: render_doppler(a.echoes, a.rate, wf, FS, n, cache=c), repeat=3
        )
        fast = render_doppler(a.echoes, a.rate, wf, FS, n, cache=cache)
        err = 20 * np.log10(np.linalg.norm(fast - ref) / np.linalg.norm(ref))
        rows.append(
            f"| {label} | {len(pts)} x {array.n_mics} | {a.rate.min():.5f} - {a.rate.max():.5f} "
            f"| {nodes.size} | {fast_t * 1e3:.1f} | {ref_t:.1f} | {err:.1f} | "
            f"{np.abs(a.curvature_s).max() * 1e9:.2f} |"
        )
    return rows


#: (nodes' tolerance, compression tolerance) compared in the time-against-error table
TOLERANCES = ((1e-4, 3e-4), (1e-3, 3e-4), (1e-3, 7e-4), (3e-3, 1e-3), (1e-2, 3e-3))


def _corridor_echoes():
    """The arguments the corridor drive passes to `plan_doppler` (those of
    `render_doppler`) for one pose."""
    seen = []
    real = _simulator.plan_doppler

    def spy(*args, **kwargs):
        seen.append((args, kwargs))
        return real(*args, **kwargs)

    _simulator.plan_doppler = spy
    try:
        Simulator(load_scene(ROOT / "corridor.toml")).run([12])
    finally:
        _simulator.plan_doppler = real
    return seen[0]


def _tolerance_table(small: bool) -> list[str]:
    """The renderer's two tolerances against its sets, time and error: render time
    of one corridor pose (sets: after compression) and the error of the two point
    cases of the renderer table against the exact reference."""
    wf = P.rtis_call("default_20_80")
    n = int(0.03 * FS)
    args, kwargs = _corridor_echoes()
    sets = []
    real_compress = _doppler.compress

    def counting(*a, **k):
        out = real_compress(*a, **k)
        sets.append(out[0].shape[2])
        return out

    cases = [_case(case, wf, n)[::2] for case in _render_cases(small)[1:]]
    rows = []
    for tn, tc in TOLERANCES:
        options = RenderOptions(doppler_tolerance=tn, compress_tolerance=tc)
        opts = dict(
            kwargs,
            options=dataclasses.replace(
                kwargs["options"], doppler_tolerance=tn, compress_tolerance=tc
            ),
        )
        _doppler.compress = counting
        try:
            render = best_time(lambda o=opts: _doppler.render_doppler(*args, **o), repeat=5)
        finally:
            _doppler.compress = real_compress
        nodes = doppler_nodes(float(args[1].min()), float(args[1].max()), args[2], args[3], tn)
        errs = []
        for a, ref in cases:
            fast = render_doppler(a.echoes, a.rate, wf, FS, n, options=options)
            errs.append(20 * np.log10(np.linalg.norm(fast - ref) / np.linalg.norm(ref)))
        default = " (default)" if (tn, tc) == (DOPPLER_TOLERANCE, COMPRESS_TOLERANCE) else ""
        rows.append(
            f"| {tn:g} / {tc:g}{default} | {nodes.size} | {sets[-1]} | {render * 1e3:.1f} | "
            + " | ".join(f"{e:.1f}" for e in errs)
            + " |"
        )
    return rows


def _geometry_table() -> list[str]:
    """Paths traced at the emission pose and moved with the emitter against paths
    traced again at the pose of later emission instants; lengths to the microphones
    at a later reception."""
    sc = load_scene(ROOT / "shoebox.toml")
    sim = Simulator(sc)
    pose = sc.sensor.poses[0]
    array = sc.sensor.array
    T = sc.sensor.call.duration_s
    rows = []
    for v, w in (([1.0, 0, 0], 90.0), ([2.0, 0.5, 0], 180.0)):
        traj = Trajectory.constant(pose, v, [0, 0, np.deg2rad(w)])
        e0 = pose.to_world(array.emitter_m)
        first = sim.paths(pose)
        spec = first.kind == 1
        mp = MovingPaths.from_traced(first, e0)
        exact = np.any(mp.mirror != 0, axis=(1, 2))
        worst = {True: 0.0, False: 0.0}
        lost = 0
        for tau in np.linspace(0, T, 6)[1:]:
            later = traj.pose(pose.time_s + tau)
            anchors, firsts = mp.moved(e0, later.to_world(array.emitter_m))
            traced = sim.paths(later)
            img = traced.anchor_m[traced.kind == 1]
            order = traced.order[traced.kind == 1]
            # the receiver 10 ms later (any receiver position is exact)
            mics = traj.to_world(array.positions_m, pose.time_s + 0.01)
            for k in np.flatnonzero(spec):
                pred = firsts[k] + np.linalg.norm(mics - anchors[k], axis=1)
                cand = np.flatnonzero(order == mp.order[k])
                true = np.linalg.norm(mics[None] - img[cand][:, None], axis=2)
                if cand.size == 0 or np.abs(true - pred[None]).max(axis=1).min() > 1e-3:
                    lost += 1  # no counterpart: the path left the view
                    continue
                e = float(np.abs(true - pred[None]).max(axis=1).min())
                worst[bool(exact[k])] = max(worst[bool(exact[k])], e)
        n_exact, n_fermat = int((spec & exact).sum()), int((spec & ~exact).sum())
        rows.append(
            f"| {np.linalg.norm(v):.1f} m/s, {w:.0f} deg/s | {n_exact} | "
            f"{worst[True] * 1e9:.3f} | {n_fermat} | {worst[False] * 1e6:.2f} | "
            f"{worst[False] / C * 1e9:.1f} | {2 * np.pi * 80e3 * worst[False] / C:.1e} | "
            f"{lost} |"
        )
    return rows


def _moving_mesh_table() -> list[str]:
    """Moving meshes: the first-order echo of a wall moving during the measurement
    (turned 20 degrees, closing and sliding), paths traced once at the emission
    instant and moved by the law of :mod:`acousim.trace.motion.moving_world`, against the
    reception times found by tracing the wall again where it is at the reflection
    instant (``tests/test_moving_mesh.reference_reception``)."""
    import trimesh

    import acousim
    from tests.acousim.trace.motion.test_moving_mesh import (
        reference_reception,  # the tests' reference
    )

    arr = P.preset("urtis_v1")
    call = P.rtis_call("default_20_80")
    yaw = np.deg2rad(20)
    n = np.array([-np.cos(yaw), -np.sin(yaw), 0.0])  # the wall's face, towards the sensor
    T = np.eye(4)
    T[:3, :3] = trimesh.transformations.rotation_matrix(yaw, [0, 0, 1])[:3, :3]
    T[:3, 3] = -2.1 * n
    mics = [0, 9, 20, 29]
    rows = []
    sliding = 1.5 * n + np.array([0.8, -1.0, 0.3])  # closing at 1.09 m/s, and sliding
    for wall_v, v, w in (
        (sliding, None, 0.0),
        (1.0 * n, [1.0, 0.2, 0], 90.0),
        (sliding, [2.0, 0.4, 0], 180.0),
    ):
        label = f"wall {np.linalg.norm(wall_v):.2f} m/s ({wall_v @ n:.2f} closing), " + (
            "sensor still" if v is None else f"sensor {np.linalg.norm(v):.2f} m/s, {w:g} deg/s"
        )
        pose = Pose([0.0, 0, 0])
        traj = None if v is None else Trajectory.constant(pose, v, [0, 0, np.deg2rad(w)])
        wall = acousim.MeshItem(
            trimesh.creation.box((0.2, 20, 20)), acousim.Material("w", 1.0), T, velocity_m_s=wall_v
        )
        sensor = acousim.Sensor(array=arr, call=call, direct_path=False, motion=traj)
        sim_settings = acousim.Simulation(max_range_m=4.0, rays=2000, absorption=False)
        sc = acousim.Scene(meshes=[wall], sensor=sensor, simulation=sim_settings)
        sim = Simulator(sc)
        moving, _, _, _ = sim.moving_paths(pose)
        kin = SensorKinematics(traj, pose, arr, sc.n_samples() / FS, TABLE_STEP_S)
        a = arrivals(moving, kin, call.duration_s, sim.c, pose.rotation[:, 0])
        # the model's own reception times of the first and last sample
        t0 = a.echoes.delay_s[:, 0] - a.curvature_s[:, 0] * (2 / 3)
        t1 = t0 + call.duration_s / a.rate[:, 0]
        still = dataclasses.replace(sc, meshes=(dataclasses.replace(wall, velocity_m_s=(0, 0, 0)),))
        err = frozen = 0.0
        for m in mics:
            r0 = reference_reception(sc, wall_v, pose, m, 0.0, traj, sim.c)
            r1 = reference_reception(sc, wall_v, pose, m, call.duration_s, traj, sim.c)
            f0 = reference_reception(still, (0, 0, 0), pose, m, 0.0, traj, sim.c)
            err = max(err, abs(t0[m] - r0), abs(t1[m] - r1))
            frozen = max(frozen, abs(f0 - r0))
        rows.append(
            f"| {label} | {np.max(np.abs(a.rate[:, 0] - 1)) * 1e3:.2f} | "
            f"{frozen * 1e6:.2f} | {err * 1e12:.1f} | {2 * np.pi * 80e3 * err:.1e} |"
        )
    return rows


def _passerby(small: bool) -> tuple[float, float, int]:
    """Time per measurement of the corridor drive in motion (as :func:`_drive`)
    without and with a person (a 0.4 x 0.5 x 1.7 m box) walking towards the robot at
    1 m/s, 0.1 m to its left (best of 3); and how many of the paths end on it."""
    import trimesh

    import acousim

    sc = load_scene(ROOT / "corridor.toml")
    poses = tuple(dataclasses.replace(p, time_s=i / 20) for i, p in enumerate(sc.sensor.poses))
    sensor = dataclasses.replace(
        sc.sensor, poses=poses, motion=Trajectory.through(poses), rate_hz=20.0
    )
    person = acousim.MeshItem(
        trimesh.creation.box((0.4, 0.5, 1.7)), position_m=(6.0, 0.1, 0.85), velocity_m_s=(-1, 0, 0)
    )
    idx = list(range(10, 14 if small else 30))
    out = []
    for meshes in (sc.meshes, (*sc.meshes, person)):
        sim = Simulator(dataclasses.replace(sc, sensor=sensor, meshes=meshes))
        sim.run([0])
        best = np.inf
        for _ in range(3):
            sim.tracer.forget()  # every repetition pays for the trace
            t0 = time.perf_counter()
            sim.run(idx)
            best = min(best, (time.perf_counter() - t0) / len(idx))
        out.append(best)
    paths = sim.paths(poses[idx[0]])
    on, _, _ = sim.tracer.riders(paths, poses[idx[0]])
    return out[0], out[1], int((on >= 0).sum())


def _drive(small: bool) -> tuple[float, float, float, float]:
    """Time per measurement of the corridor drive at 1 m/s (the file's poses at 20 Hz)
    frozen and in motion, each tracing every pose anew: the two run in turn, pair by
    pair (this shared machine's speed drifts by tens of percent within minutes), the
    best of each and the median of the pairs' ratios; and the speed (m/s)."""
    sc = load_scene(ROOT / "corridor.toml")
    poses = tuple(dataclasses.replace(p, time_s=i / 20) for i, p in enumerate(sc.sensor.poses))
    speed = np.linalg.norm(np.diff([p.position_m for p in poses], axis=0), axis=1).mean() * 20
    idx = list(range(10, 14 if small else 30))
    sims = []
    for motion in (None, Trajectory.through(poses)):
        sensor = dataclasses.replace(sc.sensor, poses=poses, motion=motion, rate_hz=20.0)
        sims.append(Simulator(dataclasses.replace(sc, sensor=sensor)))
        sims[-1].run([0])
    times = np.empty((PAIRS, 2))
    for r in range(PAIRS):
        for j, sim in enumerate(sims):
            sim.tracer.forget()  # every repetition pays for the trace
            t0 = time.perf_counter()
            sim.run(idx)
            times[r, j] = (time.perf_counter() - t0) / len(idx)
    ratio = float(np.median(times[:, 1] / times[:, 0]))
    return float(times[:, 0].min()), float(times[:, 1].min()), ratio, speed


#: frozen and moving runs of the corridor drive timed in turn
PAIRS = 7


def run(small: bool = False) -> str:
    lines = [
        "## Motion within a measurement: Doppler renderer, geometry, corridor drive",
        "",
        "**Renderer.** The fast renderer (linear delay law per path and microphone, the "
        "call time-scaled about its middle at Chebyshev nodes of the Doppler factors and "
        "interpolated as a Chebyshev series, sets compressed) "
        "against the exact reference (emission time solved per sample at 64x the rate, "
        "analytic call, band-limited); uRTIS microphones 0, 9, 20, 29; RTIS 80-20 kHz "
        "call; point reflectors 1-4 m away, one walking towards the sensor at 1 m/s; "
        "'curvature': the largest deviation of the reception time from the linear law "
        "at the middle of the call (what the fast method neglects). Target: -60 dB.",
        "",
        "| case | paths x mics | Doppler factors | nodes | fast ms | reference s | "
        "error (dB) | curvature (ns) |",
        "|---|---|---|---|---|---|---|---|",
        *_renderer_table(small),
        "",
        "The renderer's two tolerances (the Doppler nodes' interpolation bound, the "
        "compression of the gain sets) against time and error: nodes and sets (after "
        "compression) of one pose of the corridor drive (pose 12, 1 m/s, turning; "
        "3340 paths x 30 microphones) and its render time (`render_doppler` alone, "
        "best of 5); error of the two point cases above against the exact reference.",
        "",
        "| tolerances (nodes / sets) | corridor nodes | corridor sets | corridor render ms "
        "| error 1 m/s, 90 deg/s (dB) | error 2 m/s, 180 deg/s (dB) |",
        "|---|---|---|---|---|---|",
        *_tolerance_table(small),
        "",
        "**Geometry.** Paths traced once, at the pose of the start of the emission, and "
        "moved with the emitter: first- and second-order image sources exactly (their "
        "planes recovered from the traced path), the others (reflections at an edge, "
        "whose two points coincide in the trace; higher orders; scattering) by the "
        "second-order Fermat law of `acousim.trace.motion.following`; against the shoebox traced "
        "again at the pose of five later instants of the 2.5 ms call. Largest error of "
        "the path length to any microphone (the receiving side is exact: image sources "
        "do not depend on the receiver); 'lost': paths without a counterpart in the "
        "later trace.",
        "",
        "| motion | image sources moved exactly | their error (nm) | Fermat paths | "
        "their error (um) | (ns of delay) | (rad at 80 kHz) | lost |",
        "|---|---|---|---|---|---|---|---|",
        *_geometry_table(),
        "",
        "**Moving meshes.** A wall turned 20 degrees moving during the measurement, "
        "traced once where it is at the start of the emission, its image source moved "
        "as that of a translating plane (`acousim.trace.motion.moving_world`), against the wall "
        "traced again where it is at the instant of reflection (reception times of the "
        "first and last sample of the call, uRTIS microphones 0, 9, 20, 29); 'frozen': "
        "the error if the wall were left where it is at the emission.",
        "",
        "| motion | largest abs(Doppler factor - 1) (x 1e-3) | frozen error (us) | "
        "error (ps) | (rad at 80 kHz) |",
        "|---|---|---|---|---|",
        *_moving_mesh_table(),
        "",
    ]
    alone, walker, riders = _passerby(small)
    lines += [
        f"A person walking in the corridor drive (a moving mesh; {riders} of the paths of "
        "the first pose end on it): the world is rebuilt per measurement and those paths "
        "follow it; time per measurement of the drive in motion (best of 3).",
        "",
        "| drive in motion | ms per measurement | ratio |",
        "|---|---|---|",
        f"| corridor | {alone * 1e3:.0f} | 1.00 |",
        f"| corridor and a person walking at 1 m/s | {walker * 1e3:.0f} | {walker / alone:.2f} |",
        "",
    ]
    static, moving, ratio, speed = _drive(small)
    lines += [
        "**Corridor drive in motion.** The corridor's poses at 20 Hz "
        f"({speed:.2f} m/s, turning with the drive), default settings, time per "
        "measurement of `Simulator.run` (each run tracing every pose anew): frozen "
        "poses against the continuous trajectory, run in turn "
        f"{PAIRS} times; the best of each, and the median of the {PAIRS} pairs' ratios "
        "(this shared machine's speed drifts by tens of percent within minutes, "
        "so a ratio of bests taken minutes apart can be off by as much). Target: at "
        "most 1.5x.",
        "",
        "| drive | best ms per measurement | ratio (median of pairs) |",
        "|---|---|---|",
        f"| frozen poses | {static * 1e3:.0f} | 1.00 |",
        f"| in motion | {moving * 1e3:.0f} | {ratio:.2f} |",
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":  # a quick smoke run
    print(run(small=True))
