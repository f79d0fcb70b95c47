"""Edge diffraction: the edge-element step against error and time, objects against
physical optics and the full-wave reference, and (:mod:`.diffraction_pairs`) edge to
edge and the cost of the defaults in the corridor."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from acousim.trace import KIND
from acousim.trace.diffraction.btm import DEFAULT_STEP_M, ElementLimits, edge_elements
from tests.acousim.trace.diffraction.test_first_order import (
    physical_optics,  # the tests' independent reference
)
from tests.oracles.scenes import first_pose, rigid_scene, screen, spectrum, square_faces, turn_z

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
        screen(),
        _cyl(0.15, np.deg2rad(60), 0),
        _cyl(0.10, th_r, 0.05),
        ElementLimits(step_m=step),
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


def _object_level(kind, size, distance, rot_deg, tmp, order=1) -> tuple[float, float, np.ndarray]:
    """Band power (20-80 kHz, dB re an infinite rigid wall at the same distance) of
    ours (diffraction order 1 or 2) and of physical optics (lit faces), and ours at
    20 and 80 kHz; monostatic uRTIS."""
    ours, po, ends, _ = _object_response(kind, size, distance, rot_deg, tmp, order)
    return ours, po, ends


def _object_response(kind, size, distance, rot_deg, tmp, order=1, n_freq=13):
    """:func:`_object_level` and ours over n_freq frequencies of 20-80 kHz (dB re the
    wall), with the trace time (s) and the number of edge-to-edge paths."""

    from acousim.trace.tracer import Tracer

    ry = np.deg2rad(rot_deg[1])
    rot_y = np.array([[np.cos(ry), 0, np.sin(ry)], [0, 1, 0], [-np.sin(ry), 0, np.cos(ry)]])
    centre = np.array([distance, 0, 0])
    quads = square_faces(kind, size, rot_y @ turn_z(rot_deg[0]), centre)
    simulation = {"max_range_m": distance + 1.0, "rays": 20000, "bounces": 2, "beam_deg": 60.0}
    if order is not None:
        simulation.update(diffraction={"order": order}, energy_floor_db=-200.0)
    scene = rigid_scene(tmp, quads, simulation)
    pose, e, r = first_pose(scene)
    tracer = Tracer(scene, threads=1)
    t0 = time.perf_counter()
    paths = tracer.trace(pose)
    seconds = time.perf_counter() - t0
    n_e2e = 0
    if order != 1:  # edge-to-edge paths: the order-2 diffraction paths order 1 lacks
        n_e2e = int(np.sum((paths.kind == KIND["diffraction"]) & (paths.order == 2)))
    k = 2 * np.pi * np.linspace(20e3, 80e3, n_freq) / C
    ours = spectrum(paths, r, k)
    po = 0
    for q in quads:
        outward = q.mean(axis=0) - centre  # a plate (through the centre) is two-sided
        if np.linalg.norm(outward) < 1e-9 or outward @ (e - q.mean(axis=0)) > 0:
            po = po + physical_optics(q, e, r, k, n=int(size / 0.0005))
    wall = 1 / (2 * distance)

    def band(h):
        return 10 * np.log10(np.mean(np.abs(h) ** 2) / wall**2)

    spectrum_db = 20 * np.log10(np.abs(ours) / wall)
    return band(ours), band(po), spectrum_db[[0, -1]], (spectrum_db, seconds, n_e2e)


def _objects() -> list[str]:
    import tempfile

    cases = [
        (
            "40 mm plate at 0.5 m, face on",
            "plate",
            0.04,
            0.5,
            (0, 0),
            "-8.7 / +2.7 at 20 / 80 kHz",
        ),
        ("40 mm plate at 0.5 m, turned 5°", "plate", 0.04, 0.5, (5, 0), "-12"),
        ("40 mm plate at 0.5 m, turned 10°", "plate", 0.04, 0.5, (10, 0), "-20"),
        ("40 mm plate at 0.5 m, turned 20°", "plate", 0.04, 0.5, (20, 0), "-25"),
        ("40 mm plate at 0.5 m, turned 30°", "plate", 0.04, 0.5, (30, 0), "-27"),
        ("40 mm cube at 0.5 m, turned 45° (z)", "cube", 0.04, 0.5, (45, 0), "-26"),
        ("0.5 m plate at 2 m, turned 10°", "plate", 0.5, 2.0, (10, 0), ""),
        ("0.5 m cube at 2.2 m, turned 45° (z)", "cube", 0.5, 2.2, (45, 0), ""),
        ("0.5 m cube at 2.2 m, turned 30° (z), 20° (y)", "cube", 0.5, 2.2, (30, 20), ""),
    ]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, kind, size, dist, rot, full_wave in cases:
            ours, po, ends = _object_level(kind, size, dist, rot, Path(tmp))
            ours2, _, ends2 = _object_level(kind, size, dist, rot, Path(tmp), order=None)
            rows.append(
                f"| {name} | {ours:.1f} | {ours2:.1f} | {ends[0]:.1f} / {ends[1]:.1f} | "
                f"{ends2[0]:.1f} / {ends2[1]:.1f} | {po:.1f} | {full_wave} |"
            )
    return rows


def _strip() -> tuple[np.ndarray, np.ndarray]:
    """Error (dB, 20-80 kHz) of geometric + first order, and + second order, of a
    2 cm wide, 4 m long rigid strip 2 m from a monostatic sensor against the exact
    strip (the tests' reference: tests/acousim/trace/diffraction/test_edge_to_edge.py)."""
    from acousim.trace.diffraction.pairs import Wedge, edge_pair_elements
    from tests.acousim.trace.diffraction.test_edge_to_edge import strip_far_field

    d, w, length = 2.0, 0.02, 4.0
    rims = [
        Wedge(
            np.array([d, s * w / 2, -length / 2]),
            np.array([d, s * w / 2, length / 2]),
            np.array([0, -s, 0.0]),
            np.array([-1.0, 0, 0]),
            2 * np.pi,
        )
        for s in (-1, 1)
    ]
    k = 2 * np.pi * np.linspace(20e3, 80e3, 13) / C
    o = np.zeros(3)

    def resp(e):
        return (e.amplitude * np.exp(-1j * k[:, None] * (e.first_leg_m + e.second_leg_m))).sum(1)

    first = sum(
        resp(edge_elements(Wedge(r.start_m, r.end_m, r.face_dir, r.normal, 2 * np.pi), o, o))
        for r in rims
    )
    second = sum(resp(edge_pair_elements(rims[i], rims[1 - i], 0.0, 0.0, 2, o, o)) for i in (0, 1))
    exact = np.array([np.conj(strip_far_field(kk, w / 2)) for kk in k])
    exact *= np.exp(-2j * k * d) / (np.sqrt(2) * d**1.5)
    geometric = np.exp(-2j * k * d) / (2 * d)
    one = 20 * np.log10(np.abs(geometric + first) / np.abs(exact))
    two = 20 * np.log10(np.abs(geometric + first + second) / np.abs(exact))
    return one, two


FULLWAVE = Path(__file__).resolve().parent / "data" / "fullwave.csv"


def _against_fullwave() -> list[str]:
    """Ours (first order, and with edge to edge) against the cached full-wave levels
    of benchmarks/data/fullwave.csv (made by benchmarks/fullwave, branch fullwave; the
    finest mesh of each case): band power difference and the worst difference at one
    frequency (40 mm objects at 0.5 m, levels re the wall through their centre).
    Empty if the file is absent."""
    import csv
    import tempfile

    if not FULLWAVE.exists():
        return []
    with FULLWAVE.open() as f:
        table = list(csv.DictReader(line for line in f if not line.startswith("#")))
    ref: dict[tuple, tuple[float, float]] = {}
    for r in table:
        key = (r["object"], round(float(r["angle_deg"])), round(float(r["frequency_hz"])))
        if key not in ref or float(r["ppw"]) > ref[key][1]:
            ref[key] = (float(r["level_db"]), float(r["ppw"]))
    freqs = np.arange(20e3, 80.1e3, 5e3)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for obj in ("plate", "cube"):
            for angle in sorted({k[1] for k in ref if k[0] == obj}):
                have = [i for i, f in enumerate(freqs) if (obj, angle, round(f)) in ref]
                if not have:
                    continue
                full = np.array([ref[(obj, angle, round(freqs[i]))][0] for i in have])
                cells = []
                for order in (1, None):
                    spec = _object_response(obj, 0.04, 0.5, (angle, 0), Path(tmp), order, 13)[3][0]
                    ours = spec[have]
                    band = 10 * np.log10(np.mean(10 ** (ours / 10)) / np.mean(10 ** (full / 10)))
                    cells.append(f"{band:+.2f} / {np.max(np.abs(ours - full)):.1f}")
                band_full = 10 * np.log10(np.mean(10 ** (full / 10)))
                rows.append(
                    f"| 40 mm {obj}, turned {angle}° | {freqs[have[0]] / 1e3:.0f}-"
                    f"{freqs[have[-1]] / 1e3:.0f} kHz ({len(have)}) | {band_full:.1f} | "
                    f"{cells[0]} | {cells[1]} |"
                )
    if not rows:
        return []
    return [
        "Against the cached full-wave levels (benchmarks/data/fullwave.csv, bempp-cl, "
        "monostatic, 40 mm objects at 0.5 m, every 5 kHz where computed): ours minus "
        "full-wave, band power (dB) / worst single frequency (dB); first order only "
        "(`diffraction.order = 1`, floor -200 dB) and at the default settings (a scene "
        "that says nothing about diffraction).",
        "",
        "| object | frequencies | full-wave band (dB re wall) | first order | defaults |",
        "|---|---|---|---|---|",
        *rows,
        "",
    ]


def _bar() -> list[str]:
    """A 2 cm square bar turned 45° (edge on) at 2 m against the exact 2D bar (the
    tests' boundary-element reference, 8000 panels per metre), 20-80 kHz: error of
    first order alone and with edge to edge."""
    from tests.acousim.trace.diffraction.test_edge_to_edge import diamond_orders, rect_far_field

    d = 2.0
    freqs = np.arange(20e3, 81e3, 10e3)
    k = 2 * np.pi * freqs / C
    first, second = diamond_orders(d, k)
    exact = np.array([np.conj(rect_far_field(kk, 0.02, 0.02, np.pi / 4)) for kk in k])
    exact *= np.exp(-2j * k * d) / (np.sqrt(2) * d**1.5)
    rows = []
    for i, f in enumerate(freqs):
        e1 = 20 * np.log10(abs(first[i]) / abs(exact[i]))
        e2 = 20 * np.log10(abs(first[i] + second[i]) / abs(exact[i]))
        rows.append(
            f"| {f / 1e3:.0f} | {20 * np.log10(abs(exact[i]) * 2 * d):.1f} | {e1:+.2f} "
            f"| {e2:+.2f} |"
        )
    return rows


def _edge_to_edge() -> list[str]:
    """What second order (edge to edge) adds on thin plates facing the sensor at
    0.5 m, and on a long strip against the exact strip solution."""
    import tempfile

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for side in (0.02, 0.04, 0.10, 0.5):
            res = {}
            for order in (1, 2):
                best = None
                for _ in range(3):  # best of 3 trace times
                    r = _object_response("plate", side, 0.5, (0, 0), Path(tmp), order, 25)
                    best = r if best is None or r[3][1] < best[3][1] else best
                res[order] = best
            b1, b2 = res[1][0], res[2][0]
            s1, s2 = res[1][3][0], res[2][3][0]
            rows.append(
                f"| {side * 1e3:g} mm plate, face on | {b1:.2f} | {b2:.2f} | "
                f"{np.max(np.abs(s2 - s1)):.2f} | {res[2][3][2]} | "
                f"{res[1][3][1] * 1e3:.0f} / {res[2][3][1] * 1e3:.0f} |"
            )
    return rows


def run() -> str:
    from . import diffraction_pairs as pairs

    one, two = _strip()
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
            "tests/acousim/trace/diffraction/test_first_order.py). Time: one 20 m edge, best of 5.",
            "",
            "| step (mm) | elements per edge | µs per edge | worst error (dB re incident) |",
            "|---|---|---|---|",
            *_element_table(),
            "",
            "Edge to edge (`acousim.trace.diffraction.pairs`): the element step (of both edges, "
            "excess path length) against error and time. The reciprocity test's turned "
            "box (6 x 5 x 4 cm, 0.5 m, bistatic; 32 edge pairs), its edge-to-edge field "
            "at 13 frequencies of 20-80 kHz against the same at a 0.05 mm step, worst "
            "difference relative to the field's peak; time of all pairs, compiled kernel "
            "(numba, best of 3) and the numpy path (best of 2). The stage takes the scene's "
            "step scaled to the call's highest frequency (1 mm at 85 kHz: 1.7 mm for the "
            "corridor's 25-50 kHz call); bins of a quarter of the scene's step.",
            "",
            "| step (mm) | ms, compiled | ms, numpy | worst error (of the peak) |",
            "|---|---|---|---|",
            *pairs.step_table(),
            "",
            f"The corridor, `Simulator.run` over {len(pairs.POSES)} poses, each variant in turn in "
            "one process (5 rounds; the tracer's cache emptied each time): median ms per "
            "measurement, measurements/s, the median of the per-round ratios to diffraction "
            "off, and diffraction paths per pose (of them second order: edge to edge, or an "
            "edge and a reflection). 'moving': the "
            "file's drive (the Doppler renderer); 'frozen': its poses without motion.",
            "",
            "| drive | diffraction | ms per measurement | measurements/s | time / off | "
            "diffraction paths (of them second order) |",
            "|---|---|---|---|---|---|",
            *pairs.corridor_table(),
            "",
            "What the per-pair selection skips (corridor poses, defaults): the candidate "
            "edge pairs (sharing a plane, seen), those integrated, those with a path at or "
            "above the energy floor when every pair is integrated, and the largest path of "
            "a skipped pair relative to the floor (negative: below it, so the tracer's floor "
            "would have dropped it).",
            "",
            "| pose | candidate pairs | integrated | reaching the floor | largest skipped |",
            "|---|---|---|---|---|",
            *pairs.skipped_table(),
            "",
            "Scenes without many edges, diffraction off (the old default) against the "
            "defaults, in turn (7 rounds): the wall's rim is an edge (its paths are real "
            "echoes), the sphere has none.",
            "",
            "| scene | diffracting edges | ms off | ms defaults | ratio | diffraction paths |",
            "|---|---|---|---|---|---|",
            *pairs.scenes_table(),
            "",
            "Objects that geometric optics gets wrong: band power at 20-80 kHz (13 "
            "frequencies), dB relative to an infinite rigid wall at the same distance, "
            "monostatic uRTIS, rigid faces; first order only (floor -200 dB) and at the "
            "defaults; physical optics over the lit faces (0.5 mm "
            "cells); full-wave: the boundary-element levels quoted in issue 13 (read as "
            "relative to the same wall). Before edge diffraction the turned objects were "
            "silent and the 40 mm plate face on was 0 dB.",
            "",
            "| object | ours, first order (dB) | ours, defaults (dB) | first order at 20 / 80 kHz "
            "(dB) | defaults, 20 / 80 kHz (dB) | physical optics (dB) "
            "| full-wave, issue 13 (dB) |",
            "|---|---|---|---|---|---|---|",
            *_objects(),
            "",
            "What second-order (edge-to-edge) diffraction adds (`simulation.diffraction.order "
            "= 2`, floor -200 dB: every pair) on square plates facing the sensor at 0.5 m: "
            "band power at 20-80 kHz (dB re the wall) with first order only and with edge "
            "to edge, the largest change at one frequency (25 frequencies), the edge-to-edge "
            "paths added, and the trace time of the pose (best of 3). "
            f"On a 2 cm x 4 m strip at 2 m, against the exact strip solution "
            "(tests/acousim/trace/diffraction/test_edge_to_edge.py), 13 frequencies of 20-80 kHz: "
            "first order "
            f"{one.min():.2f} to {one.max():.2f} dB, with edge to edge {two.min():.2f} to "
            f"{two.max():.2f} dB.",
            "",
            "| plate | first order (dB) | with edge to edge (dB) | largest change (dB) "
            "| edge-to-edge paths | trace ms, order 1 / 2 |",
            "|---|---|---|---|---|---|",
            *_edge_to_edge(),
            "",
            "A 2 cm x 4 m square bar turned 45° (its front edge towards the sensor: no "
            "specular echo; three edges in view, two edge-to-edge pairs each way) at 2 m, "
            "against the exact 2D bar (boundary elements, "
            "tests/acousim/trace/diffraction/test_edge_to_edge.py; "
            "converged to about 0.1 dB at 60-80 kHz) taken to 3D by stationary phase: error "
            "of ours in dB.",
            "",
            "| kHz | exact (dB re wall) | first order | with edge to edge |",
            "|---|---|---|---|",
            *_bar(),
            "",
            *_against_fullwave(),
        ]
    )
