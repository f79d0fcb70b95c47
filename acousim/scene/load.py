"""Reading and validating scene files (TOML); the format is documented in
``docs/scene-format.md``.

Every error names the file, the key and the bad value, and says what is allowed;
an unknown key gets a did-you-mean. The tables that map onto a dataclass
(``[environment]``, ``[simulation]``, ``[[materials]]``, ``[[points]]`` and the scalar
keys of ``[sensor]``) are read through its declared settings (``acousim.scene.model``):
a new setting there needs no change here. Keys read by hand (the sensor's array,
call, pose and trajectory, a mesh's placement) are listed in :data:`EXTRA_KEYS`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import tomllib
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

import processing as P
from acousim.scene import model
from acousim.scene.defaults import FLAT_DIFFRACTION
from acousim.scene.lidar import PRESET, Lidar
from acousim.scene.mesh_file import MAX_UNITLESS_SPAN_M, placed_extent_m
from acousim.scene.names import (
    array_named,
    call_named,
    lidar_named,
    material_named,
    with_emitter,
)
from acousim.scene.pose import MAX_COORDINATE_M, Pose
from acousim.scene.rig import DEFAULT_RATE_HZ, ROTATION_DEG, Firing, Mount, Rig, RigSonar, schedule
from acousim.scene.trajectory import CONTINUOUS, RATES, Trajectory
from processing.base.errors import InputError
from processing.base.settings import Setting, check, read_table, refuse_unknown, settings_of
from processing.sensor.rtis import RTIS_SAMPLE_RATE_HZ

__all__ = ["SceneError", "load_scene", "parse_scene"]


class SceneError(InputError):
    """A scene file that cannot be used; the message names the file, key and value."""


NUM = (int, float)
#: keys read here rather than from a dataclass's declared settings
EXTRA_KEYS: dict[str, set[str]] = {
    "": {
        "scene",
        "environment",
        "sensor",
        "simulation",
        "materials",
        "meshes",
        "points",
        "body",
        "rig",
        "sensors",
        "lidars",
    },
    "body": {"pose", "trajectory"},
    "sensors.mount": {"position_m", "rotation_deg"},
    "scene": {"name", "description"},
    "sensor": {
        "array",
        "coordinates",
        "coordinates_units",
        "call",
        "pose",
        "trajectory",
        "lidar",
    },
    "sensor.call": {"kind", "f_start_hz", "f_end_hz", "duration_s", "taper"},
    "sensor.pose": {"position_m", "yaw_deg", "pitch_deg", "roll_deg", *RATES},
    "sensor.trajectory": {"poses", "file", "rate_hz", "continuous"},
    "meshes": {
        "file",
        "material",
        "materials",
        "units",
        "position_m",
        "rotation_deg",
        "scale",
        "velocity_m_s",
        "track",
        "angular_rate_deg_s",
    },
    "points": {"track"},
}
UNITS = model.MESH_UNITS
#: ``[[meshes]] angular_rate_deg_s``: a mesh turning about its origin (read in degrees,
#: kept in rad/s: MeshItem.angular_velocity_rad_s); the sensor's rates, for a mesh
MESH_TURN = RATES["angular_rate_deg_s"]
#: a pose's angles, in [sensor.pose] and in every row of a trajectory
POSE_ANGLES = {
    "yaw_deg": Setting("float", 0.0, "deg", -360, 360, "turns left"),
    "pitch_deg": Setting("float", 0.0, "deg", -90, 90, "points the sensor down"),
    "roll_deg": Setting("float", 0.0, "deg", -360, 360, "about the sensor's axis"),
}


class _Reader:
    def __init__(self, source: str) -> None:
        self.source = source
        self.files: list[Path] = []  # the other files read: meshes, coordinates, trajectories

    def fail(self, key: str, msg: str, value: Any = ...) -> SceneError:
        return SceneError(msg, file=self.source, key=key or "<file>", value=value)

    def check_keys(self, table: dict, section: str, where: str) -> None:
        try:
            refuse_unknown(table, EXTRA_KEYS[section], where=where, file=self.source)
        except InputError as exc:
            raise SceneError(exc.reason, file=exc.file, key=exc.key) from None

    def settings(self, cls: type, table: dict, where: str, extra: Iterable[str] = frozenset()):
        """The declared settings of `cls` in `table` (checked), unknown keys refused."""
        try:
            return read_table(cls, table, where=where, file=self.source, extra=extra)
        except InputError as exc:
            raise SceneError(exc.reason, file=exc.file, key=exc.key, value=exc.value) from None

    def table(self, d: dict, key: str, where: str) -> dict:
        v = d.get(key, {})
        if not isinstance(v, dict):
            raise self.fail(f"{where}.{key}".strip("."), "must be a table", v)
        return v

    def table_list(self, data: dict, key: str):
        """(where, table) for each table of an array of tables ``[[key]]``."""
        items = data.get(key, [])
        if not isinstance(items, list):
            raise self.fail(key, f"must be an array of tables ([[{key}]])", items)
        for i, t in enumerate(items):
            where = f"{key}[{i}]"
            if not isinstance(t, dict):
                raise self.fail(where, "must be a table", t)
            yield where, t

    def number(self, d, key, where, default, lo=-math.inf, hi=math.inf, integer=False):
        decl = Setting("int" if integer else "float", default, lo=lo, hi=hi)
        return self._check(decl, d.get(key, default), f"{where}.{key}")

    def vector(self, d: dict, key: str, where: str, default=None) -> np.ndarray:
        v = d.get(key, default)
        if v is None:
            raise self.fail(f"{where}.{key}", "missing (a list of 3 numbers)")
        decl = Setting("vector", lo=-MAX_COORDINATE_M, hi=MAX_COORDINATE_M, length=3)
        return np.array(self._check(decl, v, f"{where}.{key}"))

    def string(self, d, key, where, default=None, choices=None) -> str:
        v = d.get(key, default)
        if v is None:
            raise self.fail(f"{where}.{key}", "missing")
        decl = Setting("str", choices=None if choices is None else tuple(sorted(choices)))
        return self._check(decl, v, f"{where}.{key}")

    def boolean(self, d: dict, key: str, where: str, default: bool) -> bool:
        return self._check(Setting("bool"), d.get(key, default), f"{where}.{key}")

    def named(self, resolve, value: Any, key: str, *args: Any):
        """The object a name stands for (:mod:`acousim.scene.names`, the constructors'
        own resolution), its error keyed with the file."""
        try:
            return resolve(value, *args, key=key)
        except InputError as exc:
            raise SceneError(exc.reason, file=self.source, key=exc.key, value=exc.value) from None

    def _check(self, decl: Setting, value: Any, key: str):
        try:
            return check(decl, value, key, self.source)
        except InputError as exc:
            raise SceneError(exc.reason, file=exc.file, key=exc.key, value=exc.value) from None


def load_scene(path: str | Path) -> model.Scene:
    """Read and validate a scene file (TOML, ``docs/scene-format.md``), or a bundled
    scene named as the command line takes it (``"wall"``, ``"corridor"``: when no file
    of that name exists); a SceneError (an :class:`processing.base.errors.InputError`)
    names the file, key and value."""
    from acousim.bundled import resolve_scene

    path = Path(path)
    if not path.is_file():
        try:
            path = resolve_scene(path)
        except InputError as exc:  # no such file, nor a bundled scene: say what to type
            raise SceneError(exc.reason, file=path) from None
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(f"not valid TOML ({exc})", file=path) from None
    return parse_scene(
        data, base_dir=path.parent, source=str(path), sha256=hashlib.sha256(raw).hexdigest()
    )


def _simulation(r: _Reader, table: dict) -> model.Simulation:
    """``[simulation]`` and its ``[simulation.diffraction]`` table.  The older flat keys
    (``diffraction = false``, ``diffraction_order = 1``, ...) are read for a version with
    a DeprecationWarning that names the new key."""
    extra = {"diffraction", *FLAT_DIFFRACTION}
    declared = r.settings(model.Simulation, table, "simulation", extra=extra)
    sub = table.get("diffraction", {})
    flat = {new: table[old] for old, new in FLAT_DIFFRACTION.items() if old in table}
    if isinstance(sub, bool):
        flat = {"enabled": sub, **flat}
        sub = {}
    if flat:
        keys = ", ".join(f"simulation.diffraction.{k}" for k in flat)
        warnings.warn(
            f"{r.source}: the flat [simulation] diffraction keys are deprecated: use {keys}",
            DeprecationWarning,
            stacklevel=3,
        )
    if not isinstance(sub, dict):
        raise r.fail("simulation.diffraction", "must be a table (or true/false)", sub)
    diffraction = r.settings(model.Diffraction, {**flat, **sub}, "simulation.diffraction")
    try:
        # a table the file gives is given whole (a quality preset fills the others)
        table = {"diffraction": model.Diffraction(**diffraction)} if diffraction else {}
        return model.Simulation(**declared, **table)
    except InputError as exc:
        raise SceneError(exc.reason, file=r.source, key=exc.key, value=exc.value) from None


def parse_scene(
    data: dict[str, Any],
    *,
    base_dir: str | Path = ".",
    source: str = "<scene>",
    sha256: str | None = None,
) -> model.Scene:
    """Validate a scene given as a dict (the parsed TOML)."""
    r = _Reader(source)
    base = Path(base_dir)
    r.check_keys(data, "", "")
    meta = r.table(data, "scene", "")
    r.check_keys(meta, "scene", "scene")
    env = model.Environment(
        **r.settings(model.Environment, r.table(data, "environment", ""), "environment")
    )
    sim = _simulation(r, r.table(data, "simulation", ""))
    materials = _materials(r, data)
    meshes = [_mesh(r, m, where, base, materials) for where, m in r.table_list(data, "meshes")]
    points = []
    for where, p in r.table_list(data, "points"):
        if "position_m" not in p and "track" not in p:
            raise r.fail(f"{where}.position_m", "missing (a list of 3 numbers)")
        declared = r.settings(model.PointItem, p, where, extra=EXTRA_KEYS["points"])
        try:
            points.append(model.PointItem(**declared, track=p.get("track")))
        except InputError as exc:  # the track, checked by the model (the rest read above)
            raise r.fail(f"{where}.track", exc.reason, p.get("track")) from None
    rig = None
    if "sensors" in data:
        rig = _rig(r, data, base)
        sensor = dataclasses.replace(rig.sonars[0].sensor, poses=_first_poses(rig))
    else:
        sensor = _sensor(r, r.table(data, "sensor", ""), base)
    if not meshes and not points:
        raise r.fail("meshes", "the scene has neither meshes nor points: nothing can echo")
    return model.Scene(
        name=r.string(meta, "name", "scene", Path(source).stem),
        description=r.string(meta, "description", "scene", ""),
        source=Path(source) if source != "<scene>" else None,
        file_sha256=sha256,
        files=tuple(dict.fromkeys(r.files)),
        materials=materials,
        meshes=tuple(meshes),
        points=tuple(points),
        sensor=sensor,
        environment=env,
        simulation=sim,
        rig=rig,
    )


def _rig(r: _Reader, data: dict, base: Path) -> Rig:
    """A rig: ``[body]`` (a pose or a trajectory, as ``[sensor]`` has), ``[rig]``
    (the firing mode and rate, crosstalk), ``[[sensors]]`` (each a ``[sensor]`` table
    without pose, trajectory or LiDAR, with a name, a mount and a firing) and
    ``[[lidars]]`` (each a ``[sensor.lidar]`` table, mounted on the body)."""
    if "sensor" in data:
        raise r.fail("sensors", "give either [sensor] or [[sensors]] (a rig), not both")
    body = r.table(data, "body", "")
    r.check_keys(body, "body", "body")
    poses, rate = _poses(r, body, base, "body")
    motion = _motion(r, body, poses, "body")
    opts = r.settings(Rig, r.table(data, "rig", ""), "rig")  # firing, rate_hz, crosstalk, ...
    mode = opts.get("firing", "round_robin")
    rate = opts.get("rate_hz") or rate or DEFAULT_RATE_HZ
    tables = list(r.table_list(data, "sensors"))
    if not tables:
        raise r.fail("sensors", "must hold at least one sensor")
    firings = schedule(len(tables), rate, mode)
    extra = (EXTRA_KEYS["sensor"] - {"pose", "trajectory", "lidar"}) | {"name", "mount", "firing"}
    sonars = []
    for i, (where, t) in enumerate(tables):
        for key in ("pose", "trajectory", "lidar"):
            if key in t:
                raise r.fail(f"{where}.{key}", "a rig's sensors move with [body]; "
                             "LiDARs are [[lidars]]")  # fmt: skip
        for key in FIRING_KEYS.intersection(t):  # a sonar's rate is its firing's
            raise r.fail(
                f"{where}.{key}",
                f"unknown key {key!r}; did you mean 'firing.{key}'? (a sonar's own: "
                f"firing = {{ {key} = ... }}; every sonar's rate: [rig] rate_hz)",
            )
        sensor = _sensor(r, t, base, where, extra)
        name = r.string(t, "name", where, f"sonar{i}")
        sonars.append(RigSonar(name, sensor, _mount(r, t, where), _firing(r, t, where, firings[i])))
    lidars = []
    for where, t in r.table_list(data, "lidars"):
        preset = r._check(PRESET, t.get("preset", PRESET.default), f"{where}.preset")
        changed = r.settings(Lidar, t, where, extra={"preset"})
        lidars.append(
            dataclasses.replace(r.named(lidar_named, preset, f"{where}.preset"), **changed)
        )
    try:
        return Rig(tuple(sonars), poses, motion, tuple(lidars), **opts)
    except InputError as exc:  # keyed as the file: Rig.sonars[0].name -> sensors[0].name
        key = (exc.key or "").replace("Rig.sonars", "sensors", 1).replace("Rig.", "rig.", 1)
        key = key.replace("].sensor.", "].", 1)  # a [[sensors]] table is its Sensor's
        raise r.fail(key or "sensors", exc.reason, exc.value) from None


#: a rig sonar's ``firing`` keys (a hint when given in its table itself)
FIRING_KEYS = frozenset(settings_of(Firing)) | {"times_s"}


def _mount(r: _Reader, t: dict, where: str) -> Mount:
    """A rig sensor's ``mount``: position_m and rotation_deg (roll, pitch, yaw) in the
    body frame."""
    m = r.table(t, "mount", where)
    r.check_keys(m, "sensors.mount", f"{where}.mount")
    key = f"{where}.mount.rotation_deg"  # checked as Mount.degrees checks it
    rot = r._check(ROTATION_DEG, m.get("rotation_deg", ROTATION_DEG.default), key)
    return Mount.degrees(r.vector(m, "position_m", f"{where}.mount", [0.0, 0.0, 0.0]), rot)


def _firing(r: _Reader, t: dict, where: str, default: Firing) -> Firing:
    """A rig sensor's ``firing``: rate_hz and offset_s (and count), or times_s, not
    both; by default (and for the keys it leaves out) the rig's schedule."""
    if "firing" not in t:
        return default
    key = f"{where}.firing"
    f = r.settings(Firing, r.table(t, "firing", where), key, extra={"times_s"})
    if "times_s" not in r.table(t, "firing", where):
        f = {"rate_hz": default.rate_hz, "offset_s": default.offset_s, **f}
    try:
        return Firing(**f, times_s=t["firing"].get("times_s"))
    except InputError as exc:
        raise r.fail((exc.key or "").replace("Firing", key, 1), exc.reason, exc.value) from None


def _first_poses(rig: Rig) -> tuple[Pose, ...]:
    """A rig scene's ``sensor.poses``: its first sonar's at its firings."""
    return tuple(m.pose for m in rig.measurements() if m.sonar == 0) or (
        rig.sonars[0].mount.place(rig.poses[0]),
    )


def _materials(r: _Reader, data: dict) -> dict[str, model.Material]:
    """The scene's materials by name, ``default`` among them."""
    materials = {"default": model.Material("default")}
    for where, m in r.table_list(data, "materials"):
        if "name" not in m:
            raise r.fail(f"{where}.name", "missing")
        try:
            mat = model.Material(**r.settings(model.Material, m, where))
        except InputError as exc:  # a table's consistency, checked by the model
            key = f"{where}.{exc.key.split('.')[-1]}" if exc.key else where
            raise r.fail(key, exc.reason, exc.value) from None
        materials[mat.name] = mat
    return materials


def _mesh(r: _Reader, m: dict, where: str, base: Path, materials: dict) -> model.MeshItem:
    """One ``[[meshes]]`` table: its file (relative to `base`), materials (by name
    from `materials`), placement and motion."""
    r.check_keys(m, "meshes", where)
    file = base / r.string(m, "file", where)
    if not file.is_file():
        raise r.fail(f"{where}.file", f"mesh file not found: {file}", m["file"])
    r.files.append(file)
    mat = r.named(
        material_named, r.string(m, "material", where, "default"), f"{where}.material", materials
    )
    T = model.placement(
        r.string(m, "units", where, "m", set(UNITS)),
        r.number(m, "scale", where, 1.0, 1e-9, 1e9),
        r.vector(m, "position_m", where, [0.0, 0.0, 0.0]),
        r.vector(m, "rotation_deg", where, [0.0, 0.0, 0.0]),
    )
    if "units" not in m:
        _check_units(r, file, T, where)
    groups = r.table(m, "materials", where)
    by_group = {
        str(g): r.named(
            material_named,
            r.string(groups, g, f"{where}.materials"),
            f"{where}.materials.{g}",
            materials,
        )
        for g in groups
    }
    # a moving mesh: its velocity read through the declaration, its track as a point's
    v = settings_of(model.MeshItem)["velocity_m_s"]
    velocity = r._check(v, m.get("velocity_m_s", v.default), f"{where}.velocity_m_s")
    turn = r._check(
        MESH_TURN, m.get("angular_rate_deg_s", MESH_TURN.default), f"{where}.angular_rate_deg_s"
    )
    try:
        return model.MeshItem(
            file,
            mat,
            T,
            materials=by_group,
            velocity_m_s=velocity,
            track=_mesh_track(m.get("track")),
            angular_velocity_rad_s=tuple(np.deg2rad(turn)),
        )
    except InputError as exc:  # the track or the turn, checked by the model
        turn = (exc.key or "").endswith("angular_velocity_rad_s")
        key = "angular_rate_deg_s" if turn else "track"
        raise r.fail(f"{where}.{key}", exc.reason, m.get(key)) from None


def _check_units(r: _Reader, file: Path, T: np.ndarray, where: str) -> None:
    """A mesh whose table gives no ``units`` (read as metres) and that spans more than
    :data:`MAX_UNITLESS_SPAN_M` once placed: most likely drawn in millimetres; refused,
    saying to set ``units`` (an explicit ``units = "m"`` takes any size)."""
    extent = placed_extent_m(file, T)
    if extent is None or extent.max() <= MAX_UNITLESS_SPAN_M:
        return
    size = " x ".join(f"{v:.4g}" for v in extent)
    raise r.fail(
        f"{where}.units",
        f"{file.name} spans {size} m read in metres (no 'units' given), more than "
        f'{MAX_UNITLESS_SPAN_M:g} m: set units = "mm" (or "cm") for a mesh drawn in '
        f'those, or units = "m" if metres were meant',
    )


def _sensor(
    r: _Reader, s: dict, base: Path, where: str = "sensor", extra: set[str] | None = None
) -> model.Sensor:
    """``[sensor]`` (or a rig's ``[[sensors]]`` table, at `where`, with `extra` keys)."""
    extra = EXTRA_KEYS["sensor"] if extra is None else extra
    declared = r.settings(model.Sensor, s, where, extra=extra)
    if "coordinates" in s:
        units = r.string(s, "coordinates_units", where, "mm", {"mm", "m"})
        file = base / r.string(s, "coordinates", where)
        r.files.append(file)
        try:
            array = P.from_coordinates_file(file, units=units)
        except (OSError, ValueError) as exc:
            raise r.fail(f"{where}.coordinates", str(exc), s["coordinates"]) from None
    else:
        array = r.named(array_named, r.string(s, "array", where, "urtis_v1"), f"{where}.array")
    # the emitter as the Python constructor places it (acousim.scene.names), keyed here
    emitter = declared.get("emitter_m")
    array = r.named(with_emitter, array, f"{where}.emitter_m", emitter)
    call = s.get("call", "default_25_50")
    if isinstance(call, str):
        wf = r.named(call_named, r.string(s, "call", where, "default_25_50"), f"{where}.call")
    elif isinstance(call, dict):
        r.check_keys(call, "sensor.call", f"{where}.call")
        try:
            wf = P.Waveform(
                r.string(call, "kind", f"{where}.call", "linear", {"linear", "hyperbolic"}),
                r.number(call, "f_start_hz", f"{where}.call", 20e3, 1, 1e7),
                r.number(call, "f_end_hz", f"{where}.call", 85e3, 1, 1e7),
                r.number(call, "duration_s", f"{where}.call", 1e-3, 1e-6, 1),
                r.number(call, "taper", f"{where}.call", 0.0, 0, 0.5),
            )
        except InputError:
            raise
        except ValueError as exc:  # the waveform's own consistency checks
            raise r.fail(f"{where}.call", str(exc), call) from None
    else:
        raise r.fail(f"{where}.call", "must be a preset name or a table", call)
    fs = declared.get("sample_rate_hz", RTIS_SAMPLE_RATE_HZ)
    if max(wf.band_hz) >= fs / 2:
        raise r.fail(
            f"{where}.sample_rate_hz",
            f"is below twice the call's highest frequency {max(wf.band_hz):g} Hz",
            fs,
        )
    poses, rate = _poses(r, s, base, where)
    return model.Sensor(
        array=array,
        call=wf,
        poses=poses,
        rate_hz=rate,
        motion=_motion(r, s, poses, where),
        lidar=_lidar(r, s, where),
        **declared,
    )


def _lidar(r: _Reader, s: dict, where: str = "sensor") -> Lidar | None:
    """``[sensor.lidar]``: a preset, any of whose declared settings the table overrides."""
    if "lidar" not in s:
        return None
    t = r.table(s, "lidar", where)
    preset = r._check(PRESET, t.get("preset", PRESET.default), f"{where}.lidar.preset")
    changed = r.settings(Lidar, t, f"{where}.lidar", extra={"preset"})
    return dataclasses.replace(r.named(lidar_named, preset, f"{where}.lidar.preset"), **changed)


def _motion(r: _Reader, s: dict, poses: tuple[Pose, ...], where: str = "sensor"):
    """The sensor's motion during measurements: a trajectory moves through its poses
    (unless ``continuous = false``); a single pose moves if it has a velocity or an
    angular rate.  None: frozen poses."""
    if "trajectory" in s:
        t = s["trajectory"]
        key = f"{where}.trajectory.continuous"
        if r._check(CONTINUOUS, t.get("continuous", CONTINUOUS.default), key) and len(poses) >= 2:
            return Trajectory.through(poses)
        return None
    p = s.get("pose", {})
    v, w = (
        np.array(r._check(decl, p.get(name, decl.default), f"{where}.pose.{name}"))
        for name, decl in RATES.items()
    )
    if not (np.any(v) or np.any(w)):
        return None
    return Trajectory.constant(poses[0], v, np.deg2rad(w))


def _poses(
    r: _Reader, s: dict, base: Path, where: str = "sensor"
) -> tuple[tuple[Pose, ...], float | None]:
    if "trajectory" in s and "pose" in s:
        raise r.fail(where, "give either 'pose' or 'trajectory', not both")
    if "trajectory" in s:
        t = r.table(s, "trajectory", where)
        r.check_keys(t, "sensor.trajectory", f"{where}.trajectory")
        rate = r.number(t, "rate_hz", f"{where}.trajectory", 10.0, 1e-3, 1e4)
        if "file" in t and "poses" in t:
            raise r.fail(
                f"{where}.trajectory",
                "give either 'file' or 'poses' (the poses inline), not both",
            )
        if "file" in t:
            file = base / r.string(t, "file", f"{where}.trajectory")
            if not file.is_file():
                raise r.fail(f"{where}.trajectory.file", f"trajectory file not found: {file}")
            r.files.append(file)
            rows = _trajectory_csv(r, file, f"{where}.trajectory.file")
        else:
            given = t.get("poses")
            if not isinstance(given, list) or not given:
                raise r.fail(
                    f"{where}.trajectory.poses",
                    "must be a non-empty list of "
                    "[x, y, z, yaw_deg] (optionally pitch_deg, roll_deg)",
                )
            try:
                rows = np.array(given, float)
            except (ValueError, TypeError):
                raise r.fail(f"{where}.trajectory.poses", "rows must be lists of numbers") from None
        if rows.ndim != 2 or rows.shape[1] not in (4, 5, 6) or not np.all(np.isfinite(rows)):
            raise r.fail(
                f"{where}.trajectory",
                f"rows must be [x, y, z, yaw_deg(, pitch_deg, "
                f"roll_deg)] of finite numbers, got shape {rows.shape}",
            )
        for i, row in enumerate(rows):
            for (name, decl), v in zip(POSE_ANGLES.items(), row[3:]):
                r._check(decl, float(v), f"{where}.trajectory row {i} {name}")
        ang = np.deg2rad(np.pad(rows[:, 3:], ((0, 0), (0, 6 - rows.shape[1]))))
        return tuple(
            Pose(row[:3], a[0], a[1], a[2], time_s=i / rate)
            for i, (row, a) in enumerate(zip(rows, ang))
        ), rate
    p = r.table(s, "pose", where)
    r.check_keys(p, "sensor.pose", f"{where}.pose")
    angles = {
        name: np.deg2rad(r._check(decl, p.get(name, decl.default), f"{where}.pose.{name}"))
        for name, decl in POSE_ANGLES.items()
    }
    pose = Pose(
        r.vector(p, "position_m", f"{where}.pose", [0.0, 0.0, 0.0]),
        angles["yaw_deg"],
        angles["pitch_deg"],
        angles["roll_deg"],
    )
    return (pose,), None


#: the columns of a trajectory: a CSV file's rows, or the inline `poses`
TRAJECTORY_COLUMNS = "x, y, z, yaw_deg[, pitch_deg, roll_deg] (m, degrees)"


def _trajectory_csv(r: _Reader, file: Path, key: str) -> np.ndarray:
    """A trajectory CSV file's rows (N, 4 to 6): numbers separated by commas, no header
    row; ``#`` starts a comment, blank lines are skipped.  A header, a field that is not
    a number or a row of another length is refused naming the file's line."""
    rows: list[list[float]] = []
    first = 0  # the line of the first row
    for line_no, line in enumerate(file.read_text(errors="replace").splitlines(), 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        fields = [f.strip() for f in text.split(",")]
        try:
            row = [float(f) for f in fields]
        except ValueError:
            bad = next(f for f in fields if not _is_float(f))
            if not rows:
                raise r.fail(
                    key,
                    f"{file}: line {line_no} ({text!r}) is not numbers: a trajectory CSV "
                    f"has no header row (its columns are {TRAJECTORY_COLUMNS}); "
                    "remove the line or start it with '#'",
                ) from None
            raise r.fail(key, f"{file}: line {line_no}: {bad!r} is not a number") from None
        if len(row) not in (4, 5, 6) or (rows and len(row) != len(rows[0])):
            expected = f"{len(rows[0])} (as line {first})" if rows else "4, 5 or 6"
            raise r.fail(
                key,
                f"{file}: line {line_no} has {len(row)} column(s), {expected} expected "
                f"({TRAJECTORY_COLUMNS})",
            )
        first = first or line_no
        rows.append(row)
    if not rows:
        raise r.fail(key, f"{file}: no rows ({TRAJECTORY_COLUMNS})")
    return np.array(rows, float)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _mesh_track(value):
    """A mesh's track as the model takes it: rows [t_s, x, y, z] as they are; rows
    [t_s, x, y, z, roll_deg, pitch_deg, yaw_deg] with the angles in radians
    (anything else is passed on, for the model's error)."""
    try:
        rows = np.array(value, float)
    except (TypeError, ValueError):
        return value
    if rows.ndim != 2 or rows.shape[1] != 7:
        return value
    rows[:, 4:] = np.deg2rad(rows[:, 4:])
    return rows.tolist()
