"""The output folder of ``acousim image``: after a run it holds that run's files and
no stale file of ours from an earlier run; the user's own files stay untouched.

Our files are known by name (:func:`is_ours`): ``fan.png``, ``elaz_<method>.png``
for a method of :data:`processing.METHODS`, ``scene3d.png``, ``drive.gif`` (a rig's:
``drive_<sonar>.gif``, letters, digits, '-' and '_'), ``images.h5`` and
``peaks.csv``; with several recordings shown (``--recording``),
``fan_<N>.png``, ``elaz_<method>_<N>.png`` and ``scene3d_<N>.png`` for a recording
index N.  Anything else in the folder is the user's.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import processing as P

__all__ = [
    "OUR_FILES",
    "FolderChanges",
    "file_safe",
    "is_ours",
    "our_files",
    "replaced_kinds",
    "tidy",
]

OUR_FILES = ("fan.png", "scene3d.png", "drive.gif", "images.h5", "peaks.csv")


def is_ours(name: str) -> bool:
    """Whether a file name is one ``acousim image`` writes."""
    if name in OUR_FILES:
        return True
    if name.startswith("drive_") and name.endswith(".gif"):  # a rig's sonar's
        sonar = name[6:-4]
        return bool(sonar) and file_safe(sonar) == sonar
    if not name.endswith(".png"):
        return False
    stem, _, n = name[:-4].rpartition("_")
    if n.isdigit() and n.isascii() and _still(stem):
        return True  # a recording's own picture: fan_3.png, elaz_das_3.png
    return _still(name[:-4])


def _still(stem: str) -> bool:
    """Whether `stem` names one of a recording's pictures: fan, scene3d, elaz_METHOD."""
    return stem in ("fan", "scene3d") or (stem.startswith("elaz_") and stem[5:] in P.METHODS)


def file_safe(name: str) -> str:
    """`name` as part of a file name of ours: every character but ASCII letters,
    digits, '-' and '_' as '_' (a rig's sonar in ``drive_<sonar>.gif``)."""
    return "".join(c if c.isascii() and (c.isalnum() or c in "-_") else "_" for c in name)


def our_files(folder: str | Path) -> set[Path]:
    """Our files now in `folder` (none when it does not exist)."""
    folder = Path(folder)
    if not folder.is_dir():
        return set()
    return {p for p in folder.iterdir() if p.is_file() and is_ours(p.name)}


def replaced_kinds(folder: str | Path) -> dict[str, str]:
    """The files of `folder` a run may replace or remove (:func:`our_files`), each
    with the kind of output its content must be (:data:`acousim.cli.ours.KINDS`)
    for that: {name: "images", "peaks" or "picture"}."""
    kinds = {"images.h5": "images", "peaks.csv": "peaks"}
    return {p.name: kinds.get(p.name, "picture") for p in sorted(our_files(folder))}


@dataclass(frozen=True)
class FolderChanges:
    """What a run did to files of an earlier one: `replaced` (written again) and
    `removed` (not written by this run, so stale), sorted paths."""

    replaced: tuple[Path, ...]
    removed: tuple[Path, ...]

    def lines(self) -> list[str]:
        """What to tell the user (nothing when nothing was there)."""
        out = []
        if self.replaced:
            out.append("replaced from an earlier run: " + ", ".join(p.name for p in self.replaced))
        if self.removed:
            out.append(
                "removed, stale from an earlier run: " + ", ".join(p.name for p in self.removed)
            )
        return out


def tidy(folder: str | Path, before: set[Path], written: Iterable[str | Path]) -> FolderChanges:
    """Remove our files that were in `folder` before the run (`before`, from
    :func:`our_files`) and that the run did not write again; say what was replaced."""
    now = {Path(p).resolve() for p in written}
    replaced = sorted(p for p in before if p.resolve() in now)
    stale = sorted(p for p in before if p.resolve() not in now)
    for p in stale:
        p.unlink(missing_ok=True)
    return FolderChanges(tuple(replaced), tuple(stale))
