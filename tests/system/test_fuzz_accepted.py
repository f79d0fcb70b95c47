"""Accepted means usable: fuzzed scene files and dataset specs that load are run, and
what they produce is read back. A scene that loads simulates (or is refused with an
InputError) and its recording file loads; a spec that loads makes its samples (or is
refused with an InputError). No traceback, no warning, nothing accepted that a later
step refuses as unreadable. (tests/system/test_fuzz_inputs.py checks the loading itself
against the documented ranges; tests/processing/formats/test_fuzz_native.py the recording reader.)
"""

from __future__ import annotations

import math
import os
import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import processing as P  # noqa: E402
from processing.base.errors import InputError  # noqa: E402
from tests import REPO  # noqa: E402

SCENES = REPO / "scenes"
FUZZ = settings(  # ACOUSIM_FUZZ_EXAMPLES=400 for a deeper search than the suite's
    max_examples=int(os.environ.get("ACOUSIM_FUZZ_EXAMPLES", "25")),
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def value(x) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, float):
        return (
            "inf" if x == math.inf else "-inf" if x == -math.inf else "nan" if x != x else repr(x)
        )
    if isinstance(x, list):
        return "[" + ", ".join(value(v) for v in x) + "]"
    return repr(x) if not isinstance(x, str) else '"' + x + '"'


numbers = st.one_of(
    st.floats(-10, 10),
    st.sampled_from([0.0, -0.0, 1e-9, 1e6, -1e6, 1e7, 1e300, 4.5e5, 2.0]),
    st.integers(-3, 3),
)
vectors = st.one_of(
    st.lists(numbers, min_size=3, max_size=3),
    st.lists(numbers, min_size=0, max_size=4),
)

POINT_FIELDS = {
    "position_m": vectors,
    "strength": numbers,
    "velocity_m_s": vectors,
}
SENSOR_FIELDS = {
    "sample_rate_hz": st.sampled_from([1e3, 1e5, 2e5, 4.5e5, 1e6, 1e8, 1e9, 0.0]),
    "direct_path": st.booleans(),
    "mic_radius_m": st.sampled_from([0.0, 1e-3, 0.05, 0.5]),
}
SIMULATION_FIELDS = {
    "max_range_m": st.sampled_from([0.05, 0.3, 1.0, 2.0, 100.0, 1e3]),
    "snr_db": st.sampled_from([-60.0, 0.0, 20.0, math.inf]),
    "bounces": st.integers(-1, 7),
}


@st.composite
def points_scene(draw) -> str:
    """The 8 x 8 URA and two point reflectors, one field changed per table."""
    point = {"position_m": [1.0, 0.1, 0.0], "strength": 1.0}
    other = {"position_m": [0.6, -0.2, 0.1], "strength": 0.5}
    sensor = {"array": "paper_8x8", "call": "paper", "sample_rate_hz": 5e5}
    simulation = {"max_range_m": 1.5, "absorption": False}
    pose = {"position_m": [0.0, 0.0, 0.0]}
    for table, fields in (
        (point, POINT_FIELDS),
        (sensor, SENSOR_FIELDS),
        (simulation, SIMULATION_FIELDS),
        (pose, {"position_m": vectors, "yaw_deg": numbers}),
    ):
        if draw(st.booleans()):
            key = draw(st.sampled_from(sorted(fields)))
            table[key] = draw(fields[key])
    lines = ['[scene]\nname = "fuzz"', "[sensor]"]
    lines += [f"{k} = {value(v)}" for k, v in sensor.items()]
    lines += ["[sensor.pose]"] + [f"{k} = {value(v)}" for k, v in pose.items()]
    lines += ["[simulation]"] + [f"{k} = {value(v)}" for k, v in simulation.items()]
    for p in (point, other):
        lines += ["[[points]]"] + [f"{k} = {value(v)}" for k, v in p.items()]
    return "\n".join(lines) + "\n"


@FUZZ
@given(text=points_scene())
def test_an_accepted_scene_simulates_into_a_readable_file(tmp_path, text):
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    path = tmp_path / "s.toml"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            scene = load_scene(path)
            recs = Simulator(scene).run()
            out = P.save_recordings(tmp_path / "r.h5", recs)
        except InputError:
            _tally("scene refused")
            return  # refused, with a sentence
        _tally("scene accepted")
        back = P.load_recordings(out)  # what was written is readable
    assert [r.samples.shape for r in back] == [r.samples.shape for r in recs]


@FUZZ
@given(
    coords=st.lists(
        st.lists(
            st.one_of(st.floats(-20, 20), st.sampled_from([0.0, 5.0, math.nan, 1e300])),
            min_size=2,
            max_size=2,
        ),
        min_size=1,
        max_size=6,
    )
)
def test_an_accepted_array_layout_is_readable_in_a_recording(tmp_path, coords):
    """The coordinates files of custom arrays (mm): a layout that loads writes a
    recording file that loads (two microphones at one place used to be accepted here
    and refused by the reader)."""
    from acousim.scene import load_scene

    (tmp_path / "mics.csv").write_text("\n".join(f"{y!r} {z!r}" for y, z in coords) + "\n")
    scene_text = (SCENES / "points.toml").read_text()
    (tmp_path / "s.toml").write_text(
        scene_text.replace('array = "paper_8x8"', 'coordinates = "mics.csv"')
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            array = load_scene(tmp_path / "s.toml").sensor.array
        except InputError:
            return
        x = np.zeros((array.n_mics, 600))
        rec = P.Recording(x, 5e5, array, P.paper_chirp())
        P.load_recording(P.save_recording(tmp_path / "r.h5", rec))


SPEC = """[dataset]
samples = 3
shard_size = 1
seed = {seed}
[[scenes]]
file = "{scenes}/{scene}"
poses = "random"
clearance_m = {clearance}
region = {{ x = {x}, y = [-0.3, 0.3], z = [0.2, 0.4], yaw_deg = {yaw} }}
[randomize]
snr_db = {{ dist = "uniform", range = {snr} }}
[store]
images = ["das"]
step_deg = 15.0
depth_map = false
"""


@FUZZ
@given(
    seed=st.integers(0, 2**63 - 1),
    scene=st.sampled_from(["points.toml", "corridor.toml"]),
    clearance=st.sampled_from([0.0, 0.1, 0.5, 3.0, 10.0]),
    x=st.sampled_from([[0.5, 1.5], [1.0, 10.0], [100.0, 101.0], [2.0, 2.0], [-1e4, 1e4]]),
    yaw=st.sampled_from([[0.0, 0.0], [-360.0, 360.0], [10.0, -10.0]]),
    snr=st.sampled_from([[10.0, 30.0], [-60.0, -60.0], [30.0, 10.0]]),
)
def test_an_accepted_dataset_spec_makes_its_samples(tmp_path, seed, scene, clearance, x, yaw, snr):
    from acousim.dataset.generation import make_sample, sample_parameters
    from acousim.dataset.spec import load_spec

    text = SPEC.format(
        seed=seed, scenes=SCENES, scene=scene, clearance=clearance, x=x, yaw=yaw, snr=snr
    )
    (tmp_path / "spec.toml").write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            spec = load_spec(tmp_path / "spec.toml")
            for i in range(spec.samples):
                sample_parameters(spec, i)
            if scene == "points.toml":  # a simulation, only where it is cheap
                make_sample(spec, 0)
        except InputError:
            _tally("spec refused")
            return
        _tally("spec accepted")


def _tally(outcome: str) -> None:
    """With ACOUSIM_FUZZ_TALLY=file, append each outcome to it (how deep the search went)."""
    if os.environ.get("ACOUSIM_FUZZ_TALLY"):
        with open(os.environ["ACOUSIM_FUZZ_TALLY"], "a") as f:
            f.write(outcome + "\n")
