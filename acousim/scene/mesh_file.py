"""A mesh file read as it is (no cleaning, no placement): what the world's builder
loads, and what the scene loader measures to catch a mesh in the wrong units.

A file is read once for both: the mesh the loader measured is kept (a few at most)
and handed to the builder's next read of the same, unchanged file (its path, size
and modification time), then forgotten."""

from __future__ import annotations

import os
import threading
from collections import OrderedDict
from pathlib import Path

import numpy as np

__all__ = ["read_mesh", "binary_stl", "placed_extent_m", "MAX_UNITLESS_SPAN_M"]

MAX_UNITLESS_SPAN_M = 1000.0
"""Largest extent (m, along any world axis, once placed) of a mesh whose
``[[meshes]]`` table gives no ``units``: ten times the largest ``max_range_m``
(100 m), so no scene a sonar can hear is refused, while a room or an object of more
than 1 m drawn in millimetres (read as metres: over a kilometre) is."""

#: a binary STL's facet: normal, three corners, attribute
_STL_FACET = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attr", "<u2")])


def binary_stl(path):
    """A binary STL file as trimesh's reader gives it without processing (a corner per
    vertex, float64; the faces 0, 1, 2, ...), read in one numpy view; None for any
    other file (an ASCII STL, another format: trimesh reads it).  A third of the
    shoebox's preparation was trimesh's loader and its normals check."""
    import trimesh

    if not isinstance(path, str | Path) or Path(path).suffix.lower() != ".stl":
        return None
    data = Path(path).read_bytes()
    n = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
    if n <= 0 or len(data) != 84 + n * _STL_FACET.itemsize:  # trimesh's binary test
        return None
    corners = np.frombuffer(data, _STL_FACET, count=n, offset=84)["corners"]
    vertices = corners.reshape(-1, 3).astype(np.float64)
    faces = np.arange(3 * n, dtype=np.int64).reshape(-1, 3)
    return trimesh.Trimesh(vertices, faces, process=False)


def read_mesh(path):
    """A mesh file (any format trimesh reads) as one ``trimesh.Trimesh``, unprocessed
    and the caller's own (the one :func:`placed_extent_m` measured, if the file has
    not changed since, else read now); trimesh's exceptions pass through."""
    key = _file_key(path)
    with _lock:
        mesh = _measured.pop(key, None) if key is not None else None
    return mesh if mesh is not None else _read(path)


def _read(path):
    """The mesh file at `path`, read from the disk."""
    import trimesh

    mesh = binary_stl(path)
    return mesh if mesh is not None else trimesh.load(path, force="mesh", process=False)


#: meshes :func:`placed_extent_m` read, by :func:`_file_key`, until :func:`read_mesh`
#: takes them (the oldest forgotten beyond :data:`_KEPT`: a scene loaded and never
#: built holds no more)
_measured: OrderedDict = OrderedDict()
_KEPT = 8
_lock = threading.Lock()


def _file_key(path) -> tuple | None:
    """(resolved path, size, modification time in ns) of a mesh file; None for a
    mesh in memory or a file that cannot be looked at."""
    if not isinstance(path, str | Path):
        return None
    try:
        st = os.stat(path)
        return (str(Path(path).resolve()), st.st_size, st.st_mtime_ns)
    except (OSError, ValueError):
        return None


def placed_extent_m(path, transform: np.ndarray) -> np.ndarray | None:
    """The extent (3,) along world x, y, z (m) of the mesh file at `path` placed by
    `transform` (4, 4); None when it cannot be read or has no finite vertices (the
    world's builder then says why).  The mesh read is kept for the builder
    (:func:`read_mesh`)."""
    key = _file_key(path)  # before reading: a file changed meanwhile is read again
    try:
        mesh = _read(path)
    except Exception:  # trimesh raises many kinds; the builder reports them
        return None
    if key is not None:
        with _lock:
            _measured[key] = mesh
            while len(_measured) > _KEPT:
                _measured.popitem(last=False)
    vertices = np.asarray(mesh.vertices, float)
    if not len(vertices) or not np.all(np.isfinite(vertices)):
        return None
    with np.errstate(over="ignore", invalid="ignore"):  # a huge scale: inf, refused
        placed = vertices @ np.asarray(transform, float)[:3, :3].T
        return placed.max(axis=0) - placed.min(axis=0)
