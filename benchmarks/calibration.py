"""Scene calibration: how long fitting the corridor's materials takes, and how it
scales with poses and parameters.

The corridor (uRTIS, 450 kHz, range 4 m, 2 bounces) with a metal cabinet beside
its plaster walls; the "recordings" are simulated with materials the fit does not
see (plaster 0.70/0.35, metal 0.90/0.05; a plaster table over 25/37.5/50 kHz of
0.85/0.70/0.50 where a table is fitted), 7000 rays (the fit traces 5000: another
draw of the diffuse tail) and 30 dB of noise; the fit starts from the bundled values
(plaster 0.95/0.20, metal 0.99/0.00).  Time of one :func:`acousim.calibrate.calibrate`
call (tracing, rendering each path group once, the envelopes, and the fit), and of
its fit alone; the largest error against the truth (reflection, diffuse).

The second table: the bundled ``wall`` (one flat wall 2 m ahead, one bounce, no
direct path), perfectly specular (reflection 0.6, diffuse 0: its implicit default
material), three recordings of its one pose (seeds 1, 2, 3) at each SNR, fitted from
the bundled 0.95 / 0.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from acousim.calibrate import CalibrationSettings, calibrate
from acousim.scene import load_scene
from tests.oracles.corridor_cabinet import folder, simulate_truth

POSES = [0, 12, 24, 36, 48, 6, 18, 30, 42, 54]
TRUTH = {"plaster": (0.70, 0.35), "metal": (0.90, 0.05)}
TABLE = ((25.0, 37.5, 50.0), (0.85, 0.70, 0.50))


def _scenes(tmp: Path, table: bool):
    """The scene the fit starts from, and the recordings of the truth."""
    p, m = TRUTH["plaster"], TRUTH["metal"]
    plaster = f"reflection = {p[0]}\ndiffuse = {p[1]}"
    if table:
        plaster = (
            f"frequencies_khz = {list(TABLE[0])}\nreflection = {list(TABLE[1])}\ndiffuse = {p[1]}"
        )
    recs = simulate_truth(
        folder(tmp) / "truth.toml",
        POSES,
        plaster=plaster,
        metal=f"reflection = {m[0]}\ndiffuse = {m[1]}",
    )
    return load_scene(tmp / "start.toml"), recs


def _errors(cal, table: bool) -> tuple[float, float]:
    """Largest |error| of the reflections (dB for a table's points, else absolute)
    and of the diffuse fractions."""
    er, ed = [], []
    for name, m in cal.materials.items():
        R, d = np.atleast_1d(m.reflection), np.atleast_1d(m.diffuse)
        if table and name == "plaster":
            er.append(np.max(np.abs(20 * np.log10(R / np.array(TABLE[1])))))
        else:
            er.append(np.max(np.abs(R - TRUTH[name][0])))
        ed.append(np.max(np.abs(d - TRUTH[name][1])))
    return max(er), max(ed)


def _row(label: str, scene, recs, n: int, settings: CalibrationSettings, table: bool) -> str:
    cal = calibrate(scene, recs[:n], POSES[:n], settings)
    er, ed = _errors(cal, table)
    unit = " dB" if table else ""
    return (
        f"| {label} | {n} | {len(cal.parameters)} | {cal.seconds:.1f} | {cal.seconds_fit:.2f} | "
        f"{cal.solution.evaluations} | {cal.rms_db_before:.2f} -> {cal.rms_db_after:.2f} | "
        f"{er:.3f}{unit} | {ed:.3f} |"
    )


def _wall_rows() -> list[str]:
    import dataclasses

    from acousim.bundled import find_scene
    from acousim.simulator import Simulator

    wall = load_scene(find_scene("wall"))
    (mesh,) = wall.meshes
    material = dataclasses.replace(mesh.material, reflection=0.6, diffuse=0.0)
    truth = dataclasses.replace(wall, meshes=(dataclasses.replace(mesh, material=material),))
    rows = []
    for snr in (30.0, 60.0, float("inf")):
        recs = []
        for seed in (1, 2, 3):
            sim = dataclasses.replace(wall.simulation, snr_db=snr, seed=seed)
            recs += Simulator(dataclasses.replace(truth, simulation=sim)).run()
        cal = calibrate(wall, recs, [0, 0, 0])
        R, d = cal.parameters
        rows.append(
            f"| {snr:g} | {R.value:.4f} +- {R.sigma:.4f} | {d.value:.2g} +- {d.sigma:.2g} | "
            f"{cal.rms_db_before:.2f} -> {cal.rms_db_after:.2f} | {len(cal.unexplained)} | "
            f"{cal.seconds:.1f} |"
        )
    return rows


def run() -> str:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        scene, recs = _scenes(Path(tmp), table=False)
        calibrate(scene, recs[:1], POSES[:1])  # warm-up: imports, compiled kernels
        default = CalibrationSettings()
        for n in (1, 3, 5, 10):
            rows.append(_row("both materials", scene, recs, n, default, False))
        plaster = CalibrationSettings(parameters=("plaster",))
        rows.append(_row("plaster only", scene, recs, 5, plaster, False))
    with tempfile.TemporaryDirectory() as tmp:
        scene, recs = _scenes(Path(tmp), table=True)
        s = CalibrationSettings(tables={"plaster": TABLE[0]})
        for n in (5, 10):
            rows.append(_row("plaster as a 3-point table, metal", scene, recs, n, s, True))
    corridor, wall = __doc__.split("\n\n")[1:3]
    return "\n".join(
        [
            "## Scene calibration: the corridor's materials fitted to recordings",
            "",
            corridor.strip(),
            "",
            "| fitted | poses | parameters | s per call | s fitting | evaluations | rms "
            "residual (dB) | reflection error | diffuse error |",
            "|---|---|---|---|---|---|---|---|---|",
            *rows,
            "",
            wall.strip(),
            "",
            "| SNR (dB) | reflection (truth 0.6) | diffuse (truth 0) | rms residual (dB) | "
            "unexplained bins | s per call |",
            "|---|---|---|---|---|---|",
            *_wall_rows(),
        ]
    )


if __name__ == "__main__":
    print(run())
