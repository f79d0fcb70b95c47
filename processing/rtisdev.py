"""Files from CoSys-Lab's public ``rtisdev`` wheel, fetched at run time, never bundled.

The wheel (version 2.15.1 on PyPI) carries the microphone layouts of the real
sensors and one raw eRTIS measurement.  Its license (CC BY-NC-SA 4.0) forbids
redistributing those files inside this project, so they are downloaded with
``pip download`` into a cache outside the repository (``$ACOUSIM_CACHE``, else
``$XDG_CACHE_HOME/acousim``, else ``~/.cache/acousim``) and read from there.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

__all__ = ["cache_dir", "wheel_path", "layout_file", "sample_recording", "SAMPLE_SHA256"]

VERSION = "2.15.1"
#: sha256 of ``rtisdev/simulate.bin`` (a raw eRTIS v3D1 measurement, 163840 tick words).
SAMPLE_SHA256 = "d5558295dfaa6f15c7815a4ddff461d8887e842cac0c18763cd736c26e11df0f"


def cache_dir() -> Path:
    """The folder where fetched third-party files are kept."""
    root = os.environ.get("ACOUSIM_CACHE")
    if root:
        return Path(root)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "acousim"


def wheel_path() -> Path:
    """Path of the rtisdev wheel in the cache, downloading it with pip if needed."""
    folder = cache_dir() / f"rtisdev-{VERSION}"
    found = sorted(folder.glob("rtisdev-*.whl"))
    if found:
        return found[0]
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        cmd = [
            sys.executable,
            "-m",
            "pip",
            "download",
            f"rtisdev=={VERSION}",
            "--no-deps",
            "--quiet",
            "-d",
            tmp,
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wheels = sorted(Path(tmp).glob("rtisdev-*.whl"))
        if proc.returncode != 0 or not wheels:
            raise RuntimeError(
                f"could not download rtisdev=={VERSION} with pip (exit {proc.returncode}): "
                f"{proc.stderr.strip()[-500:]}"
            )
        target = folder / wheels[0].name
        os.replace(wheels[0], target)
    return target


def _extract(member: str) -> Path:
    """Extract one member of the wheel into the cache (atomically) and return its path."""
    target = cache_dir() / f"rtisdev-{VERSION}" / "files" / member
    if target.is_file():
        return target
    with zipfile.ZipFile(wheel_path()) as zf:
        try:
            data = zf.read(member)
        except KeyError:
            raise FileNotFoundError(f"{member} is not in the rtisdev {VERSION} wheel") from None
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.part")  # one per process
    tmp.write_bytes(data)
    os.replace(tmp, target)
    return target


def layout_file(sensor: str) -> Path:
    """The ``mic_coordinates.mat`` of a sensor (e.g. ``"eRTIS_v3D1"``, ``"uRTIS_v1"``)."""
    return _extract(f"rtisdev/config/microphoneLayouts/{sensor}/mic_coordinates.mat")


def sample_recording() -> Path:
    """The raw eRTIS v3D1 measurement ``simulate.bin``, its sha256 checked."""
    path = _extract("rtisdev/simulate.bin")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if digest != SAMPLE_SHA256:
        path.unlink()
        raise RuntimeError(f"{path}: sha256 {digest} does not match the expected {SAMPLE_SHA256}")
    return path
