"""acousim: a simulator of active in-air ultrasonic 3D sonars (eRTIS, uRTIS).

Scenes can be files (``load_scene("scenes/corridor.toml")``) or built in code::

    import trimesh
    import acousim

    wall = acousim.MeshItem(trimesh.creation.box((0.1, 4.0, 3.0)),
                            acousim.Material("brick", reflection=0.9), position_m=(2, 0, 0))
    scene = acousim.Scene(meshes=[wall], sensor=acousim.Sensor(),
                          simulation=acousim.Simulation(max_range_m=3.0))
    recordings = acousim.Simulator(scene).run()

The names below are imported on first use, so ``import acousim`` stays light (the
command line starts fast); so are the subpackages (``acousim.process.configure()``,
``acousim.calibrate``, ``acousim.imaging`` ...): ``import acousim`` is enough for all.
Every public constructor and function refuses a misspelled keyword as a scene file
refuses a misspelled key (:mod:`processing.api`).
"""

from __future__ import annotations

import importlib
import importlib.util

__all__ = [
    "Simulator",
    "load_scene",
    "parse_scene",
    "Scene",
    "Sensor",
    "Material",
    "MeshItem",
    "PointItem",
    "Environment",
    "Simulation",
    "Pose",
    "Trajectory",
    "SceneError",
    "ImagingOptions",
    "image_recordings",
    "peak_table",
]

_ELSEWHERE = {
    "Simulator": "acousim.simulator",
    "ImagingOptions": "acousim.imaging",
    "image_recordings": "acousim.imaging",
    "peak_table": "acousim.imaging",
}
_WHERE = _ELSEWHERE | {name: "acousim.scene" for name in __all__ if name not in _ELSEWHERE}


def __getattr__(name: str) -> object:  # (no typing import: the command line starts fast)
    if name in _WHERE:
        from processing.api import check_keywords

        space = {name: getattr(importlib.import_module(_WHERE[name]), name)}
        check_keywords(space, [name])  # a misspelled keyword: the scene file's answer
        globals()[name] = space[name]
        return space[name]
    if not name.startswith("_") and importlib.util.find_spec(f"acousim.{name}") is not None:
        return importlib.import_module(f"acousim.{name}")  # a subpackage, on first use
    raise AttributeError(f"module 'acousim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
