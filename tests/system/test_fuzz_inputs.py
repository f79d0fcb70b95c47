"""Fuzzed scene files and dataset specs: every file is either refused with an InputError
naming the file and the key, or accepted with exactly the value written, and only when
that value is allowed.

The allowed values are an oracle written here from the documentation
(docs/scene-format.md, docs/dataset-format.md), independent of the declarations in
the code. Any other exception (a traceback) fails the test.
"""

from __future__ import annotations

import json
import math

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from acousim.dataset.spec import load_spec  # noqa: E402
from acousim.scene import load_scene  # noqa: E402
from processing.base.errors import InputError  # noqa: E402
from tests import REPO  # noqa: E402

SCENES = REPO / "scenes"
# derandomize: the same examples on every run (every random choice takes a seed)
FUZZ = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def real(lo, hi):
    return lambda v: _number(v) and not math.isnan(v) and lo <= v <= hi


def whole(lo, hi):
    return lambda v: real(lo, hi)(v) and float(v).is_integer()


def boolean(v) -> bool:
    return isinstance(v, bool)


def one_of(*names):
    return lambda v: isinstance(v, str) and v in names


def vector3(v) -> bool:
    return isinstance(v, list) and len(v) == 3 and all(_number(x) and math.isfinite(x) for x in v)


def vector3_in(lo, hi):
    return lambda v: vector3(v) and all(lo <= x <= hi for x in v)


def interval(lo, hi):
    def ok(v):
        return (
            isinstance(v, list)
            and len(v) == 2
            and all(_number(x) and math.isfinite(x) and lo <= x <= hi for x in v)
            and v[0] <= v[1]
        )

    return ok


# (table, key): what docs/scene-format.md allows. The base scene uses the default call
# (25-50 kHz), so the sample rate must also exceed 100 kHz.
SCENE_ORACLE = {
    ("environment", "temperature_c"): (real(-20, 50), (-20, 50)),
    ("environment", "humidity_percent"): (real(0, 100), (0, 100)),
    ("environment", "pressure_kpa"): (real(50, 120), (50, 120)),
    ("simulation", "max_range_m"): (real(0.05, 100), (0.05, 100)),
    ("simulation", "rays"): (whole(0, 10_000_000), (0, 10_000_000)),
    ("simulation", "bounces"): (whole(0, 6), (0, 6)),
    ("simulation", "beam_deg"): (real(1, 180), (1, 180)),
    ("simulation", "snr_db"): (real(-60, math.inf), (-60, math.inf)),
    ("simulation", "seed"): (whole(0, 2**63 - 1), (0, 2**63 - 1)),
    ("simulation", "fractional_delay"): (one_of("sinc", "lagrange", "nearest"), None),
    ("simulation", "absorption"): (boolean, None),
    ("simulation", "energy_floor_db"): (real(-300, 0), (-300, 0)),
    ("simulation", "render_rate"): (one_of("full", "baseband"), None),
    ("simulation", "render_domain"): (one_of("auto", "frequency", "time"), None),
    ("simulation", "render_band_db"): (real(-200, -10), (-200, -10)),
    ("simulation", "render_tolerance"): (real(1e-6, 0.3), (1e-6, 0.3)),
    ("materials", "reflection"): (real(0, 1), (0, 1)),
    ("materials", "diffuse"): (real(0, 1), (0, 1)),
    ("materials", "lobe_deg"): (real(0.1, 90), (0.1, 90)),
    # a table needs reflection or diffuse as a list of as many values: alone, only empty
    ("materials", "frequencies_khz"): (lambda v: v == [], None),
    ("points", "strength"): (real(0, 1e6), (0, 1e6)),
    ("points", "position_m"): (vector3, None),
    ("points", "velocity_m_s"): (vector3_in(-100, 100), None),
    ("sensor", "sample_rate_hz"): (lambda v: real(1e3, 1e8)(v) and v > 100e3, (1e5, 1e8)),
    ("sensor", "emitter_radius_m"): (real(0, 0.5), (0, 0.5)),
    ("sensor", "mic_radius_m"): (real(0, 0.05), (0, 0.05)),
    ("sensor", "direct_path"): (boolean, None),
    ("sensor.pose", "yaw_deg"): (real(-360, 360), (-360, 360)),
    ("sensor.pose", "pitch_deg"): (real(-90, 90), (-90, 90)),
}


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return (
            "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        )
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"


def toml(doc: dict) -> str:
    """A small TOML writer for the documents built here (tables, arrays of tables)."""
    lines = []
    for name, table in doc.items():
        if isinstance(table, list):
            for t in table:
                lines.append(f"[[{name}]]")
                lines += [f"{k} = {toml_value(v)}" for k, v in t.items()]
        else:
            lines.append(f"[{name}]")
            lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


scalar = st.one_of(
    st.booleans(),
    st.integers(-(2**64), 2**64),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=8),
)
junk = st.one_of(
    scalar,
    st.lists(st.one_of(st.integers(-5, 5), st.floats(-1e3, 1e3), st.just(math.nan)), max_size=4),
    st.dictionaries(st.sampled_from(["a", "b"]), st.integers(0, 3), max_size=2),
)


def near_bounds(bounds):
    """Values at, just inside and just outside the documented bounds."""
    if bounds is None:
        return st.nothing()
    vals = []
    for b in bounds:
        if math.isfinite(b):
            vals += [b, math.nextafter(b, -math.inf), math.nextafter(b, math.inf), int(b)]
            vals += [int(b) - 1, int(b) + 1]
        else:
            vals.append(b)
    return st.sampled_from(vals)


@st.composite
def scene_case(draw, table, key):
    ok, bounds = SCENE_ORACLE[(table, key)]
    value = draw(st.one_of(junk, near_bounds(bounds)))
    doc = {
        "sensor": {"array": "urtis_v1"},
        "sensor.pose": {"position_m": [0.0, 0.0, 0.0]},
        "simulation": {"max_range_m": 2.0},
        "materials": [{"name": "m", "reflection": 0.5}],
        "points": [{"position_m": [1.0, 0.0, 0.0]}],
    }
    target = doc.setdefault(table, {})
    (target[0] if isinstance(target, list) else target)[key] = value
    return table, key, value, ok(value), toml(doc)


def _loaded(scene, table, key):
    obj = {
        "environment": scene.environment,
        "simulation": scene.simulation,
        "sensor": scene.sensor,
        "materials": scene.materials.get("m"),
        "points": scene.points[0],
    }.get(table)
    if table == "sensor.pose":
        import numpy as np

        pose = scene.sensor.poses[0]
        return float(np.rad2deg({"yaw_deg": pose.yaw_rad, "pitch_deg": pose.pitch_rad}[key]))
    v = getattr(obj, key)
    return list(v) if isinstance(v, tuple) else v


def fuzzed(oracle):
    """A test run for every (table, key) of `oracle`, with hypothesis drawing `data`."""

    def wrap(test):
        return pytest.mark.parametrize("table,key", sorted(oracle))(
            FUZZ(given(data=st.data())(test))
        )

    return wrap


def _loads_or_names_the_file(load, path, text) -> None:
    """`text` written to `path` loads, or is refused with an InputError naming the file."""
    path.write_text(text)
    try:
        load(path)
    except InputError as exc:
        assert str(exc).startswith(str(path)), str(exc)


def _drawn(data, strategy, load, path):
    """A case drawn from `strategy`, written to `path` and loaded (:func:`_accepted`):
    its value and the loaded result (None if refused)."""
    case = data.draw(strategy)
    return case[2], _accepted(load, path, case)


def _accepted(load, path, case):
    """`case` (table, key, value, allowed, text) written to `path` and loaded: the
    result if accepted (it must be allowed), None if refused (it must not be, with
    an InputError naming the file and the key)."""
    table, key, value, allowed, text = case
    path.write_text(text)
    try:
        loaded = load(path)
    except InputError as exc:
        assert not allowed, f"{table}.{key} = {value!r} is allowed but refused: {exc}"
        assert str(exc).startswith(f"{path}: ") and key in str(exc), str(exc)
        return None
    assert allowed, f"{table}.{key} = {value!r} was silently accepted"
    return loaded


@fuzzed(SCENE_ORACLE)
def test_fuzzed_scene_files(tmp_path, table, key, data):
    value, scene = _drawn(data, scene_case(table, key), load_scene, tmp_path / "fuzz.toml")
    if scene is None:
        return
    got = _loaded(scene, table, key)
    if isinstance(value, float | int) and not isinstance(value, bool):
        assert math.isclose(got, value, rel_tol=1e-12, abs_tol=1e-9)
    else:
        assert got == value


@FUZZ
@given(key=st.text(st.characters(min_codepoint=97, max_codepoint=122), min_size=1, max_size=12))
def test_fuzzed_unknown_scene_keys(tmp_path, key):
    known = {k for (t, k) in SCENE_ORACLE if t == "simulation"} | {"max_memory_gb"}
    hypothesis.assume(key not in known)
    path = tmp_path / "fuzz.toml"
    path.write_text(
        f'[sensor]\narray = "urtis_v1"\n[simulation]\n{key} = 1\n'
        "[[points]]\nposition_m = [1, 0, 0]\n"
    )
    with pytest.raises(InputError, match=f"simulation.{key}: unknown key"):
        load_scene(path)


# ---- dataset specs (docs/dataset-format.md) ----
SPEC_ORACLE = {
    ("dataset", "samples"): (whole(1, 1e9), (1, 1e9)),
    ("dataset", "shard_size"): (whole(1, 1e6), (1, 1e6)),
    ("dataset", "seed"): (whole(0, 2**63 - 1), (0, 2**63 - 1)),
    ("dataset", "compression"): (one_of("gzip", "lzf", "none"), None),
    ("store", "raw"): (boolean, None),
    ("store", "snapshot"): (boolean, None),
    ("store", "depth_map"): (boolean, None),
    ("store", "step_deg"): (real(0.1, 45), (0.1, 45)),
    ("store", "energy_fraction"): (real(0, 1), (0, 1)),
    ("store", "min_range_m"): (real(0, 100), (0, 100)),
    ("store", "max_bins"): (whole(1, 1e6), (1, 1e6)),
    ("store", "azimuth_deg"): (interval(-90, 90), None),
    ("store", "elevation_deg"): (interval(-90, 90), None),
    ("randomize", "humidity_percent"): (real(0, 100), (0, 100)),
    ("randomize", "temperature_c"): (real(-20, 50), (-20, 50)),
    ("randomize", "snr_db"): (real(-60, math.inf), (-60, math.inf)),
    ("randomize", "speed_m_s"): (real(-100, 100), (-100, 100)),
    ("randomize", "turn_rate_deg_s"): (real(-3600, 3600), (-3600, 3600)),
    ("scenes", "weight"): (lambda v: real(0, 1e6)(v) and v > 0, (0, 1e6)),
    ("scenes", "clearance_m"): (real(0, 10), (0, 10)),
    ("region", "x"): (interval(-1e4, 1e4), None),
    ("region", "yaw_deg"): (interval(-360, 360), None),
}


@st.composite
def spec_case(draw, table, key):
    ok, bounds = SPEC_ORACLE[(table, key)]
    value = draw(
        st.one_of(junk, near_bounds(bounds), st.lists(st.floats(-100, 100), min_size=2, max_size=2))
    )
    region = {"x": [0.0, 1.0], "y": [0.0, 1.0], "z": [0.0, 1.0]}
    scene = {"file": str(SCENES / "wall.toml"), "poses": "random", "region": region}
    doc = {"dataset": {"samples": 4}, "scenes": [scene], "store": {}, "randomize": {}}
    if table == "region":
        region[key] = value
    elif table == "scenes":
        scene[key] = value
    else:
        doc[table][key] = value
    return table, key, value, ok(value), toml(doc)


@fuzzed(SPEC_ORACLE)
def test_fuzzed_dataset_specs(tmp_path, table, key, data):
    value, spec = _drawn(data, spec_case(table, key), load_spec, tmp_path / "spec.toml")
    if spec is None:
        return
    if table == "randomize":
        d = spec.randomize[key]
        # a TOML integer is read as the float nearest to it (2**53 + 1 -> 2**53)
        assert d.kind == "constant" and (d.a == float(value) or math.isinf(value))
    elif table == "region":
        assert list(spec.scenes[0].region[key]) == value
    elif table == "scenes":
        assert getattr(spec.scenes[0], key) == value
    elif table == "store":
        got = getattr(spec.store, key)
        assert (list(got) if isinstance(got, tuple) else got) == value
    elif key == "compression":
        assert spec.compression == (None if value == "none" else value)
    else:
        assert getattr(spec, key) == value


STRUCTURE = [
    ("", "environment"),
    ("", "simulation"),
    ("", "sensor"),
    ("", "scene"),
    ("", "materials"),
    ("", "meshes"),
    ("", "points"),
    ("sensor", "pose"),
    ("sensor", "call"),
    ("sensor", "trajectory"),
    ("sensor", "array"),
    ("sensor", "coordinates"),
    ("sensor", "emitter_m"),
    ("meshes", "file"),
    ("meshes", "material"),
    ("meshes", "rotation_deg"),
    ("meshes", "units"),
    ("materials", "name"),
]
shapes = st.one_of(
    junk,
    st.lists(
        st.dictionaries(st.sampled_from(["file", "name", "x"]), scalar, max_size=2), max_size=2
    ),
    st.dictionaries(
        st.sampled_from(["poses", "file", "rate_hz", "kind", "f_start_hz", "yaw_deg"]),
        st.one_of(scalar, st.lists(st.lists(st.integers(-400, 400), max_size=7), max_size=3)),
        max_size=3,
    ),
)


@pytest.mark.parametrize("table,key", STRUCTURE)
@FUZZ
@given(data=st.data())
def test_fuzzed_scene_structure(tmp_path, table, key, data):
    """Tables, arrays of tables and nested keys replaced by values of any shape: either
    a scene or an InputError naming the file, never another exception."""
    import shutil

    shutil.copy(SCENES / "meshes" / "wall.stl", tmp_path / "wall.stl")
    value = data.draw(shapes)
    doc = {
        "sensor": {"array": "urtis_v1"},
        "meshes": [{"file": "wall.stl"}],
        "materials": [{"name": "m"}],
        "points": [{"position_m": [1.0, 0.0, 0.0]}],
    }
    if table == "":
        doc[key] = value
    else:
        target = doc[table]
        (target[0] if isinstance(target, list) else target)[key] = value
    top = {k: v for k, v in doc.items() if not isinstance(v, dict | list) or not v}
    tables = {k: v for k, v in doc.items() if k not in top}
    lines = [f"{k} = {toml_value(v)}" for k, v in top.items()]
    text = (
        "\n".join(lines)
        + "\n"
        + toml(
            {
                k: v
                for k, v in tables.items()
                if isinstance(v, dict) or all(isinstance(x, dict) for x in v)
            }
        )
    )
    for k, v in tables.items():
        if isinstance(v, list) and not all(isinstance(x, dict) for x in v):
            text = f"{k} = {toml_value(v)}\n" + text
    _loads_or_names_the_file(load_scene, tmp_path / "fuzz.toml", text)


SPEC_STRUCTURE = [
    ("", "dataset"),
    ("", "scenes"),
    ("", "randomize"),
    ("", "store"),
    ("scenes", "region"),
    ("scenes", "file"),
    ("scenes", "poses"),
    ("randomize", "snr_db"),
    ("randomize", "mount_jitter_m"),
    ("store", "images"),
]


@pytest.mark.parametrize("table,key", SPEC_STRUCTURE)
@FUZZ
@given(data=st.data())
def test_fuzzed_spec_structure(tmp_path, table, key, data):
    value = data.draw(shapes)
    doc = {
        "dataset": {"samples": 2},
        "scenes": [{"file": str(SCENES / "wall.toml")}],
        "randomize": {"snr_db": 20.0},
        "store": {"raw": False},
    }
    if table == "":
        doc[key] = value
    else:
        target = doc[table]
        (target[0] if isinstance(target, list) else target)[key] = value
    text = ""
    for k, v in doc.items():
        if (
            isinstance(v, dict)
            and v
            or isinstance(v, list)
            and v
            and all(isinstance(x, dict) for x in v)
        ):
            text += toml({k: v})
        else:
            text = f"{k} = {toml_value(v)}\n" + text
    _loads_or_names_the_file(load_spec, tmp_path / "spec.toml", text)
