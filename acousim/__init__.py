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
refuses a misspelled key (:mod:`processing.base.api`).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys

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
    "Diffraction",
    "Lidar",
    "Pose",
    "Trajectory",
    "SceneError",
    "ImagingOptions",
    "image_recordings",
    "peak_table",
]

_ELSEWHERE = {
    "Simulator": "acousim.simulator",
    "RigSimulator": "acousim.rig",
    **{name: "acousim.scene.rig" for name in ("Rig", "RigSonar", "Mount", "Firing")},
    "Lidar": "acousim.scene.lidar",
    "ImagingOptions": "acousim.imaging",
    "image_recordings": "acousim.imaging",
    "peak_table": "acousim.imaging",
}
_WHERE = _ELSEWHERE | {name: "acousim.scene" for name in __all__ if name not in _ELSEWHERE}

#: a type checker reads the names from their modules (mypy and pyright take the
#: name itself as the flag; at run time the names load on first use, below)
TYPE_CHECKING = False
if TYPE_CHECKING:
    from acousim.imaging.run import ImagingOptions, image_recordings, peak_table
    from acousim.rig import RigSimulator
    from acousim.scene import (
        Diffraction,
        Environment,
        Material,
        MeshItem,
        PointItem,
        Pose,
        Scene,
        SceneError,
        Sensor,
        Simulation,
        Trajectory,
        load_scene,
        parse_scene,
    )
    from acousim.scene.lidar import Lidar
    from acousim.scene.rig import Firing, Mount, Rig, RigSonar
    from acousim.simulator import Simulator


#: the modules' names before the re-layout by concept (CHANGELOG): they keep importing,
#: with a DeprecationWarning, once `processing` (which every module imports) is loaded
_MOVED = {
    "acousim.calibrate.settings": "acousim.calibrate.options",
    "acousim.compare_inputs": "acousim.compare.inputs",
    "acousim.core.delays": "acousim.core.rendering",
    "acousim.compare_summary": "acousim.compare.summary",
    "acousim.matching": "acousim.imaging.matching",
    "acousim.outputs": "acousim.imaging.outputs",
    "acousim.synth.echoes": "acousim.synth.point_reflectors",
    "acousim.synth.model": "acousim.synth.signal_model",
    "acousim.trace._bound_kernel": "acousim.trace.diffraction.bound_kernel",
    "acousim.trace._pair_kernel": "acousim.trace.diffraction.pair_kernel",
    "acousim.trace.btm": "acousim.trace.diffraction.btm",
    "acousim.trace.btm_pair_geometry": "acousim.trace.diffraction.pair_geometry",
    "acousim.trace.btm_pairs": "acousim.trace.diffraction.pairs",
    "acousim.trace.btm_pairs_compiled": "acousim.trace.diffraction.pairs_compiled",
    "acousim.trace.budget": "acousim.trace.rays.budget",
    "acousim.trace.cluster": "acousim.trace.rays.cluster",
    "acousim.trace.diffracted": "acousim.trace.diffraction.paths",
    "acousim.trace.diffraction_setup": "acousim.trace.diffraction.setup",
    "acousim.trace.edge_reflected": "acousim.trace.diffraction.edge_reflected",
    "acousim.trace.edge_to_edge": "acousim.trace.diffraction.edge_to_edge",
    "acousim.trace.edges": "acousim.trace.world.edges",
    "acousim.trace.embree": "acousim.trace.world.embree",
    "acousim.trace.first_order": "acousim.trace.diffraction.first_order",
    "acousim.trace.following": "acousim.trace.motion.following",
    "acousim.trace.geometry": "acousim.trace.world.build",
    "acousim.trace.glints": "acousim.trace.rays.glints",
    "acousim.trace.mesh_index": "acousim.trace.world.mesh_index",
    "acousim.trace.moving": "acousim.trace.motion.moving_world",
    "acousim.trace.pair_bound": "acousim.trace.diffraction.pair_bound",
    "acousim.trace.scatter": "acousim.trace.rays.scatter",
    "acousim.trace.settings": "acousim.trace.options",
    "acousim.trace.shoot": "acousim.trace.rays.shoot",
    "acousim.trace.specular": "acousim.trace.rays.specular",
}


def __getattr__(name: str) -> object:  # (no typing import: the command line starts fast)
    if name == "__version__":  # the installed distribution's, as `acousim --version`
        from acousim.bundled import version

        return version()
    if name in _WHERE:
        from processing.base.api import check_keywords

        space = {name: getattr(importlib.import_module(_WHERE[name]), name)}
        check_keywords(space, [name])  # a misspelled keyword: the scene file's answer
        globals()[name] = space[name]
        return space[name]
    if not name.startswith("_") and importlib.util.find_spec(f"acousim.{name}") is not None:
        return importlib.import_module(f"acousim.{name}")  # a subpackage, on first use
    raise AttributeError(f"module 'acousim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])


class _Moved:
    """Answers acousim's old module names (:data:`_MOVED`) through
    :mod:`processing.base.moved`, imported only when an old name is asked for (``import
    acousim`` stays light)."""

    @staticmethod
    def find_spec(fullname, path=None, target=None):
        if fullname not in _MOVED:
            return None
        from processing.base.moved import moved_spec

        return moved_spec(fullname, _MOVED)


if _Moved not in sys.meta_path:
    sys.meta_path.append(_Moved)
