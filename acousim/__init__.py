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
command line starts fast).
"""

from __future__ import annotations

import importlib

__all__ = [
    "Simulator",
    "RigSimulator",
    "Rig",
    "RigSonar",
    "Mount",
    "Firing",
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
]

_WHERE = (
    {"Simulator": "acousim.simulator", "RigSimulator": "acousim.rig"}
    | {name: "acousim.scene.rig" for name in ("Rig", "RigSonar", "Mount", "Firing")}
    | {name: "acousim.scene" for name in __all__[6:]}
)


def __getattr__(name: str) -> object:  # (no typing import: the command line starts fast)
    if name in _WHERE:
        value = getattr(importlib.import_module(_WHERE[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'acousim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
