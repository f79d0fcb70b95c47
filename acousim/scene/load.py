"""Reading and validating scene files (TOML); the format is documented in
``docs/scene-format.md``.

Every error names the file, the key and the bad value, and says what is allowed;
an unknown key gets a did-you-mean.
"""

from __future__ import annotations

import difflib
import hashlib
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

import processing as P

from .model import Environment, Material, MeshItem, PointItem, Scene, Sensor, Simulation
from .pose import Pose, rotation

__all__ = ["SceneError", "load_scene", "parse_scene"]


class SceneError(ValueError):
    """A scene file that cannot be used; the message names the file, key and value."""


NUM = (int, float)
KEYS: dict[str, set[str]] = {
    "": {"scene", "environment", "sensor", "simulation", "materials", "meshes", "points"},
    "scene": {"name", "description"},
    "environment": {"temperature_c", "humidity_percent", "pressure_kpa"},
    "sensor": {
        "array",
        "coordinates",
        "coordinates_units",
        "emitter_m",
        "emitter_radius_m",
        "mic_radius_m",
        "call",
        "sample_rate_hz",
        "direct_path",
        "pose",
        "trajectory",
    },
    "sensor.call": {"kind", "f_start_hz", "f_end_hz", "duration_s", "taper"},
    "sensor.pose": {"position_m", "yaw_deg", "pitch_deg", "roll_deg"},
    "sensor.trajectory": {"poses", "file", "rate_hz"},
    "simulation": {
        "max_range_m",
        "rays",
        "bounces",
        "beam_deg",
        "snr_db",
        "seed",
        "fractional_delay",
        "absorption",
        "energy_floor_db",
        "diffraction",
        "diffraction_step_m",
        "diffraction_reflections",
    },
    "materials": {"name", "reflection", "diffuse", "lobe_deg"},
    "meshes": {"file", "material", "units", "position_m", "rotation_deg", "scale"},
    "points": {"position_m", "strength"},
}
UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}


class _Reader:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, msg: str) -> SceneError:
        return SceneError(f"{self.source}: [{key}] {msg}")

    def check_keys(self, table: dict, section: str, where: str) -> None:
        allowed = KEYS[section]
        for k in table:
            if k not in allowed:
                close = difflib.get_close_matches(k, sorted(allowed), n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.fail(
                    f"{where}.{k}".strip("."),
                    f"unknown key {k!r}{hint} (allowed: {', '.join(sorted(allowed))})",
                )

    def table(self, d: dict, key: str, where: str) -> dict:
        v = d.get(key, {})
        if not isinstance(v, dict):
            raise self.fail(f"{where}.{key}".strip("."), f"must be a table, got {v!r}")
        return v

    def table_list(self, data: dict, key: str):
        """(where, table) for each table of an array of tables ``[[key]]``, keys checked."""
        items = data.get(key, [])
        if not isinstance(items, list):
            raise self.fail(key, f"must be an array of tables ([[{key}]])")
        for i, t in enumerate(items):
            where = f"{key}[{i}]"
            if not isinstance(t, dict):
                raise self.fail(where, "must be a table")
            self.check_keys(t, key, where)
            yield where, t

    def number(
        self,
        d: dict,
        key: str,
        where: str,
        default: float,
        lo: float = -math.inf,
        hi: float = math.inf,
        integer: bool = False,
    ) -> float:
        v = d.get(key, default)
        name = f"{where}.{key}"
        if isinstance(v, bool) or not isinstance(v, NUM):
            raise self.fail(name, f"must be a number, got {v!r}")
        if integer and (not float(v).is_integer()):
            raise self.fail(name, f"must be a whole number, got {v!r}")
        if math.isnan(v) or not lo <= v <= hi:
            raise self.fail(name, f"value {v!r} outside the allowed range [{lo}, {hi}]")
        return int(v) if integer else float(v)

    def vector(self, d: dict, key: str, where: str, default=None) -> np.ndarray:
        v = d.get(key, default)
        name = f"{where}.{key}"
        if v is None:
            raise self.fail(name, "missing (a list of 3 numbers)")
        if (
            not isinstance(v, list)
            or len(v) != 3
            or not all(isinstance(x, NUM) and not isinstance(x, bool) for x in v)
            or not all(math.isfinite(x) for x in v)
        ):
            raise self.fail(name, f"must be a list of 3 finite numbers, got {v!r}")
        return np.array(v, float)

    def string(
        self,
        d: dict,
        key: str,
        where: str,
        default: str | None = None,
        choices: set[str] | None = None,
    ) -> str:
        v = d.get(key, default)
        name = f"{where}.{key}"
        if v is None:
            raise self.fail(name, "missing")
        if not isinstance(v, str):
            raise self.fail(name, f"must be a string, got {v!r}")
        if choices is not None and v not in choices:
            close = difflib.get_close_matches(v, sorted(choices), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise self.fail(name, f"{v!r} is not one of {', '.join(sorted(choices))}{hint}")
        return v

    def boolean(self, d: dict, key: str, where: str, default: bool) -> bool:
        v = d.get(key, default)
        if not isinstance(v, bool):
            raise self.fail(f"{where}.{key}", f"must be true or false, got {v!r}")
        return v


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: no such scene file")
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: not valid TOML ({exc})") from None
    return parse_scene(
        data, base_dir=path.parent, source=str(path), sha256=hashlib.sha256(raw).hexdigest()
    )


def parse_scene(
    data: dict[str, Any],
    *,
    base_dir: str | Path = ".",
    source: str = "<scene>",
    sha256: str | None = None,
) -> Scene:
    """Validate a scene given as a dict (the parsed TOML)."""
    r = _Reader(source)
    base = Path(base_dir)
    r.check_keys(data, "", "")
    meta = r.table(data, "scene", "")
    r.check_keys(meta, "scene", "scene")
    env_t = r.table(data, "environment", "")
    r.check_keys(env_t, "environment", "environment")
    env = Environment(
        temperature_c=r.number(env_t, "temperature_c", "environment", 20.0, -20, 50),
        humidity_percent=r.number(env_t, "humidity_percent", "environment", 50.0, 0, 100),
        pressure_kpa=r.number(env_t, "pressure_kpa", "environment", 101.325, 50, 120),
    )
    sim_t = r.table(data, "simulation", "")
    r.check_keys(sim_t, "simulation", "simulation")
    from acousim.synth.render import METHODS

    sim = Simulation(
        max_range_m=r.number(sim_t, "max_range_m", "simulation", 6.0, 0.05, 100),
        rays=r.number(sim_t, "rays", "simulation", 20000, 0, 10_000_000, integer=True),
        bounces=r.number(sim_t, "bounces", "simulation", 2, 0, 6, integer=True),
        beam_deg=r.number(sim_t, "beam_deg", "simulation", 90.0, 1, 180),
        snr_db=r.number(sim_t, "snr_db", "simulation", math.inf, -60, math.inf),
        seed=r.number(sim_t, "seed", "simulation", 0, 0, 2**63 - 1, integer=True),
        fractional_delay=r.string(
            sim_t,
            "fractional_delay",
            "simulation",
            "sinc",
            {"sinc", "lagrange", "nearest"} & set(METHODS),
        ),
        absorption=r.boolean(sim_t, "absorption", "simulation", True),
        energy_floor_db=r.number(sim_t, "energy_floor_db", "simulation", -80.0, -300, 0),
        diffraction=r.boolean(sim_t, "diffraction", "simulation", False),
        diffraction_step_m=r.number(sim_t, "diffraction_step_m", "simulation", 1e-3, 1e-5, 0.1),
        diffraction_reflections=r.boolean(sim_t, "diffraction_reflections", "simulation", False),
    )
    materials = {"default": Material("default")}
    for where, m in r.table_list(data, "materials"):
        name = r.string(m, "name", where)
        materials[name] = Material(
            name,
            reflection=r.number(m, "reflection", where, 0.95, 0, 1),
            diffuse=r.number(m, "diffuse", where, 0.0, 0, 1),
            lobe_deg=r.number(m, "lobe_deg", where, 5.0, 0.1, 90),
        )
    meshes = []
    for where, m in r.table_list(data, "meshes"):
        file = base / r.string(m, "file", where)
        if not file.is_file():
            raise r.fail(f"{where}.file", f"mesh file not found: {file}")
        mat = r.string(m, "material", where, "default", set(materials))
        units = r.string(m, "units", where, "m", set(UNITS))
        scale = r.number(m, "scale", where, 1.0, 1e-9, 1e9) * UNITS[units]
        rot = np.deg2rad(r.vector(m, "rotation_deg", where, [0.0, 0.0, 0.0]))
        T = np.eye(4)
        T[:3, :3] = rotation(rot[2], rot[1], rot[0]) * scale  # (roll, pitch, yaw) given x,y,z
        T[:3, 3] = r.vector(m, "position_m", where, [0.0, 0.0, 0.0])
        meshes.append(MeshItem(file, materials[mat], T))
    points = []
    for where, p in r.table_list(data, "points"):
        points.append(
            PointItem(
                tuple(r.vector(p, "position_m", where)), r.number(p, "strength", where, 1.0, 0, 1e6)
            )
        )
    sensor = _sensor(r, r.table(data, "sensor", ""), base)
    if not meshes and not points:
        raise r.fail("meshes", "the scene has neither meshes nor points: nothing can echo")
    return Scene(
        name=r.string(meta, "name", "scene", Path(source).stem),
        description=r.string(meta, "description", "scene", ""),
        source=Path(source) if source != "<scene>" else None,
        file_sha256=sha256,
        materials=materials,
        meshes=tuple(meshes),
        points=tuple(points),
        sensor=sensor,
        environment=env,
        simulation=sim,
    )


def _sensor(r: _Reader, s: dict, base: Path) -> Sensor:
    r.check_keys(s, "sensor", "sensor")
    if "coordinates" in s:
        units = r.string(s, "coordinates_units", "sensor", "mm", {"mm", "m"})
        file = base / r.string(s, "coordinates", "sensor")
        try:
            array = P.from_coordinates_file(file, units=units)
        except (OSError, ValueError) as exc:
            raise r.fail("sensor.coordinates", str(exc)) from None
    else:
        name = r.string(s, "array", "sensor", "urtis_v1", set(P.PRESETS))
        array = P.preset(name)
    emitter = r.vector(s, "emitter_m", "sensor", [0.0, 0.0, 0.0])
    array = P.Array(
        array.name, array.positions_m, emitter, array.grid_index, array.pitch_m, array.channels
    )
    call = s.get("call", "default_25_50")
    if isinstance(call, str):
        presets = {"default_25_50", "default_20_80", "paper"}
        name = r.string(s, "call", "sensor", "default_25_50", choices=presets)
        wf = P.paper_chirp() if name == "paper" else P.rtis_call(name)
    elif isinstance(call, dict):
        r.check_keys(call, "sensor.call", "sensor.call")
        try:
            wf = P.Waveform(
                r.string(call, "kind", "sensor.call", "linear", {"linear", "hyperbolic"}),
                r.number(call, "f_start_hz", "sensor.call", 20e3, 1, 1e7),
                r.number(call, "f_end_hz", "sensor.call", 85e3, 1, 1e7),
                r.number(call, "duration_s", "sensor.call", 1e-3, 1e-6, 1),
                r.number(call, "taper", "sensor.call", 0.0, 0, 0.5),
            )
        except ValueError as exc:
            raise r.fail("sensor.call", str(exc)) from None
    else:
        raise r.fail("sensor.call", f"must be a preset name or a table, got {call!r}")
    fs = r.number(s, "sample_rate_hz", "sensor", 450e3, 1e3, 1e8)
    if max(wf.band_hz) >= fs / 2:
        raise r.fail(
            "sensor.sample_rate_hz",
            f"{fs:g} Hz is below twice the call's highest frequency {max(wf.band_hz):g}",
        )
    poses, rate = _poses(r, s, base)
    return Sensor(
        array,
        wf,
        fs,
        r.number(s, "emitter_radius_m", "sensor", 0.0, 0, 0.5),
        r.boolean(s, "direct_path", "sensor", True),
        poses,
        rate,
        r.number(s, "mic_radius_m", "sensor", 0.0, 0, 0.05),
    )


def _poses(r: _Reader, s: dict, base: Path) -> tuple[tuple[Pose, ...], float | None]:
    if "trajectory" in s and "pose" in s:
        raise r.fail("sensor", "give either 'pose' or 'trajectory', not both")
    if "trajectory" in s:
        t = r.table(s, "trajectory", "sensor")
        r.check_keys(t, "sensor.trajectory", "sensor.trajectory")
        rate = r.number(t, "rate_hz", "sensor.trajectory", 10.0, 1e-3, 1e4)
        if "file" in t:
            file = base / r.string(t, "file", "sensor.trajectory")
            if not file.is_file():
                raise r.fail("sensor.trajectory.file", f"trajectory file not found: {file}")
            try:
                rows = np.loadtxt(file, delimiter=",", comments="#", ndmin=2)
            except ValueError as exc:
                raise r.fail("sensor.trajectory.file", f"{file}: {exc}") from None
        else:
            rows = t.get("poses")
            if not isinstance(rows, list) or not rows:
                raise r.fail(
                    "sensor.trajectory.poses",
                    "must be a non-empty list of "
                    "[x, y, z, yaw_deg] (optionally pitch_deg, roll_deg)",
                )
            try:
                rows = np.array(rows, float)
            except (ValueError, TypeError):
                raise r.fail("sensor.trajectory.poses", "rows must be lists of numbers") from None
        if rows.ndim != 2 or rows.shape[1] not in (4, 5, 6) or not np.all(np.isfinite(rows)):
            raise r.fail(
                "sensor.trajectory",
                f"rows must be [x, y, z, yaw_deg(, pitch_deg, "
                f"roll_deg)] of finite numbers, got shape {rows.shape}",
            )
        ang = np.deg2rad(np.pad(rows[:, 3:], ((0, 0), (0, 6 - rows.shape[1]))))
        return tuple(
            Pose(row[:3], *a, time_s=i / rate) for i, (row, a) in enumerate(zip(rows, ang))
        ), rate
    p = r.table(s, "pose", "sensor")
    r.check_keys(p, "sensor.pose", "sensor.pose")
    pose = Pose(
        r.vector(p, "position_m", "sensor.pose", [0.0, 0.0, 0.0]),
        np.deg2rad(r.number(p, "yaw_deg", "sensor.pose", 0.0, -360, 360)),
        np.deg2rad(r.number(p, "pitch_deg", "sensor.pose", 0.0, -90, 90)),
        np.deg2rad(r.number(p, "roll_deg", "sensor.pose", 0.0, -360, 360)),
    )
    return (pose,), None
