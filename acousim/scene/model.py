"""What a scene describes, as small frozen dataclasses (SI units; degrees only in names
ending ``_deg``).

Every setting is declared once (:func:`processing.base.settings.setting`: type, unit,
default, allowed range) and that declaration checks both the TOML loader and the
Python constructors, so ``Material(reflection=5)`` is refused like
``reflection = 5`` in a scene file. To add a setting, add one ``setting(...)`` line
to its dataclass; the loader reads it from the table of the same name
(``[environment]``, ``[simulation]``, ``[[materials]]``, ``[[points]]``, ``[sensor]``).

Building a scene in code (every argument has a default except what echoes)::

    import trimesh
    import acousim

    wall = acousim.MeshItem(trimesh.creation.box((0.1, 4, 3)),
                            acousim.Material("brick", reflection=0.9),
                            position_m=(2.0, 0, 0))
    scene = acousim.Scene(meshes=[wall], sensor=acousim.Sensor(sample_rate_hz=450e3))
    recordings = acousim.Simulator(scene).run()
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import InitVar, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, cast, get_args

import numpy as np

from acousim.core.air import speed_of_sound
from acousim.core.materials import interpolate, reference
from acousim.core.rendering import (
    COMPRESS_TOLERANCE,
    SHAPED_INTERPOLATORS,
    RenderDomain,
    RenderRate,
    ShapedDelay,
)
from acousim.scene.defaults import (
    QUALITIES,
    Quality,
    fill_unset,
    memory_limit_bytes,
    record_given,
)
from acousim.scene.defaults import given as given_settings
from acousim.scene.motion import (
    MAX_SPEED_M_S,
    MAX_TURN_DEG_S,
    motion_at,
    moves,
    track_rotation,
    track_rows,
    vector3,
    velocity_setting,
)
from acousim.scene.names import (
    array_named,
    call_named,
    lidar_named,
    scene_materials,
    with_emitter,
)
from acousim.scene.pose import MAX_COORDINATE_M, Pose, rotation
from acousim.scene.trajectory import Trajectory
from processing import Array, Waveform
from processing.base.api import warn_deprecated
from processing.base.errors import InputError
from processing.base.settings import setting, validate
from processing.sensor.arrays import MAX_EXTENT_M
from processing.sensor.rtis import RTIS_SAMPLE_RATE_HZ

__all__ = [
    "Material",
    "MeshItem",
    "PointItem",
    "Sensor",
    "Environment",
    "Simulation",
    "Scene",
    "FRACTIONAL_DELAYS",
    "MAX_SPEED_M_S",
    "MAX_TURN_DEG_S",
    "track_rows",
    "memory_limit_bytes",
]

FRACTIONAL_DELAYS = SHAPED_INTERPOLATORS
FloorRule = Literal["path", "sum"]
"""What ``energy_floor_db`` bounds (:mod:`acousim.trace.floor`): "path", each dropped
path's level; "sum", the summed energy of all the dropped paths."""
#: peak memory of the ray tracer, bytes per ray and per (bounces + 1)**2: the slope
#: of the peak RSS of the corridor's first pose against its rays
#: (benchmarks/trace_memory.py) is 1315 B per ray at 3 bounces (0.4, 0.8, 1.6
#: million rays) and 293 B at 1 bounce (0.8, 1.6 million): 82 and 73 B x (bounces +
#: 1)**2 (the hits of every bounce kept, the later bounces' rays the longer),
#: rounded up so that both are covered
TRACE_BYTES_PER_RAY = 85
"""Fractional-delay interpolators a scene may choose: those of the renderer that take
a path response (:data:`acousim.synth.render.ShapedDelay`)."""


@dataclass(frozen=True)
class Material:
    """How a surface reflects.

    reflection : pressure reflection coefficient (0..1) of the specular part.
    diffuse : fraction of the reflected energy scattered diffusely (Lambert), 0..1.
    lobe_deg : width (standard deviation) of the reflection lobe around the mirror
        direction on curved surfaces, for paths with more than one reflection (the
        first-order echo of a curved surface is exact geometric optics, see
        ``acousim.trace.rays.glints``); a sampling kernel: a wider lobe converges with
        fewer rays but spreads a glint's energy in delay.
    frequencies_khz : table frequencies (kHz, increasing); when given, `reflection`
        and/or `diffuse` may be lists of the same length: their values there,
        interpolated linearly in frequency and held at the end values outside the
        table (:mod:`acousim.core.materials`).  Empty: single numbers.
    """

    name: str = setting("default", doc="name the meshes refer to")
    reflection: float | tuple[float, ...] = setting(
        0.95, "", 0, 1, "pressure reflection coefficient (or a table)", kind="scalar_or_vector"
    )
    diffuse: float | tuple[float, ...] = setting(
        0.0,
        "",
        0,
        1,
        "fraction of energy scattered diffusely (or a table)",
        kind="scalar_or_vector",
    )
    lobe_deg: float = setting(5.0, "deg", 0.1, 90, "reflection lobe width (std)")
    frequencies_khz: tuple[float, ...] = setting(
        (), "kHz", 0, 1e4, "table frequencies, increasing", kind="vector"
    )

    def __post_init__(self) -> None:
        validate(self)
        f = self.frequencies_khz
        tables = {k: getattr(self, k) for k in ("reflection", "diffuse")}
        lists = {k: v for k, v in tables.items() if isinstance(v, tuple)}
        if not f:
            if lists:
                k, v = next(iter(lists.items()))
                raise InputError(
                    "a table needs frequencies_khz (of the same length)",
                    key=f"Material.{k}",
                    value=list(v),
                )
            return
        if not lists:
            raise InputError(
                "given, but reflection and diffuse are single numbers: give one of them "
                "as a list of values at these frequencies, or leave frequencies_khz out",
                key="Material.frequencies_khz",
                value=list(f),
            )
        if any(b <= a for a, b in zip(f, f[1:])):
            raise InputError(
                "must increase strictly", key="Material.frequencies_khz", value=list(f)
            )
        for k, v in lists.items():
            if len(v) != len(f):
                raise InputError(
                    f"has {len(v)} values but frequencies_khz has {len(f)}",
                    key=f"Material.{k}",
                    value=list(v),
                )

    @property
    def frequency_dependent(self) -> bool:
        """Whether reflection or diffuse is a table over frequency."""
        return bool(self.frequencies_khz)

    @property
    def reference(self) -> tuple[float, float]:
        """(reflection, diffuse): the single numbers the tracer uses; a table's
        largest reflection and mean diffuse fraction
        (:func:`acousim.core.materials.reference`), the numbers themselves otherwise."""
        if not self.frequency_dependent:  # single numbers (checked in __post_init__)
            return self.reflection, self.diffuse  # type: ignore[return-value]

        return reference(np.multiply(self.frequencies_khz, 1e3), self.reflection, self.diffuse)

    def scaled(self, factor: float) -> Material:
        """The material with its reflection (every value of a table) times `factor`."""
        r = self.reflection
        r = tuple(v * factor for v in r) if isinstance(r, tuple) else r * factor
        return dataclasses.replace(self, reflection=r)

    def at(self, frequency_hz) -> tuple[np.ndarray, np.ndarray]:
        """(reflection, diffuse) at `frequency_hz` (any shape)."""
        f = np.asarray(frequency_hz, float)
        if not self.frequency_dependent:
            return np.full(f.shape, self.reflection), np.full(f.shape, self.diffuse)

        table = np.multiply(self.frequencies_khz, 1e3)
        reflection, diffuse = (
            interpolate(f, table, np.broadcast_to(getattr(self, k), table.shape))
            for k in ("reflection", "diffuse")
        )
        return reflection, diffuse


#: a mesh file's length unit (a ``[[meshes]]`` table's ``units``) in metres
MESH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}


def placement(
    units: str = "m",
    scale: float = 1.0,
    position_m: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
    rotation_deg: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """The (4, 4) transform of a mesh placed as a scene file places it: its `units`
    (:data:`MESH_UNITS`) and `scale` to metres, turned by `rotation_deg` (roll, pitch,
    yaw about x, y, z, degrees, as a pose's), moved to `position_m` (m)."""
    if units not in MESH_UNITS:
        raise InputError(f"must be one of {sorted(MESH_UNITS)}", key="units", value=units)
    if isinstance(scale, bool) or not (np.isfinite(scale) and 1e-9 <= scale <= 1e9):
        raise InputError("must be a number in [1e-09, 1e9]", key="scale", value=scale)
    angles = np.asarray(rotation_deg, dtype=float)
    if angles.shape != (3,) or not np.all(np.isfinite(angles)):
        raise InputError("must be 3 finite angles (deg)", key="rotation_deg", value=rotation_deg)
    roll, pitch, yaw = np.deg2rad(angles)
    T = np.eye(4)
    T[:3, :3] = rotation(yaw, pitch, roll) * (scale * MESH_UNITS[units])
    T[:3, 3] = vector3(position_m, "position_m")
    return T


@dataclass(frozen=True, eq=False)
class MeshItem:
    """A mesh placed in the world.

    mesh : a mesh file (any format trimesh reads) or a ``trimesh.Trimesh`` in memory
        (copied when the world is built: the caller's mesh is never changed).
    transform : (4, 4) maps the mesh's units to metres in the world; ``position_m``
        (3,), when given, is added to its translation (a convenience for code).
    material : a Material or the name of one of the scene's (:class:`Scene` resolves it).
    materials : {group name: Material or material name} for the face groups of a mesh
        file (OBJ groups, objects or ``usemtl`` names, GLB/GLTF node or mesh names;
        see ``acousim.trace.world.build.face_groups``); faces of other groups take
        `material`.  Empty: the whole mesh is `material`.
    """

    mesh: Any
    material: Material | str = field(default_factory=Material)
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    position_m: tuple[float, float, float] | None = None
    materials: dict[str, Material] = field(default_factory=dict)
    #: a moving mesh (a person, another robot): it translates rigidly, at this
    #: velocity from where `transform` puts it at time 0, or along its own `track`
    #: (rows t_s, x, y, z: where the mesh's origin is, as a point's; or rows t_s, x,
    #: y, z, roll, pitch, yaw (rad): also how it is turned about its origin then,
    #: ``R(t) R_0`` with R as a pose's, interpolated by a rotation spline:
    #: :func:`track_rows`)
    velocity_m_s: tuple[float, float, float] = velocity_setting()
    track: tuple[tuple[float, ...], ...] | None = None
    #: or it turns at this angular velocity (world frame) about its origin (where
    #: the transform, the velocity or the track put it): ``R(t) = exp(w t) R_0``
    angular_velocity_rad_s: tuple[float, float, float] = setting(
        (0.0, 0.0, 0.0),
        "rad/s",
        -math.radians(MAX_TURN_DEG_S),
        math.radians(MAX_TURN_DEG_S),
        "turns about world x, y, z through its origin (file: angular_rate_deg_s)",
        kind="vector",
        length=3,
    )

    if TYPE_CHECKING:  # `materials` takes names too; the Scene makes them Materials

        def __init__(
            self,
            mesh: Any,
            material: Material | str = ...,
            transform: np.ndarray = ...,
            position_m: Sequence[float] | None = ...,
            materials: Mapping[str, Material | str] = ...,
            velocity_m_s: Sequence[float] = ...,
            track: Sequence[Sequence[float]] | None = ...,
            angular_velocity_rad_s: Sequence[float] = ...,
        ) -> None: ...

    def __post_init__(self) -> None:
        mesh = self.mesh
        if isinstance(mesh, str | os.PathLike):
            mesh = Path(mesh)
            if not mesh.is_file():
                raise InputError("mesh file not found", key="MeshItem.mesh", value=str(mesh))
        elif not (hasattr(mesh, "vertices") and hasattr(mesh, "faces")):
            raise InputError(
                "must be a mesh file or a trimesh.Trimesh", key="MeshItem.mesh", value=mesh
            )
        if not isinstance(mat := self.material, Material | str):
            raise InputError("must be a Material or a name", key="MeshItem.material", value=mat)
        groups = dict(self.materials)
        for group, mat in groups.items():
            if not isinstance(group, str) or not isinstance(mat, Material | str):
                raise InputError(
                    "must map group names (str) to Materials or material names",
                    key=f"MeshItem.materials[{group!r}]",
                    value=mat,
                )
        object.__setattr__(self, "materials", groups)
        T = np.array(self.transform, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InputError(
                "must be a finite (4, 4) matrix", key="MeshItem.transform", value=self.transform
            )
        if self.position_m is not None:
            p = vector3(self.position_m, "MeshItem.position_m")
            T[:3, 3] += p
            object.__setattr__(self, "position_m", None)
        object.__setattr__(self, "mesh", mesh)
        object.__setattr__(self, "transform", T)
        if self.track is not None:
            track = track_rows(self.track, "MeshItem.track", turns=True)
            object.__setattr__(self, "track", track)
        validate(self)
        if self._track_turns and any(w != 0 for w in self.angular_velocity_rad_s):
            raise InputError(
                "a track with orientations turns the mesh itself: give no angular velocity",
                key="MeshItem.angular_velocity_rad_s",
                value=self.angular_velocity_rad_s,
            )

    @classmethod
    def placed(
        cls,
        mesh: Any,
        *,
        units: str = "m",
        scale: float = 1.0,
        position_m: Sequence[float] = (0.0, 0.0, 0.0),
        rotation_deg: Sequence[float] = (0.0, 0.0, 0.0),
        **keywords: Any,
    ) -> MeshItem:
        """A mesh placed by a scene file's keys (a ``[[meshes]]`` table's `units` of the
        mesh file, `scale`, `position_m` in metres, `rotation_deg` roll, pitch, yaw
        about x, y, z in degrees): :func:`placement`'s transform; the other keywords
        are MeshItem's (`material`, `materials`, the motion)."""
        return cls(mesh, transform=placement(units, scale, position_m, rotation_deg), **keywords)

    @property
    def moving(self) -> bool:
        return moves(self) or self.turning

    @property
    def turning(self) -> bool:
        return self._track_turns or any(w != 0 for w in self.angular_velocity_rad_s)

    @property
    def _track_turns(self) -> bool:
        return self.track is not None and len(self.track[0]) == 7

    def at(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Where the mesh's origin is (3,) and its velocity (3,) at time `t_s` of the
        trajectory clock (as :meth:`PointItem.at`; still: the transform's translation)."""
        return motion_at(self, self.transform[:3, 3], t_s)

    def rotation_at(self, t_s: float) -> np.ndarray:
        """The turn (3, 3) of the mesh at time `t_s` about its origin, after its
        transform's rotation: ``exp(w t)``, or its track's orientation."""
        if self._track_turns:
            return track_rotation(self.track, t_s)[0].as_matrix()
        from scipy.spatial.transform import Rotation

        w = np.asarray(self.angular_velocity_rad_s, float)
        return Rotation.from_rotvec(w * t_s).as_matrix()

    def angular_velocity_at(self, t_s: float) -> np.ndarray:
        """The angular velocity (3,) in rad/s, world frame, at time `t_s`."""
        if self._track_turns:
            turn, rate = track_rotation(self.track, t_s)
            return turn.apply(rate)
        return np.asarray(self.angular_velocity_rad_s, float)

    def placed_at(self, t_s: float) -> MeshItem:
        """The mesh where it is at time `t_s` (itself if it does not move)."""
        if not self.moving:
            return self
        T = self.transform.copy()
        T[:3, :3] = self.rotation_at(t_s) @ T[:3, :3]
        T[:3, 3] = self.at(t_s)[0]
        return dataclasses.replace(
            self,
            transform=T,
            velocity_m_s=(0.0, 0.0, 0.0),
            track=None,
            angular_velocity_rad_s=(0.0, 0.0, 0.0),
        )

    @property
    def path(self) -> Path | None:
        """The mesh file, or None for a mesh in memory."""
        return self.mesh if isinstance(self.mesh, Path) else None


@dataclass(frozen=True)
class PointItem:
    """An explicit point reflector (world frame): strength a_k of eq. 1; it may move
    at `velocity_m_s` (position_m is where it is at time 0 of the trajectory)."""

    position_m: tuple[float, float, float] | None = setting(
        None,
        "m",
        -MAX_COORDINATE_M,
        MAX_COORDINATE_M,
        "position at time 0 (required without a track)",
        kind="vector",
        length=3,
    )
    strength: float = setting(1.0, "", 0, 1e6, "amplitude at 1 m relative to the call")
    velocity_m_s: tuple[float, float, float] = velocity_setting()
    #: its own trajectory instead: rows (t_s, x, y, z), two or more, times increasing
    #: (a table, checked by :func:`track_rows`; read by hand from TOML)
    track: tuple[tuple[float, float, float, float], ...] | None = None

    def __post_init__(self) -> None:
        if self.track is not None:
            track = track_rows(self.track, "PointItem.track")
            object.__setattr__(self, "track", track)
            if self.position_m is None:  # where the track starts (unused with a track)
                object.__setattr__(self, "position_m", track[0][1:])
        elif self.position_m is None:
            raise InputError("missing (a list of 3 numbers)", key="PointItem.position_m")
        validate(self)

    @property
    def moving(self) -> bool:
        return moves(self)

    def at(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity (3,) at time `t_s` of the trajectory clock: along
        its track (a cubic spline with natural ends, extended by its end pieces), or
        moving at its velocity from its position at time 0."""
        return motion_at(self, self.position_m, t_s)


@dataclass(frozen=True)
class Environment:
    """The air: `temperature_c` (degrees Celsius), `humidity_percent` (relative
    humidity, %) and `pressure_kpa` (kPa) set the speed of sound
    (:attr:`speed_of_sound_m_s`, m/s) and the air absorption of every path (ISO
    9613-1, :mod:`acousim.core.air`)."""

    temperature_c: float = setting(20.0, "degC", -20, 50, "air temperature")
    humidity_percent: float = setting(50.0, "%", 0, 100, "relative humidity")
    pressure_kpa: float = setting(101.325, "kPa", 50, 120, "static pressure")

    def __post_init__(self) -> None:
        validate(self)

    @property
    def speed_of_sound_m_s(self) -> float:
        return speed_of_sound(self.temperature_c, self.humidity_percent, self.pressure_kpa)


@dataclass(frozen=True, eq=False)
class Sensor:
    """The sonar: array, emitter, call and sampling, and where it is.

    array, call, lidar : objects, or names as in a scene file (``"urtis_v1"``, the
        default; ``"default_25_50"``, the default; ``"vlp16"``), resolved by the
        loader's code (:mod:`acousim.scene.names`).
    poses : one Pose or a sequence (a trajectory sampled at `rate_hz`, Hz).
    emitter_m : the emitter's position (3,) m in the sensor frame, as the scene
        file's ``emitter_m``: it replaces the array's (``array.emitter_m`` holds the
        result); None (the default): the array's own, the centre (0, 0, 0) for the
        presets.
    emitter_radius_m : the emitter as a baffled piston of this radius (m); 0 (the
        default): omnidirectional.
    """

    array: Array = cast(Any, "urtis_v1")  # a name, resolved when constructed
    call: Waveform = cast(Any, "default_25_50")
    sample_rate_hz: float = setting(
        RTIS_SAMPLE_RATE_HZ, "Hz", 1e3, 1e8, "sampling rate of the microphones"
    )
    emitter_radius_m: float = setting(0.0, "m", 0, 0.5, "emitter as a baffled piston; 0: omni")
    direct_path: bool = setting(True, doc="include the emitter-to-microphone crosstalk")
    poses: tuple[Pose, ...] = field(default_factory=lambda: (Pose(np.zeros(3)),))
    rate_hz: float | None = None
    mic_radius_m: float = setting(0.0, "m", 0, 0.05, "microphone port as a piston; 0: omni")
    #: continuous motion during measurements (:class:`acousim.scene.trajectory.Trajectory`,
    #: whose rates are declared in ``acousim.scene.trajectory.RATES``); None: every pose
    #: is frozen for its measurement
    motion: Any = None
    #: a LiDAR beside the sonar (:class:`acousim.scene.lidar.Lidar`), scanning at
    #: every pose; None: none
    lidar: Any = None
    emitter_m: tuple[float, float, float] | None = setting(
        None,
        "m",
        -MAX_EXTENT_M,
        MAX_EXTENT_M,
        "emitter in the sensor frame; unset: the array's own (the centre for the presets)",
        kind="vector",
        length=3,
    )

    if TYPE_CHECKING:  # the constructor takes names too; the fields hold the objects

        def __init__(
            self, array: Array | str = ..., call: Waveform | str = ..., **k: Any
        ) -> None: ...

    def __post_init__(self) -> None:
        validate(self)

        object.__setattr__(self, "lidar", lidar_named(self.lidar, "Sensor.lidar"))
        array = array_named(self.array, "Sensor.array")
        object.__setattr__(self, "array", with_emitter(array, self.emitter_m, "Sensor.emitter_m"))
        object.__setattr__(self, "call", call_named(self.call, "Sensor.call"))
        poses = (self.poses,) if isinstance(self.poses, Pose) else tuple(self.poses)
        if not poses or not all(isinstance(p, Pose) for p in poses):
            raise InputError("must be a Pose or a non-empty sequence of Poses", key="Sensor.poses")
        object.__setattr__(self, "poses", poses)
        if self.rate_hz is not None:
            if isinstance(self.rate_hz, bool) or not 1e-3 <= float(self.rate_hz) <= 1e4:
                raise InputError(
                    "must be None or in [0.001, 10000] Hz", key="Sensor.rate_hz", value=self.rate_hz
                )
            object.__setattr__(self, "rate_hz", float(self.rate_hz))
        if self.motion is not None:
            if not isinstance(self.motion, Trajectory):
                raise InputError(
                    "must be None or an acousim.scene.trajectory.Trajectory",
                    key="Sensor.motion",
                    value=self.motion,
                )
        top = max(self.call.band_hz)
        if top >= self.sample_rate_hz / 2:
            raise InputError(
                f"is below twice the call's highest frequency {top:g} Hz",
                key="Sensor.sample_rate_hz",
                value=self.sample_rate_hz,
            )


@dataclass(frozen=True)
class Diffraction:
    """Edge diffraction (Biot-Tolstoy-Medwin, :mod:`acousim.trace.diffraction`): the
    scene file's ``[simulation.diffraction]`` table, passed whole to the stage.

    enabled : false: geometric optics alone.
    order : 2 (default): each edge, and edge to edge over the pairs of edges that share
        a plane (the rims of a plate, the edges of a box face) where a pair can reach
        the energy floor; 1: each edge alone.
    step_m : the edge-element step, in excess path length (m); edge to edge takes it
        scaled to the call's highest frequency (:class:`acousim.trace.options.TraceSettings`).
    reflections : also edge diffraction combined with one specular reflection before
        or after the edge (image sources; slow in large scenes).
    """

    enabled: bool = setting(True, doc="edge diffraction (BTM)")
    order: int = setting(2, "", 1, 2, "2: also edge to edge where it matters; 1: not")
    step_m: float = setting(1e-3, "m", 1e-5, 0.1, "edge-element step (excess path)")
    reflections: bool = setting(False, doc="also edge + one reflection (slow)")

    def __post_init__(self) -> None:
        validate(self, prefix="Simulation.diffraction")


def _fold_flat_diffraction(diffraction: Any, flat: dict[str, Any]) -> Diffraction:
    """The Diffraction of a Simulation given the old way: ``diffraction=True/False`` and
    ``diffraction_step_m`` / ``_order`` / ``_reflections`` keywords (a DeprecationWarning
    naming the new spelling); a Diffraction as it is."""
    given = {k: v for k, v in flat.items() if v is not None}
    if isinstance(diffraction, Diffraction) and not given:
        return diffraction
    if isinstance(diffraction, bool | np.bool_):
        given = {"enabled": bool(diffraction), **given}
        diffraction = Diffraction()
    elif not isinstance(diffraction, Diffraction):
        raise InputError(
            "must be an acousim.Diffraction (or true/false)",
            key="Simulation.diffraction",
            value=diffraction,
        )
    new = ", ".join(f"{k}={v!r}" for k, v in given.items())
    warn_deprecated(
        f"Simulation(diffraction=bool, diffraction_step_m/_order/_reflections=...) is "
        f"deprecated: use Simulation(diffraction=Diffraction({new}))"
    )
    return dataclasses.replace(diffraction, **given)


@dataclass(frozen=True)
class Simulation:
    """Simulation settings.

    max_range_m : echoes are computed up to this range (window: 2 r / c plus the call).
    rays : rays cast from the emitter over its beam per pose; unset (the default):
        found per pose, the automatic budget of :mod:`acousim.trace.rays.budget` (batches
        of rays until one finds nothing new and the diffuse tail has converged; no
        rays where nothing needs them).  A number gives exactly that many rays, on
        the deterministic spiral.
    rays_max : cap of the automatic budget (rays per pose).
    bounces : maximum reflections of a path (3: a corner reflector's triple bounce).
    beam_deg : half-angle of the cone of rays around the emitter axis.
    energy_floor_db : paths weaker than this, relative to the strongest echo of the
        pose, are dropped (``energy_floor_rule`` "path"), or the weakest paths whose
        summed energy stays this far below that echo's ("sum").
    energy_floor_rule : what the floor bounds: "path" (each dropped path's level)
        or "sum" (the summed energy of every dropped path: many weak paths that add
        up to a strong echo are kept); :mod:`acousim.trace.floor`.
    diffraction : edge diffraction (:class:`Diffraction`: the scene file's
        ``[simulation.diffraction]`` table); on by default, edge to edge where it matters.
    snr_db : noise level relative to the echoes (the direct path left out, see
        ``acousim.synth.signal_model.simulate``, ``snr_reference="echoes"``); inf: no noise.
    max_memory_gb : refuse a simulation whose estimated memory
        (:meth:`Scene.memory_bytes`) is above this many gigabytes (10^9 bytes). The
        default is :func:`memory_limit_bytes`: ``$ACOUSIM_MAX_MEMORY_GB`` or 8.
    quality : a preset of the settings not given (:mod:`acousim.scene.defaults`):
        "fast", "default" or "reference"; ``dataclasses.replace`` keeps the given ones.
    """

    max_range_m: float = setting(6.0, "m", 0.05, 100, "echoes computed up to this range")
    rays: int | None = setting(
        None, "", 0, 10_000_000, "rays per pose; unset: automatic", kind="int"
    )
    rays_max: int = setting(400_000, "", 1, 10_000_000, "cap of the automatic ray budget")
    bounces: int = setting(3, "", 0, 6, "maximum reflections of a path")
    beam_deg: float = setting(90.0, "deg", 1, 180, "half-angle of the cone of rays")
    snr_db: float = setting(math.inf, "dB", -60, math.inf, "noise below the echoes; inf: none")
    seed: int = setting(0, "", 0, 2**63 - 1, "noise seed")
    fractional_delay: ShapedDelay = setting(
        "sinc", choices=FRACTIONAL_DELAYS, doc="fractional-delay interpolator"
    )
    absorption: bool = setting(True, doc="air absorption")
    render_rate: RenderRate = setting("full", choices=get_args(RenderRate), doc="full, baseband")
    render_domain: RenderDomain = setting(
        "auto", choices=get_args(RenderDomain), doc="full rate: sum in time or by FFT; auto"
    )
    render_band_db: float = setting(-60.0, "dB", -200, -10, "baseband: bins within this of the top")
    render_tolerance: float = setting(COMPRESS_TOLERANCE, "", 1e-6, 0.3, "gain-set compression")
    energy_floor_db: float = setting(-80.0, "dB", -300, 0, "drop weaker paths")
    energy_floor_rule: FloorRule = setting(
        "path", choices=get_args(FloorRule), doc="the floor bounds each dropped path, or their sum"
    )
    diffraction: Diffraction = field(default_factory=lambda: Diffraction())
    max_memory_gb: float = setting(
        math.nan, "GB", 1e-3, 1e6, "refuse larger simulations", kind="float"
    )
    quality: Quality = setting(
        "default",
        choices=QUALITIES,
        doc="measured preset of the settings not given (docs/physics.md: run time against error)",
    )
    _origin: tuple | None = field(default=None, repr=False, compare=False)  # see fill_unset

    #: the flat names of the diffraction settings before they became one table (a
    #: version's grace, with a DeprecationWarning: :func:`_fold_flat_diffraction`)
    diffraction_step_m: InitVar[float | None] = None
    diffraction_reflections: InitVar[bool | None] = None
    diffraction_order: InitVar[int | None] = None

    def __post_init__(self, diffraction_step_m, diffraction_reflections, diffraction_order) -> None:
        if isinstance(self.max_memory_gb, float) and math.isnan(self.max_memory_gb):
            object.__setattr__(self, "max_memory_gb", memory_limit_bytes() / 1e9)
        flat = {
            "step_m": diffraction_step_m,
            "reflections": diffraction_reflections,
            "order": diffraction_order,
        }
        object.__setattr__(self, "diffraction", _fold_flat_diffraction(self.diffraction, flat))
        validate(self)  # the quality among the others: a known preset below
        fill_unset(self)

    def with_quality(self, quality: Quality) -> Simulation:
        """These settings under another preset, the explicitly given ones kept."""
        return dataclasses.replace(self, quality=quality)


record_given(Simulation)


@dataclass(frozen=True, eq=False)
class Scene:
    """A whole scene; give at least one mesh or point. `materials` ({name: Material} or
    a list) defaults to those of the meshes (a mesh's material name is one of them);
    `source` and `file_sha256` identify a scene file (None in code); `files`: the other
    files it was read from (meshes, coordinate files, trajectories; empty in code)."""

    name: str = "scene"
    description: str = ""
    source: Path | None = None
    file_sha256: str | None = None
    materials: dict[str, Material] = field(default_factory=dict)
    meshes: tuple[MeshItem, ...] = ()
    points: tuple[PointItem, ...] = ()
    sensor: Sensor = field(default_factory=Sensor)
    environment: Environment = field(default_factory=Environment)
    simulation: Simulation = field(default_factory=Simulation)
    rig: Any = None  #: sonars on one body (acousim.scene.rig.Rig, acousim.rig); None: `sensor`
    files: tuple[Path, ...] = ()

    if TYPE_CHECKING:  # the constructor takes a list of Materials too

        def __init__(self, *a: Any, materials: Mapping | Sequence = ..., **k: Any) -> None: ...

    def __post_init__(self) -> None:
        meshes, points = tuple(self.meshes), tuple(self.points)
        for key, items, kind in (
            ("Scene.meshes", meshes, MeshItem),
            ("Scene.points", points, PointItem),
        ):
            bad = [x for x in items if not isinstance(x, kind)]
            if bad:
                raise InputError(f"must hold {kind.__name__} objects", key=key, value=bad[0])
        if not meshes and not points:
            raise InputError(
                "the scene has neither meshes nor points: nothing can echo", key="Scene.meshes"
            )
        for key, value, expected in (
            ("Scene.sensor", self.sensor, Sensor),
            ("Scene.environment", self.environment, Environment),
            ("Scene.simulation", self.simulation, Simulation),
        ):
            if not isinstance(value, expected):
                raise InputError(f"must be a {expected.__name__}", key=key, value=value)

        materials, meshes = scene_materials(self.materials, meshes, Material)
        object.__setattr__(self, "meshes", meshes)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "materials", materials)
        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))

    def n_samples(self) -> int:
        """Recording length: the round trip to max_range plus the call."""
        c = self.environment.speed_of_sound_m_s
        t = 2 * self.simulation.max_range_m / c + self.sensor.call.duration_s
        return int(np.ceil(t * self.sensor.sample_rate_hz))

    def memory_bytes(self, n_poses: int | None = None, n_samples: int | None = None) -> int:
        """Estimated peak memory of simulating `n_poses` poses (default: all), bytes.

        Every recording is kept (M microphones x T samples, float64) and one pose at
        a time needs about six more such arrays of working memory (the render's
        oversampled and FFT buffers): ``8 M T (n_poses + 6)``; and the ray tracer
        holds its rays' hits, :meth:`trace_bytes`.
        """
        n = len(self.sensor.poses) if n_poses is None else n_poses
        T = self.n_samples() if n_samples is None else n_samples
        return 8 * self.sensor.array.n_mics * T * (n + 6) + self.trace_bytes(n)

    def trace_bytes(self, n_poses: int = 1) -> int:
        """Peak memory of the ray tracing of `n_poses` poses, bytes: ``TRACE_BYTES_PER_RAY
        x N (bounces + 1)**2`` a pose, N the rays (``simulation.rays``, else
        ``rays_max``), twice from two poses on (:meth:`Simulator.run` traces the next
        pose while one is prepared: 4.66 GB measured for 4 poses against 2.46 GB for
        one, 1.6 million rays, 3 bounces); 0 without meshes (points are not traced)."""
        sim = self.simulation
        if not self.meshes:
            return 0
        rays = sim.rays_max if sim.rays is None else sim.rays
        return TRACE_BYTES_PER_RAY * rays * (sim.bounces + 1) ** 2 * min(max(n_poses, 1), 2)

    def check_memory(self, n_poses: int | None = None, n_samples: int | None = None) -> None:
        """Refuse (InputError) a simulation whose :meth:`memory_bytes` exceeds
        ``simulation.max_memory_gb`` (named ``ACOUSIM_MAX_MEMORY_GB`` when that
        environment variable set it)."""
        need = self.memory_bytes(n_poses, n_samples)
        sim = self.simulation
        if need <= sim.max_memory_gb * 1e9:
            return
        n = len(self.sensor.poses) if n_poses is None else n_poses
        trace = ""
        if self.trace_bytes(n):
            rays = f"{sim.rays_max} rays (rays_max)" if sim.rays is None else f"{sim.rays} rays"
            both = " (two poses at once)" if n > 1 else ""
            trace = (
                f", and {self.trace_bytes(n) / 1e9:.3g} GB to trace {rays} x {sim.bounces} "
                f"bounces{both}"
            )
        env = "max_memory_gb" not in given_settings(sim) and os.environ.get("ACOUSIM_MAX_MEMORY_GB")
        raise InputError(
            f"the simulation would need about {need / 1e9:.3g} GB "
            f"({self.sensor.array.n_mics} mics x {n_samples or self.n_samples()} samples "
            f"x {n} pose(s){trace}), "
            f"above the limit of {sim.max_memory_gb:g} GB; lower sample_rate_hz, "
            "max_range_m, rays or bounces, simulate fewer poses, or raise "
            "simulation.max_memory_gb (or $ACOUSIM_MAX_MEMORY_GB)",
            file=None if env else self.source,
            key="ACOUSIM_MAX_MEMORY_GB" if env else "simulation.max_memory_gb",
            value=env or sim.max_memory_gb,
        )
