"""Scene files: format, validation, materials and poses."""

from acousim.scene.load import SceneError, load_scene, parse_scene
from acousim.scene.model import (
    Diffraction,
    Environment,
    Material,
    MeshItem,
    PointItem,
    Scene,
    Sensor,
    Simulation,
)
from acousim.scene.pose import Pose, rotation
from acousim.scene.trajectory import Trajectory

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
    "Diffraction",
    "Pose",
    "Trajectory",
    "rotation",
]

from processing.base.api import check_keywords  # noqa: E402

# a misspelled keyword of Sensor(...), Material(...), ...: the scene file's answer
check_keywords(globals(), __all__)
