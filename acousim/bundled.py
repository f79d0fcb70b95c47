"""The scenes and dataset specs that come with acousim, found where they are.

In the source tree they are the top-level ``scenes/`` and ``datasets/`` folders; a
built wheel carries copies of them as package data, ``acousim/_data/scenes`` and
``acousim/_data/datasets`` (``setup.py`` copies them at build time, so the source
tree keeps one copy), read through :mod:`importlib.resources`.  A scene is named by
its file name without ``.toml`` (``corridor``); relative paths inside a scene
(meshes, trajectories) and a spec (``../scenes/corridor.toml``) work in both places.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Literal

from processing.base.errors import InputError, did_you_mean

__all__ = [
    "Kind",
    "data_dir",
    "scene_files",
    "bundled_names",
    "find_bundled",
    "find_scene",
    "resolve",
    "resolve_scene",
    "version",
]

Kind = Literal["scenes", "datasets"]
KINDS: tuple[Kind, ...] = ("scenes", "datasets")


def data_dir(kind: Kind) -> Path:
    """The folder of the bundled `kind` ("scenes" or "datasets"): the installed
    package's data, else the source tree's folder."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    packaged = resources.files("acousim") / "_data" / kind
    if packaged.is_dir():
        return Path(str(packaged))
    source = Path(__file__).resolve().parent.parent / kind
    if source.is_dir():
        return source
    raise FileNotFoundError(
        f"the bundled {kind} are neither in the installed package ({packaged}) nor in "
        f"a source tree ({source}): reinstall acousim"
    )


def scene_files() -> list[Path]:
    """Every bundled scene file, sorted by name."""
    return sorted(data_dir("scenes").glob("*.toml"))


def bundled_names(kind: Kind) -> list[str]:
    """The names of the bundled scenes or dataset specs (file names without .toml)."""
    return sorted(p.stem for p in data_dir(kind).glob("*.toml"))


def find_bundled(kind: Kind, name: str) -> Path | None:
    """The bundled scene or dataset spec called `name` (``"corridor"`` or
    ``"corridor.toml"``), or None; a name with a folder in it is never bundled."""
    if not name or "/" in name or "\\" in name:
        return None
    stem = name[:-5] if name.endswith(".toml") else name
    path = data_dir(kind) / f"{stem}.toml"
    return path if path.is_file() else None


def find_scene(name: str) -> Path | None:
    """The bundled scene called `name`, or None."""
    return find_bundled("scenes", name)


def resolve(kind: Kind, text: str | Path) -> Path:
    """A scene (or dataset spec) argument -> a path: an existing file as given, else a
    bundled one of that name.  Neither: an InputError naming the argument once, with
    the bundled name to use when the file name is a bundled one
    (``scenes/wall.toml`` outside the source tree) or a near miss (``corridr``)."""
    path = Path(text)
    if path.is_file():
        return path
    found = find_bundled(kind, str(text))
    if found is not None:
        return found
    raise InputError(_not_found(kind, path), file=str(text))


def _not_found(kind: Kind, path: Path) -> str:
    """Why `path` is neither a file nor a bundled name, and what to type instead."""
    what = "scene" if kind == "scenes" else "dataset spec"
    names = bundled_names(kind)
    stem = path.name[:-5] if path.name.endswith(".toml") else path.name
    folder = len(path.parts) > 1
    if folder and stem in names:
        return (
            f"no such file; a bundled {what} has that file name: give {stem!r} "
            "(bundled names work from any folder)"
        )
    close = did_you_mean(stem, names)
    if close is not None:
        return f"no such file, nor a bundled {what} of that name; did you mean {close!r}?"
    listing = "acousim scenes lists them" if kind == "scenes" else ", ".join(names)
    return f"no such file, nor a bundled {what} of that name (bundled: {listing})"


def resolve_scene(text: str | Path) -> Path:
    """:func:`resolve` for scenes (``acousim simulate corridor``)."""
    return resolve("scenes", text)


def version() -> str:
    """acousim's version: the installed distribution's, else "unknown"."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as _version

    try:
        return _version("acousim")
    except PackageNotFoundError:
        return "unknown (not installed)"
