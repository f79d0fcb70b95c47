"""Run every benchmark section and rewrite BENCHMARKS.md (``make bench``)."""

from __future__ import annotations

import datetime
import os
import platform
import sys
from pathlib import Path

from processing.base.atomic import write_text

from . import (
    array_calibration,
    broadband,
    calibration,
    corridor,
    dataset,
    diffraction,
    doa_speed,
    fractional_delay,
    front,
    materials,
    motion,
    pdm_decode,
    peer,
    pictures,
    recording_file,
    rig,
    scaling,
)
from .fullwave import compare as fullwave

SECTIONS = {
    "doa": doa_speed,
    "broadband": broadband,
    "fractional_delay": fractional_delay,
    "corridor": corridor,
    "pdm_decode": pdm_decode,
    "dataset": dataset,
    "pictures": pictures,
    "recording_file": recording_file,
    "motion": motion,
    "diffraction": diffraction,
    "materials": materials,
    "calibration": calibration,
    "array_calibration": array_calibration,
    "fullwave": fullwave,
    "peer": peer,
    "scaling": scaling,
    "rig": rig,
    "front": front,
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


def _marker(name: str) -> str:
    return f"<!-- section: {name} -->"


def _previous_sections(path: Path) -> dict[str, str]:
    """Section texts of an existing BENCHMARKS.md, by name (empty when there is none)."""
    if not path.is_file():
        return {}
    text = path.read_text()
    out = {}
    for name in SECTIONS:
        start = text.find(_marker(name))
        if start < 0:
            continue
        end = text.find("<!-- section:", start + 1)
        out[name] = text[start + len(_marker(name)) : end if end >= 0 else len(text)].strip("\n")
    return out


def main(argv: list[str]) -> int:
    from acousim.process import configure

    configure()  # the process's policy, as the command line sets it
    wanted = argv or list(SECTIONS)
    unknown = [w for w in wanted if w not in SECTIONS]
    if unknown:
        print(f"unknown benchmark section(s) {unknown}; choose from {list(SECTIONS)}")
        return 2
    out = Path(__file__).resolve().parent.parent / "BENCHMARKS.md"
    # a partial run replaces its own sections and keeps the others with their dates
    sections = _previous_sections(out)
    now = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
    for name in wanted:
        print(f"running {name} ...", flush=True)
        head, _, rest = SECTIONS[name].run().strip("\n").partition("\n")
        sections[name] = f"{head}\n\n_Run {now} on {machine()}._\n{rest}"
    parts = [
        "# Benchmarks",
        "",
        "Written by `make bench` (`python -m benchmarks [section ...]`); do not edit by hand. "
        "Each section states when and where it ran.",
        "",
    ]
    for name in SECTIONS:
        if name in sections:
            parts += [_marker(name), sections[name], ""]
    write_text(out, "\n".join(parts))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
