"""A benchmark script run in alternating processes, one per checkout.

Each round runs the script once per checkout (its root first on ``PYTHONPATH``, so
the process imports that checkout's code), the order swapped every other round: a
shared machine's drift falls on both sides alike.  Used by
:mod:`benchmarks.scene_cost` and :mod:`benchmarks.stages` (``--base DIR``).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent.parent


def stdout_of(root: Path, script: Path, args: list[str]) -> str:
    """What `script` prints when run with `args` in a process importing the checkout
    `root`'s code (one thread for BLAS, as the command line configures it)."""
    env = {**os.environ, "PYTHONPATH": str(root), "OPENBLAS_NUM_THREADS": "1"}
    cmd = [sys.executable, str(script), *args]
    return subprocess.run(cmd, cwd=root, env=env, check=True, capture_output=True, text=True).stdout


def stage_fields(line: str) -> dict[str, float]:
    """``"name a 1.2 | b+c 3.4 ..."`` -> ``{"a": 1.2, "b+c": 3.4}``."""
    return {k: float(v) for k, v in re.findall(r"([a-z+]+) ([0-9.]+)", line)}


def alternate(script: Path, args: list[str], base: Path, rounds: int) -> dict[str, list[str]]:
    """The stdout of `rounds` runs of `script` on each side ("base": the checkout
    `base`, "now": this tree), alternating."""
    runs: dict[str, list[str]] = {"base": [], "now": []}
    for r in range(rounds):
        sides = (("base", base), ("now", HERE))
        for label, root in sides if r % 2 == 0 else sides[::-1]:
            runs[label].append(stdout_of(root, script, args))
    return runs


def summary(runs: dict[str, list[dict[str, float]]], stages: tuple[str, ...], name: str) -> str:
    """Medians per stage of each side's rounds and the median (quartiles) of the
    rounds' ratios of the totals, base over now."""
    lines = []
    for label in ("base", "now"):
        med = {k: np.median([r[k] for r in runs[label]]) for k in stages}
        least = min(r["total"] for r in runs[label])
        cells = " | ".join(f"{k} {v:.2f}" for k, v in med.items())
        lines.append(
            f"{name} {label} {cells} ms CPU (medians of {len(runs[label])} rounds; "
            f"least total {least:.2f})"
        )
    ratio = [b["total"] / a["total"] for b, a in zip(runs["base"], runs["now"])]
    q1, q2, q3 = np.percentile(ratio, [25, 50, 75])
    lines.append(f"{name} base / now, total: median {q2:.2f}x (quartiles {q1:.2f}x-{q3:.2f}x)")
    return "\n".join(lines)
