"""The recording file: bytes per pose and read/write times for float64, float32 and
float32 + gzip, and reading one recording against reading the whole file."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

import processing as P

from .timing import run_times

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"


def run(poses: int = 60) -> str:
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    scene = load_scene(SCENE)
    recs = Simulator(scene, threads=2).run(range(min(poses, len(scene.sensor.poses))))
    n = len(recs)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.h5"
        for label, kw in (
            ("float64, no checksum (schema 1's layout)", {"dtype": np.float64, "checksum": False}),
            ("float32 + fletcher32 (default)", {}),
            ("float32 + fletcher32 + gzip", {"compression": "gzip"}),
        ):
            write = run_times(lambda kw=kw: P.save_recordings(path, recs, **kw), repeat=3)
            size = path.stat().st_size
            one = run_times(lambda: P.load_recording(path, n - 1), repeat=5)
            every = run_times(lambda: P.load_recordings(path), repeat=3)
            rows.append(
                f"| {label} | {size / n / 1e6:.2f} | {size / 1e6:.0f} | "
                f"{np.median(write):.2f} | {np.median(one) * 1e3:.1f} | {np.median(every):.2f} |"
            )
    r = recs[0]
    return "\n".join(
        [
            f"## Recording files: the corridor drive, {n} poses",
            "",
            f"uRTIS, {r.array.n_mics} mics x {r.n_samples} samples, {len(r.truth)} ground-"
            "truth paths a pose. Median times; `one` is `load_recording(path, last)`, "
            "`all` is `load_recordings(path)` (both validate every field).",
            "",
            "| samples | MB per pose | MB file | write (s) | read one (ms) | read all (s) |",
            "|---|---|---|---|---|---|",
            *rows,
            "",
        ]
    )
