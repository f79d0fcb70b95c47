"""Files from CoSys-Lab's public ``rtisdev`` wheel, fetched at run time, never bundled.

The wheel (version 2.15.1 on PyPI) carries the microphone layouts of the real
sensors and one raw eRTIS measurement.  Its license (CC BY-NC-SA 4.0) forbids
redistributing those files inside this project, so they are downloaded with
``pip download`` into a cache outside the repository (``$ACOUSIM_CACHE``, else
``$XDG_CACHE_HOME/acousim``, else ``~/.cache/acousim``) and read from there.

Every file is checked, every time it is used:

1. the wheel is downloaded with ``pip download --require-hashes`` against the pinned
   :data:`WHEEL_SHA256` (PyPI's digest of rtisdev-2.15.1-py3-none-any.whl) and its
   sha256 is checked again when a process first opens it from the cache (and
   whenever it has changed since);
2. a file taken from it is checked against the digest the verified wheel's own
   ``RECORD`` lists for it, when it is extracted and whenever it is read from the
   cache; ``simulate.bin`` also against its own pinned :data:`SAMPLE_SHA256`.

A mismatch raises :class:`IntegrityError` naming the file and both digests and the
file is never used: delete the cache folder to fetch it again.
"""

from __future__ import annotations

import base64
import csv
import hashlib
import io
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from processing.base.atomic import committed_together, write_bytes

__all__ = [
    "cache_dir",
    "wheel_path",
    "layout_file",
    "sample_recording",
    "IntegrityError",
    "SAMPLE_SHA256",
    "WHEEL_SHA256",
]

VERSION = "2.15.1"
#: sha256 of ``rtisdev-2.15.1-py3-none-any.whl`` as published on PyPI.
WHEEL_SHA256 = "adf512f6d0504bbbceb1b2be97ca607343bd9045f365ae4a28f740220531b208"
#: sha256 of ``rtisdev/simulate.bin`` (a raw eRTIS v3D1 measurement, 163840 tick words).
SAMPLE_SHA256 = "d5558295dfaa6f15c7815a4ddff461d8887e842cac0c18763cd736c26e11df0f"


def cache_dir() -> Path:
    """The folder where fetched third-party files are kept."""
    root = os.environ.get("ACOUSIM_CACHE")
    if root:
        return Path(root)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "acousim"


class IntegrityError(RuntimeError):
    """A fetched or cached third-party file is not the one that was pinned."""


#: wheels verified in this process: (path, mtime_ns, size, inode) -> sha256.  Hashing
#: the 4.6 MB wheel on every use cost about 25 ms per layout; it is hashed once per
#: process and again when it changes.  The small files taken from it are hashed on
#: every use.
_verified: dict[tuple[str, int, int, int], str] = {}


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _check(path: Path, expected: str, what: str, *, once: bool = False) -> Path:
    """`path` if its sha256 is `expected`, else IntegrityError; with `once`, a file
    already verified in this process and unchanged since is not hashed again."""
    st = path.stat()
    key = (str(path), st.st_mtime_ns, st.st_size, st.st_ino)
    if once and _verified.get(key) == expected:
        return path
    digest = _sha256(path)
    if digest == expected:
        if once:
            _verified[key] = digest
    else:
        raise IntegrityError(
            f"{path}: sha256 {digest} is not the expected {expected} ({what}); the file "
            f"is not used: delete {cache_dir()} to fetch it again"
        )
    return path


def wheel_path() -> Path:
    """Path of the rtisdev wheel in the cache (its sha256 checked), downloading it with
    pip (``--require-hashes``) if needed."""
    folder = cache_dir() / f"rtisdev-{VERSION}"
    found = sorted(folder.glob("rtisdev-*.whl"))
    if found:
        return _check(found[0], WHEEL_SHA256, f"the pinned rtisdev {VERSION} wheel", once=True)
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        req = Path(tmp) / "requirements.txt"
        req.write_text(f"rtisdev=={VERSION} --hash=sha256:{WHEEL_SHA256}\n")
        cmd = [
            sys.executable,
            "-m",
            "pip",
            "download",
            "--no-deps",
            "--require-hashes",
            "--quiet",
            "-r",
            str(req),
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
        _check(wheels[0], WHEEL_SHA256, f"the pinned rtisdev {VERSION} wheel")
        target = folder / wheels[0].name
        os.replace(wheels[0], target)
    return target


def _record_digest(zf: zipfile.ZipFile, member: str) -> str:
    """The sha256 (hex) that the wheel's RECORD lists for `member`."""
    record = next(n for n in zf.namelist() if n.endswith(".dist-info/RECORD"))
    for row in csv.reader(io.TextIOWrapper(zf.open(record), "utf-8")):
        if row and row[0] == member and len(row) > 1:
            algo, _, b64 = row[1].partition("=")
            if algo != "sha256":
                break
            return base64.urlsafe_b64decode(b64 + "=" * (-len(b64) % 4)).hex()
    raise IntegrityError(f"{member}: the rtisdev {VERSION} wheel's RECORD has no sha256 for it")


def _extract(member: str) -> Path:
    """One member of the verified wheel, extracted into the cache (atomically) once and
    checked against the wheel's RECORD whenever it is used."""
    target = cache_dir() / f"rtisdev-{VERSION}" / "files" / member
    with zipfile.ZipFile(wheel_path()) as zf:
        try:
            expected = _record_digest(zf, member)
        except StopIteration:
            raise IntegrityError(f"the rtisdev {VERSION} wheel has no RECORD") from None
        if not target.is_file():
            try:
                data = zf.read(member)
            except KeyError:
                raise FileNotFoundError(f"{member} is not in the rtisdev {VERSION} wheel") from None
            if hashlib.sha256(data).hexdigest() != expected:
                raise IntegrityError(f"{member}: does not match the wheel's RECORD")
            target.parent.mkdir(parents=True, exist_ok=True)
            # in place now, even inside a command's group of outputs renamed together
            # at its end (`acousim compare rtisdev-sample`): the cache is not an output
            with committed_together():
                write_bytes(target, data)
    return _check(target, expected, f"the rtisdev {VERSION} wheel's RECORD")


def layout_file(sensor: str) -> Path:
    """The ``mic_coordinates.mat`` of a sensor (e.g. ``"eRTIS_v3D1"``, ``"uRTIS_v1"``)."""
    return _extract(f"rtisdev/config/microphoneLayouts/{sensor}/mic_coordinates.mat")


def sample_recording() -> Path:
    """The raw eRTIS v3D1 measurement ``simulate.bin``, its sha256 checked."""
    return _check(_extract("rtisdev/simulate.bin"), SAMPLE_SHA256, "the pinned eRTIS sample")
