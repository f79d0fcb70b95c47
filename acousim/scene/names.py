"""What a scene file names, resolved to objects in one place: the scene loader and the
Python constructors (``acousim.Sensor(array="urtis_v1", call="paper", lidar="vlp16")``,
``acousim.MeshItem(..., material="plaster")``) both call these, so a name means the
same object, and a wrong name gets the same answer (did-you-mean, the choices), on
both paths. Each takes the name or the object itself (returned unchanged).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import processing as P
from acousim.scene.lidar import LIDAR_PRESETS, PRESET, Lidar
from processing.base.errors import InputError
from processing.base.settings import Setting, check

__all__ = [
    "array_named",
    "call_named",
    "lidar_named",
    "material_named",
    "scene_materials",
    "with_emitter",
]


def array_named(value: Any, key: str = "Sensor.array") -> P.Array:
    """An array preset by name (:data:`processing.PRESETS`), or a processing.Array."""
    return _named(value, P.Array, P.PRESETS, _array, key)


def _array(name: str) -> P.Array:
    try:
        return P.preset(name)
    except (OSError, ValueError) as exc:  # ertis_v3d1 offline, a damaged cached layout
        raise InputError(f"cannot load the preset ({exc})", value=name) from None


def with_emitter(array: P.Array, emitter_m: Any, key: str = "Sensor.emitter_m") -> P.Array:
    """`array` with its emitter at `emitter_m` ((3,) m, sensor frame: the scene file's
    ``emitter_m``); None: `array` as it is.  The array's own check of the emitter
    (finite, within ±10 m) raises keyed `key`."""
    if emitter_m is None:
        return array
    try:
        return dataclasses.replace(array, emitter_m=emitter_m)
    except InputError as exc:
        raise InputError(exc.reason, key=key, value=emitter_m) from None


def call_named(value: Any, key: str = "Sensor.call") -> P.Waveform:
    """A call by name (:data:`processing.CALLS`), or a processing.Waveform."""
    return _named(value, P.Waveform, P.CALLS, P.named_call, key)


def lidar_named(value: Any, key: str = "Sensor.lidar"):
    """A LiDAR preset by name (:data:`acousim.scene.lidar.LIDAR_PRESETS`, the scene
    file's ``[sensor.lidar] preset``), a Lidar, or None (no LiDAR)."""
    if value is None:
        return None
    return _named(value, Lidar, PRESET.choices or (), LIDAR_PRESETS.__getitem__, key)


def _named(value: Any, kind: type, choices: Iterable[str], make: Callable[[str], Any], key: str):
    """`value` if it is a `kind`, else the object `make` gives for a name among
    `choices` (the scene loader's answer to any other name or value)."""
    if isinstance(value, kind):
        return value
    if not isinstance(value, str):
        what = f"{kind.__module__.split('.')[0]}.{kind.__name__}"
        raise InputError(f"must be a name ({', '.join(choices)}) or a {what}", key=key, value=value)
    _one_of(value, choices, key)
    try:
        return make(value)
    except InputError as exc:
        raise InputError(exc.reason, key=key, value=value) from None


def material_named(value: Any, materials: Mapping[str, Any], key: str):
    """A material by name among `materials` ({name: Material}, ``default`` among
    them); anything else as it is (a Material: :class:`MeshItem` checks)."""
    if not isinstance(value, str):
        return value
    _one_of(value, materials, key)
    return materials[value]


def _one_of(value: str, choices: Iterable[str], key: str) -> None:
    """The scene loader's answer to a name not among `choices`: "is not one of ...;
    did you mean ...?" (:func:`processing.base.settings.check`)."""
    check(Setting("str", choices=tuple(choices)), value, key)


def scene_materials(given: Any, meshes: tuple, material: Any) -> tuple[dict[str, Any], tuple]:
    """A scene's materials by name (`given`: {name: Material} or a list, as a scene
    file's ``[[materials]]``; ``default`` and the meshes' own added) and its `meshes`
    with every material given by name replaced by the scene's. `material`: the
    Material class (this module does not import the model)."""
    by_name = (
        dict(given) if isinstance(given, Mapping) else {getattr(m, "name", m): m for m in given}
    )
    for name, mat in by_name.items():
        if not isinstance(mat, material):
            raise InputError("must hold Materials", key=f"Scene.materials[{name!r}]", value=mat)
    materials: dict[str, Any] = {"default": material("default"), **by_name}
    for m in meshes:
        for mat in (m.material, *m.materials.values()):
            if isinstance(mat, material):
                materials.setdefault(mat.name, mat)
    return materials, tuple(
        _mesh_named(m, materials, f"Scene.meshes[{i}]") for i, m in enumerate(meshes)
    )


def _mesh_named(mesh: Any, materials: Mapping[str, Any], key: str) -> Any:
    """The mesh (a MeshItem) with its materials given by name replaced by the scene's."""
    if not any(isinstance(m, str) for m in (mesh.material, *mesh.materials.values())):
        return mesh
    return dataclasses.replace(
        mesh,
        material=material_named(mesh.material, materials, f"{key}.material"),
        materials={
            g: material_named(m, materials, f"{key}.materials[{g!r}]")
            for g, m in mesh.materials.items()
        },
    )
