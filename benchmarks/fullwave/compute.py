"""Compute the full-wave reference levels and cache them in benchmarks/data/fullwave.csv.

    nice -n 10 python -m benchmarks.fullwave.compute [--max-khz 80] [--objects ...]

Needs the ``fullwave`` extra: ``make fullwave`` installs bempp-cl, pyopencl and Debian's
OpenCL CPU driver pocl-opencl-icd (without an OpenCL driver bempp falls back to numba,
slower). Each row is
appended as soon as it is solved and rows already in the file are skipped, so the run can
be stopped and resumed.

Set-up (monostatic, as in issue 13): a unit point source and the receiver at the origin;
the object's centre at D = 0.5 m on the x axis. A plate or cube "turned by theta" about
the vertical (z) axis through its centre is computed by moving the source and receiver
on the circle of radius D around the fixed object (the same geometry, rotated), so one
boundary-element matrix serves every angle. Steps per object and frequency:

1. mesh with quad side h = lambda / ppw (ppw points per wavelength, a column);
2. assemble and solve (solve.rigid: Burton-Miller for closed objects, the hypersingular
   screen equation for the zero-thickness plate);
3. level = 20 log10 |p_s / p_wall| with p_wall = exp(ik 2D) / (4 pi 2D), the echo of an
   infinite rigid wall through the object's centre, facing the sensor (image source at
   2D: for a source of unit pressure at 1 m, 1 / (2 * 0.5 m)); phase = arg(p_s / p_wall),
   time factor exp(-i omega t).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from tests.oracles import fullwave_meshes as geometry
from tests.oracles import sphere_series as series

from . import solve

C = 343.0  # m/s (the frequencies; the sensor's c only rescales k)
D = 0.5  # m, source and receiver to the object's centre
OUT = Path(__file__).resolve().parent.parent / "data" / "fullwave.csv"
FIELDS = [
    "object",
    "angle_deg",
    "frequency_hz",
    "level_db",
    "phase_deg",
    "exact_level_db",
    "exact_phase_deg",
    "formulation",
    "ppw",
    "h_m",
    "triangles",
    "dofs",
    "gmres_iterations",
    "assemble_s",
    "solve_s",
]
SIDE = 0.04  # m, plate and cube
SPHERE_RADIUS = 0.02  # m
PLATE_ANGLES = (0.0, 5.0, 10.0, 20.0, 30.0)
CUBE_ANGLES = (0.0, 45.0)


def _mesh(obj: str, h: float):
    if obj == "sphere":
        v, t = geometry.sphere(SPHERE_RADIUS, h)
    elif obj == "cube":
        v, t = geometry.box((SIDE, SIDE, SIDE), h)
    elif obj == "plate":
        v, t = geometry.screen(SIDE, h)
    elif obj == "plate_thick":  # 1.5 mm thick, a cross-check of the screen
        v, t = geometry.box((0.0015, SIDE, SIDE), h)
    else:
        raise ValueError(obj)
    return v + np.array([D, 0, 0]), t


def _angles(obj: str) -> tuple[float, ...]:
    return {"plate": PLATE_ANGLES, "plate_thick": (0.0, 30.0), "cube": CUBE_ANGLES}.get(obj, (0.0,))


def _done(path: Path) -> set[tuple[str, float, float]]:
    if not path.is_file():
        return set()
    with path.open() as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    return {(r[0], float(r[2]), float(r[8])) for r in rows[1:]}


def _append(path: Path, rows: list[dict]) -> None:
    new = not path.is_file()
    with path.open("a", newline="") as f:
        if new:
            f.write(
                "# Full-wave (bempp-cl boundary elements) monostatic echoes of rigid objects; "
                "made by benchmarks/fullwave/compute.py (see its docstring).\n"
                "# Source and receiver at the origin, object centre at 0.5 m; 'turned by "
                "angle_deg' about the vertical axis through the object's centre.\n"
                "# level_db = 20 log10 |p_s / p_wall|, p_wall = exp(ik 1.0 m) / (4 pi 1.0 m): "
                "an infinite rigid wall through the object's centre (image source at 1 m); "
                "phase_deg = arg(p_s / p_wall), time factor exp(-i omega t); c = 343 m/s.\n"
                "# exact_*: the rigid-sphere series (sphere rows). ppw: quad side h = "
                "wavelength / ppw. Seconds on the shared 2-core machine (heavily loaded by "
                "other work), under nice; the first solve of each run includes about a "
                "minute of compilation.\n"
            )
        w = csv.DictWriter(f, FIELDS)
        if new:
            w.writeheader()
        w.writerows(rows)


def run_case(obj: str, freq: float, ppw: float, eta: complex | None = None) -> list[dict]:
    """Solve one object at one frequency; one row per angle."""
    k = 2 * np.pi * freq / C
    h = C / freq / ppw
    v, t = _mesh(obj, h)
    centre = np.array([D, 0, 0])
    angles = np.deg2rad(_angles(obj))
    # turning the object by +a about z through its centre == moving the sensor by -a
    points = centre + D * np.stack([-np.cos(-angles), -np.sin(-angles), 0 * angles], 1)
    closed = obj != "plate"
    sol = solve.rigid(v, t, k, points, closed=closed, eta=eta)
    rows = []
    wall = np.exp(1j * k * 2 * D) / (4 * np.pi * 2 * D)
    exact = series.rigid_sphere_monostatic(k, SPHERE_RADIUS, D)[0] if obj == "sphere" else None
    for a, p in zip(np.rad2deg(angles), sol.pressure):
        ratio = p / wall
        row = {
            "object": obj if eta is None else f"{obj}_eta{eta}",
            "angle_deg": f"{a:g}",
            "frequency_hz": f"{freq:g}",
            "level_db": f"{20 * np.log10(abs(ratio)):.3f}",
            "phase_deg": f"{np.angle(ratio, deg=True):.2f}",
            "exact_level_db": "",
            "exact_phase_deg": "",
            "formulation": "burton-miller"
            if closed and eta != 0
            else ("screen" if not closed else "plain"),
            "ppw": f"{ppw:g}",
            "h_m": f"{h:.6f}",
            "triangles": len(t),
            "dofs": sol.dofs,
            "gmres_iterations": sol.iterations,
            "assemble_s": f"{sol.assemble_s:.1f}",
            "solve_s": f"{sol.solve_s / len(angles):.1f}",
        }
        if exact is not None:
            row["exact_level_db"] = f"{20 * np.log10(abs(exact / wall)):.3f}"
            row["exact_phase_deg"] = f"{np.angle(exact / wall, deg=True):.2f}"
        rows.append(row)
    return rows


PLAN = [
    # (object, ppw, frequencies in kHz) in the order run: cheapest and most needed first
    ("plate", 6.0, (20, 30, 40, 50, 60, 70, 80)),
    ("sphere", 6.0, (20, 40)),
    ("cube", 6.0, (20, 30, 40)),
    ("plate", 10.0, (20, 40, 60)),
    ("sphere", 10.0, (20,)),
    ("plate_thick", 12.0, (20,)),  # faces 1.5 mm apart: finer elements
    ("plate", 6.0, (25, 35, 45, 55, 65, 75)),
    # above 40 kHz the cube at ppw 6 (10 000-22 000 dofs) is too slow and large for this
    # machine: 4 points per wavelength, validated on the sphere at 80 kHz and against
    # ppw 6 on the cube at 40 kHz
    ("sphere", 4.0, (40, 60, 80)),
    ("cube", 4.0, (40, 50, 60, 70, 80)),
    ("sphere", 6.0, (60,)),
    ("cube", 6.0, (50, 60, 70, 80)),
    # the turned plate's notches (a level far below its neighbours: the rims nearly
    # cancel) converge slowly with the mesh, about linearly in h: finer meshes there
    ("plate", 10.0, (25, 50, 75)),
    ("plate", 14.0, (25,)),
    ("plate", 20.0, (25,)),
    ("plate", 28.0, (25,)),
    ("plate", 14.0, (35, 40)),
    ("cube", 8.0, (30,)),
]
OBJECTS = ("plate", "plate_thick", "sphere", "cube")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--objects", nargs="+", default=list(OBJECTS), choices=OBJECTS)
    ap.add_argument(
        "--max-khz", type=float, default=80.0, help="highest frequency to compute (kHz)"
    )
    ap.add_argument(
        "--ppw",
        type=float,
        default=None,
        help="only the plan entries with this many points per wavelength",
    )
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    done = _done(args.out)
    for obj, ppw, freqs in PLAN:
        if obj not in args.objects or (args.ppw is not None and ppw != args.ppw):
            continue
        for f_khz in freqs:
            if f_khz > args.max_khz or (obj, f_khz * 1e3, ppw) in done:
                continue
            rows = run_case(obj, f_khz * 1e3, ppw)
            _append(args.out, rows)
            print(
                obj,
                f_khz,
                "kHz",
                ppw,
                "ppw:",
                [r["level_db"] for r in rows],
                rows[0]["exact_level_db"],
                rows[0]["dofs"],
                "dofs",
                rows[0]["assemble_s"],
                "s",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
