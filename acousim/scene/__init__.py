"""Scene files: format, validation, materials and poses."""

from .load import SceneError, load_scene, parse_scene
from .model import Environment, Material, MeshItem, PointItem, Scene, Sensor, Simulation
from .pose import Pose, rotation
from .trajectory import Trajectory

__all__ = [
    "SceneError",
    "load_scene",
    "parse_scene",
    "Environment",
    "Material",
    "MeshItem",
    "PointItem",
    "Scene",
    "Sensor",
    "Simulation",
    "Pose",
    "Trajectory",
    "rotation",
]

from processing.api import check_keywords  # noqa: E402

# a misspelled keyword of Sensor(...), Material(...), ...: the scene file's answer
check_keywords(globals(), __all__)
