"""Fuzzed recording files, field by field: every HDF5 attribute, dataset and metadata
key of a valid file is deleted or replaced by a value of another type, shape or range.
The loader either refuses the file with a RecordingFileError naming it, or returns a
recording that everything downstream accepts: it is written again and reads back the
same, it is imaged (or refused with an InputError) and described by ``acousim info``,
all without a traceback or a numerical warning. Nothing is accepted and later refused.
"""

from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
import h5py  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import processing as P  # noqa: E402
from processing.base.errors import InputError  # noqa: E402

# ACOUSIM_FUZZ_EXAMPLES=2000 for a deeper search than the suite's
FUZZ = settings(
    max_examples=int(os.environ.get("ACOUSIM_FUZZ_EXAMPLES", "60")),
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

METADATA = {
    "scene": "fuzz",
    "scene_file": None,
    "simulated": True,
    "seed": 3,
    "pose_index": 2,
    "n_paths": 3,
    "max_range_m": 2.0,
    "pose": {"position_m": [1.0, 2.0, 0.5], "yaw_deg": 10, "pitch_deg": 0, "roll_deg": 0},
    "motion": {
        "emission_pose": {"position_m": [1.0, 2.0, 0.5], "yaw_deg": 10, "time_s": 0.0},
        "velocity_m_s": [0.5, 0.0, 0.0],
        "angular_velocity_deg_s": [0.0, 0.0, 30.0],
        "doppler_min": 0.999,
        "doppler_max": 1.001,
    },
}


def base_recording() -> P.Recording:
    """2 x 2 URA, 1024 samples at 450 kHz: noise and one echo, with a ground truth."""
    rng = np.random.default_rng(11)
    x = 0.01 * rng.standard_normal((4, 1024))
    call = P.rtis_call("default_25_50").sampled(450e3)
    x[:, 400 : 400 + call.size] += call[:624]
    truth = P.GroundTruth(
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]],
        [0.5, 0.25, 1.0],
        [1, 2, 0],
        ["specular", "scatter", "direct"],
    )
    return P.Recording(
        x, 450e3, P.ura(2, 2, 4e-3), P.rtis_call("default_25_50"), 343.0, 5, METADATA, truth
    )


GROUP = "recordings/000000"
ATTRS = ["sample_rate_hz", "speed_of_sound_m_s", "emission_index", "array_name", "waveform"]
ROOT_ATTRS = ["schema", "schema_version", "count"]
DATASETS = [
    "samples",
    "array/positions",
    "array/emitter",
    "array/channels",
    "array/grid_index",
    "truth/position_world_m",
    "truth/position_sensor_m",
    "truth/amplitude",
    "truth/order",
    "truth/kind",
]
WAVEFORM_KEYS = ["kind", "f_start_hz", "f_end_hz", "duration_s", "taper", "amplitude"]


def scalars():
    return st.one_of(
        st.none(),
        st.booleans(),
        st.integers(min_value=-(2**63), max_value=2**63 - 1),
        st.sampled_from([0, -1, 1, 7, 1023, 1024, 2**31, 10**15]),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from([0.0, -0.0, 1e-320, 1e308, -1e308, 1e12, 450e3, 343.0, 1e-3]),
        st.text(max_size=8),
    )


def json_values():
    return st.recursive(
        scalars(),
        lambda inner: (
            st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=3)
        ),
        max_leaves=6,
    )


def arrays():
    """Arrays of assorted kinds and shapes, near and far from the valid ones."""
    shapes = st.sampled_from(
        [
            (),
            (0,),
            (3,),
            (4,),
            (5,),
            (4, 3),
            (3, 3),
            (4, 2),
            (4, 1024),
            (1, 4, 1024),
            (4, 1023),
            (2, 2, 3),
            (0, 3),
        ]
    )
    kinds = st.sampled_from(["f8", "f4", "i8", "i2", "u1", "bool", "c16", "S4"])

    @st.composite
    def build(draw):
        shape, kind = draw(shapes), draw(kinds)
        n = int(np.prod(shape)) if shape else 1
        fill = draw(
            st.sampled_from(["zeros", "ones", "random", "huge", "nan", "negative", "index"])
        )
        rng = np.random.default_rng(draw(st.integers(0, 2**16)))
        base = {
            "zeros": np.zeros(n),
            "ones": np.ones(n),
            "random": rng.standard_normal(n),
            "huge": np.full(n, 1e300),
            "nan": np.where(np.arange(n) % 2, np.nan, 1.0),
            "negative": -np.arange(1, n + 1, dtype=float),
            "index": np.arange(n, dtype=float),
        }[fill].reshape(shape)
        if kind == "S4":
            return np.asarray(base).astype("S4")
        with np.errstate(all="ignore"):
            return np.asarray(base).astype(kind)

    return build()


def write(path, rec: P.Recording) -> None:
    P.save_recording(path, rec)


def mutate_file(path, data) -> str:
    """One field of the file at `path` deleted or replaced; returns what was done."""
    where = data.draw(st.sampled_from(["attr", "root", "dataset", "pitch", "metadata", "waveform"]))
    with h5py.File(path, "r+") as f:
        g = f[GROUP]
        if where in ("attr", "root"):
            owner = g if where == "attr" else f
            name = data.draw(st.sampled_from(ATTRS if where == "attr" else ROOT_ATTRS))
            value = data.draw(st.one_of(st.just(...), scalars(), arrays()))
            del owner.attrs[name]
            if value is not ...:
                _set_attr(owner, name, value, data)
            return f"{where} {name} = {value!r}"[:200]
        if where == "dataset":
            name = data.draw(st.sampled_from(DATASETS))
            value = data.draw(st.one_of(st.just(...), arrays()))
            del g[name]
            if value is not ...:
                g.create_dataset(name, data=value)
            return f"dataset {name} = {value!r}"[:200]
        if where == "pitch":
            value = data.draw(st.one_of(st.just(...), scalars(), arrays()))
            del g["array/grid_index"].attrs["pitch_m"]
            if value is not ...:
                _set_attr(g["array/grid_index"], "pitch_m", value, data)
            return f"pitch_m = {value!r}"
        text = (
            json.loads(g.attrs["waveform"])
            if where == "waveform"
            else json.loads(g["metadata"][()])
        )
        doc = _mutate_json(text, data)
        if where == "waveform":
            g.attrs["waveform"] = json.dumps(doc)
        else:
            del g["metadata"]
            g.create_dataset("metadata", data=json.dumps(doc))
        return f"{where} -> {json.dumps(doc)[:200]}"


def _set_attr(owner, name, value, data) -> None:
    try:
        owner.attrs[name] = value
    except (TypeError, ValueError, OSError):
        hypothesis.reject()  # a value HDF5 cannot store as an attribute


def _mutate_json(doc, data):
    """Delete or replace one key anywhere in a JSON document (or the whole of it)."""
    paths = []

    def walk(node, path):
        if isinstance(node, dict):
            for k, v in node.items():
                paths.append((*path, k))
                walk(v, (*path, k))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                paths.append((*path, i))
                walk(v, (*path, i))

    walk(doc, ())
    if not paths or data.draw(st.integers(0, 20)) == 0:
        return data.draw(json_values())
    path = data.draw(st.sampled_from(paths))
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    if isinstance(parent, dict) and data.draw(st.booleans()):
        del parent[path[-1]]
    else:
        parent[path[-1]] = data.draw(json_values())
    return doc


def accepted_everywhere(rec: P.Recording, tmp_path) -> None:
    """What the loader accepts, the rest of the program accepts too."""
    from acousim.dataset.info import describe
    from acousim.imaging.run import ImagingOptions, image_recordings

    again = P.save_recording(tmp_path / "again.h5", rec)  # never refused by the writer
    back = P.load_recording(again)  # nor by the reader
    assert back.samples.tobytes() == np.asarray(rec.samples, np.float32).tobytes()
    assert back.metadata == rec.metadata
    describe(again)
    try:
        image_recordings([rec], ImagingOptions(methods=("das",), step_deg=15.0))
    except InputError:
        pass  # refused with a sentence (e.g. a grid a 2x2 array cannot fill)


@FUZZ
@given(data=st.data())
def test_fuzzed_recording_files(tmp_path, data):
    path = tmp_path / "r.h5"
    write(path, base_recording())
    what = mutate_file(path, data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a numerical warning before the error fails
        try:
            rec = P.load_recording(path)
        except P.RecordingFileError as exc:
            assert str(path) in str(exc), what
            _tally("refused")
            return
        accepted_everywhere(rec, tmp_path)
        _tally("accepted")


def _tally(outcome: str) -> None:
    """With ACOUSIM_FUZZ_TALLY=file, append each outcome to it (how deep the search went)."""
    if os.environ.get("ACOUSIM_FUZZ_TALLY"):
        with open(os.environ["ACOUSIM_FUZZ_TALLY"], "a") as f:
            f.write(outcome + "\n")


def test_the_unmodified_file_is_accepted_everywhere(tmp_path):
    path = tmp_path / "r.h5"
    write(path, base_recording())
    accepted_everywhere(P.load_recording(path), tmp_path)
