"""The corridor's recordings and ground truth in two checkouts, compared: the
waveform residual relative to the energy of the echoes, and the largest difference
of each ground-truth field (what a change that is not bit-identical must state).

Each checkout runs in a process of its own (its root first on the path) and makes
the poses with noise off (``snr_db = inf``), every trace paid; the samples from
``--after`` (s; 2.5 ms: past the direct path) of all microphones are compared:

    residual = 10 log10( sum (new - base)^2 / sum base^2 )   over those samples

    python -m benchmarks.echo_residual --base /path/to/old/checkout [--poses 16]
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "corridor.toml"
#: the ground truth's fields compared (those of every corridor recording)
FIELDS = (
    "position_world_m",
    "amplitude",
    "delay_s",
    "arrival_sensor",
    "apparent_position_sensor_m",
    "apparent_position_world_m",
    "first_point_m",
    "last_point_m",
    "object_index",
    "velocity_world_m_s",
)


def worker(scene_path: str, first: int, count: int, out: str) -> None:
    """Make the poses with noise off; pickle their samples and truth fields to `out`."""
    import dataclasses

    import acousim
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    print(f"{acousim.__file__}", file=sys.stderr)
    scene = load_scene(scene_path)
    sim_settings = dataclasses.replace(scene.simulation, snr_db=float("inf"))
    sim = Simulator(dataclasses.replace(scene, simulation=sim_settings))
    recs = sim.run(list(range(first, first + count)), processes=1)
    truth = [{k: getattr(r.truth, k) for k in FIELDS} | {"kind": r.truth.kind} for r in recs]
    fs = scene.sensor.sample_rate_hz
    with open(out, "wb") as f:
        pickle.dump({"samples": np.stack([r.samples for r in recs]), "truth": truth, "fs": fs}, f)


def _made(checkout: Path, scene: Path, first: int, count: int, out: Path) -> dict:
    """The pickled run of `checkout`: this file run as a script (its folder first on
    the path, no package there), the checkout on PYTHONPATH, from the checkout."""
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    me = Path(__file__).resolve()
    args = [str(scene), str(first), str(count), str(out)]
    subprocess.run([sys.executable, str(me), "--worker", *args], env=env, cwd=checkout, check=True)
    with open(out, "rb") as f:
        return pickle.load(f)


def compare(base: dict, new: dict, after_s: float) -> list[str]:
    """The lines of the report: the residual (dB re the echoes) and per field the
    largest difference over the poses."""
    k = int(round(after_s * base["fs"]))
    b, n = base["samples"][..., k:], new["samples"][..., k:]
    err = np.sum((n - b) ** 2)
    res = 10 * np.log10(err / np.sum(b**2)) if err > 0 else -np.inf
    same = np.array_equal(base["samples"], new["samples"])
    lines = [
        f"waveform residual from {after_s * 1e3:.1f} ms on, all microphones, "
        f"{len(b)} poses: {res:.1f} dB re the echoes' energy (bit-identical: {same})"
    ]
    for key in (*FIELDS, "kind"):
        worst = 0.0
        for tb, tn in zip(base["truth"], new["truth"]):
            x, y = tb[key], tn[key]
            if x is None or y is None or x.shape != y.shape:
                worst = np.nan if (x is None) != (y is None) or x.shape != y.shape else worst
                continue
            if x.dtype.kind in "US":
                worst = max(worst, float(np.sum(x != y)))
            else:
                d = np.abs(np.asarray(x, float) - np.asarray(y, float))
                d = d[~(np.isnan(np.asarray(x, float)) & np.isnan(np.asarray(y, float)))]
                worst = max(worst, float(d.max(initial=0.0)))
        lines.append(f"  {key}: largest difference {worst:.3g}")
    return lines


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, required=True, help="checkout to compare against")
    ap.add_argument("--new", type=Path, default=ROOT, help="checkout compared (this one)")
    ap.add_argument("--scene", type=Path, default=SCENE)
    ap.add_argument("--first", type=int, default=10)
    ap.add_argument("--poses", type=int, default=16)
    ap.add_argument("--after", type=float, default=2.5e-3, help="s: samples compared from")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        runs = [
            _made(c.resolve(), a.scene.resolve(), a.first, a.poses, Path(tmp) / f"{i}.pkl")
            for i, c in enumerate((a.base, a.new))
        ]
    print("\n".join(compare(*runs, a.after)))


if __name__ == "__main__":
    if sys.argv[1:2] == ["--worker"]:
        worker(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5])
    else:
        main()
