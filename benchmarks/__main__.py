"""Run every benchmark section and rewrite BENCHMARKS.md (``make bench``)."""

from __future__ import annotations

import datetime
import os
import platform
import sys
from pathlib import Path

from . import corridor, dataset, doa_speed, fractional_delay, pdm_decode

SECTIONS = {
    "doa": doa_speed,
    "fractional_delay": fractional_delay,
    "corridor": corridor,
    "pdm_decode": pdm_decode,
    "dataset": dataset,
}


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numpy
    import scipy

    return (
        f"{cpu}, {os.cpu_count()} cores; Python {platform.python_version()}, "
        f"numpy {numpy.__version__}, scipy {scipy.__version__}"
    )


def main(argv: list[str]) -> int:
    wanted = argv or list(SECTIONS)
    unknown = [w for w in wanted if w not in SECTIONS]
    if unknown:
        print(f"unknown benchmark section(s) {unknown}; choose from {list(SECTIONS)}")
        return 2
    parts = [
        "# Benchmarks",
        "",
        "Written by `make bench` (`python -m benchmarks`); do not edit by hand.",
        "",
        f"- date: {datetime.datetime.now().strftime('%Y-%m-%d %H:%M')}",
        f"- machine: {machine()}",
        "",
    ]
    for name in wanted:
        print(f"running {name} ...", flush=True)
        parts.append(SECTIONS[name].run())
    out = Path(__file__).resolve().parent.parent / "BENCHMARKS.md"
    tmp = out.with_suffix(".md.part")
    tmp.write_text("\n".join(parts))
    os.replace(tmp, out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
