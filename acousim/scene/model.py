"""What a scene file describes, as small frozen dataclasses (SI units)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing import Array, Waveform

from .pose import Pose

__all__ = ["Material", "MeshItem", "PointItem", "Sensor", "Environment", "Simulation", "Scene"]


@dataclass(frozen=True)
class Material:
    """How a surface reflects.

    reflection : pressure reflection coefficient (0..1) of the specular part.
    diffuse : fraction of the reflected energy scattered diffusely (Lambert), 0..1.
    lobe_deg : width (standard deviation) of the reflection lobe around the mirror
        direction used on curved surfaces and rough materials.
    """

    name: str
    reflection: float = 0.95
    diffuse: float = 0.0
    lobe_deg: float = 5.0


@dataclass(frozen=True, eq=False)
class MeshItem:
    """A mesh file placed in the world: `transform` (4, 4) maps file units to metres."""

    path: Path
    material: Material
    transform: np.ndarray


@dataclass(frozen=True)
class PointItem:
    """An explicit point reflector (world frame): strength a_k of eq. 1."""

    position_m: tuple[float, float, float]
    strength: float = 1.0


@dataclass(frozen=True)
class Environment:
    temperature_c: float = 20.0
    humidity_percent: float = 50.0
    pressure_kpa: float = 101.325

    @property
    def speed_of_sound_m_s(self) -> float:
        from acousim.synth.air import speed_of_sound

        return speed_of_sound(self.temperature_c, self.humidity_percent)


@dataclass(frozen=True, eq=False)
class Sensor:
    """The sonar: array, emitter, call and sampling, and where it is."""

    array: Array
    call: Waveform
    sample_rate_hz: float
    emitter_radius_m: float
    direct_path: bool
    poses: tuple[Pose, ...]
    rate_hz: float | None = None
    mic_radius_m: float = 0.0  # microphone port as a baffled piston; 0: omnidirectional


@dataclass(frozen=True)
class Simulation:
    """Simulation settings.

    max_range_m : echoes are computed up to this range (the window is 2 r / c plus
        the call).
    rays : rays cast from the emitter over its beam per pose.
    bounces : maximum number of reflections of a path.
    beam_deg : half-angle of the cone of rays around the emitter axis.
    energy_floor_db : paths weaker than this, relative to the strongest echo of the
        pose, are dropped.
    diffraction : edge diffraction (BTM, :mod:`acousim.trace.diffraction`).
    diffraction_step_m : edge-element step, in excess path length (m).
    diffraction_reflections : also edge diffraction combined with one specular
        reflection before or after the edge (image sources; slow in large scenes).
    snr_db : noise level relative to the echoes (the direct path left out, see
        ``acousim.synth.model.simulate``, ``snr_reference="echoes"``); inf: no noise.
    """

    max_range_m: float = 6.0
    rays: int = 20000
    bounces: int = 2
    beam_deg: float = 90.0
    snr_db: float = float("inf")
    seed: int = 0
    fractional_delay: str = "sinc"
    absorption: bool = True
    energy_floor_db: float = -80.0
    diffraction: bool = False
    diffraction_step_m: float = 1e-3
    diffraction_reflections: bool = False


@dataclass(frozen=True, eq=False)
class Scene:
    name: str
    description: str
    source: Path | None
    file_sha256: str | None
    materials: dict[str, Material]
    meshes: tuple[MeshItem, ...]
    points: tuple[PointItem, ...]
    sensor: Sensor
    environment: Environment = field(default_factory=Environment)
    simulation: Simulation = field(default_factory=Simulation)

    def n_samples(self) -> int:
        """Recording length: the round trip to max_range plus the call."""
        c = self.environment.speed_of_sound_m_s
        t = 2 * self.simulation.max_range_m / c + self.sensor.call.duration_s
        return int(np.ceil(t * self.sensor.sample_rate_hz))
