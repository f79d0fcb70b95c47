"""Dataset specs over the bundled wall's mesh, written where a test asks."""

from __future__ import annotations

from pathlib import Path

from acousim.bundled import resolve

WALL_MESH = resolve("scenes", "wall").parent / "meshes" / "wall.stl"


def wall_spec(folder: Path, scene: str, spec: str | None = None) -> Path:
    """`scene` (its ``{mesh}`` the bundled wall's STL) written to `folder`/wall.toml
    and `spec` (if given) to `folder`/spec.toml; returns the spec's path."""
    (folder / "wall.toml").write_text(scene.format(mesh=WALL_MESH.as_posix()))
    if spec is not None:
        (folder / "spec.toml").write_text(spec)
    return folder / "spec.toml"
