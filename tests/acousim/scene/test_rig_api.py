"""A rig and its sonars built in Python take what the scene file takes, with the
same defaults and the same answers to mistakes: the emitter's keys, a mount's
angles, the booleans, the firing schedule (round robin by default, a rate or
explicit times, within the body's trajectory), a sonar's name and sample rate.
References: the point reflector's two-way path written here, and the schedule's
times worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

import acousim
from acousim.rig import RigSimulator
from acousim.scene import SceneError, parse_scene
from acousim.scene.rig import Firing, Mount, Rig, RigSonar
from processing.base.errors import InputError

POINT = {"points": [{"position_m": [1.0, 0.0, 0.0]}]}
EMITTER = (0.0, 0.0, -0.012)  # 12 mm below the array centre


def test_python_sensor_takes_the_files_emitter_keys_and_places_the_emitter_there():
    s = acousim.Sensor(emitter_m=EMITTER, emitter_radius_m=0.004, direct_path=False)
    np.testing.assert_array_equal(s.array.emitter_m, EMITTER)
    f = parse_scene({"sensor": {"emitter_m": list(EMITTER), "emitter_radius_m": 0.004}, **POINT})
    np.testing.assert_array_equal(f.sensor.array.emitter_m, s.array.emitter_m)
    assert f.sensor.emitter_radius_m == s.emitter_radius_m == 0.004
    # the defaults: the presets' emitter at the array centre, omnidirectional
    assert acousim.Sensor().emitter_m is None and acousim.Sensor().emitter_radius_m == 0.0
    np.testing.assert_array_equal(acousim.Sensor().array.emitter_m, [0.0, 0.0, 0.0])
    # the echo of a point 1 m ahead leaves from there: emitter -> point -> array centre
    scene = acousim.Scene(
        points=[acousim.PointItem((1.0, 0.0, 0.0))],
        sensor=s,
        simulation=acousim.Simulation(max_range_m=1.5, absorption=False),
    )
    (rec,) = acousim.Simulator(scene).run()
    c = scene.environment.speed_of_sound_m_s
    path = np.linalg.norm(np.subtract((1.0, 0.0, 0.0), EMITTER)) + 1.0
    ((delay,),) = [rec.truth.delay_s[rec.truth.kind == "point"]]
    assert delay == pytest.approx(path / c, abs=1e-12)
    assert abs(path / c - 2.0 / c) > 1e-7  # the offset emitter's 0.2 us is resolved


@pytest.mark.parametrize(
    "make, pattern",
    [
        (
            lambda: acousim.Sensor(emitter_m=[0, 0]),
            r"Sensor.emitter_m = \[0, 0\]: must be a list of 3",
        ),
        (
            lambda: acousim.Sensor(emitter_m=[0, 0, 11]),
            r"Sensor.emitter_m = \[0, 0, 11\]: .*\[-10, 10\]",
        ),
        (
            lambda: Mount.degrees((0, 0, 0), (0, 45)),
            r"Mount.degrees.rotation_deg = \(0, 45\): must be a list of 3",
        ),
        (
            lambda: Mount.degrees((0, 0, 0), (0, 0, 400)),
            r"rotation_deg = \(0, 0, 400\): .*\[-360, 360\]",
        ),
        (
            lambda: Firing(rate_hz=10, times_s=(0.0,)),
            r"Firing.times_s = \(0.0,\): times_s and rate_hz both given",
        ),
        (lambda: Firing(count=3, times_s=(0.0,)), r"times_s and count both given"),
        (lambda: Firing(rate_hz=0.0), r"Firing.rate_hz = 0.0: outside"),
    ],
)
def test_python_mistakes_get_the_files_answer(make, pattern):
    with pytest.raises(InputError, match=pattern):
        make()


def sonar(name, y=0.0, firing=None, **sensor):
    s = acousim.Sensor(direct_path=False, **sensor)
    return RigSonar(name, s, Mount.degrees((0.0, y, 0.0)), firing)


OUTSIDE = "fires at 5 s, outside the body's trajectory (0 to 0.3 s)"
DRIVE = tuple(acousim.Pose.degrees((0.1 * k, 0.0, 0.0), time_s=0.1 * k) for k in range(4))


@pytest.mark.parametrize("key", ["crosstalk", "earlier_calls"])
def test_a_rigs_booleans_are_booleans(key):
    with pytest.raises(InputError, match=rf"Rig.{key} = 'no': must be true or false"):
        Rig((sonar("a"),), **{key: "no"})
    assert Rig((sonar("a"),), **{key: np.bool_(False)}).__getattribute__(key) is False


def test_python_and_file_default_to_the_same_round_robin():
    rig = Rig((sonar("a", 0.2), sonar("b", -0.2)), poses=DRIVE)
    # two sonars at the drive's 10 Hz, round robin: b 1 / (2 x 10 Hz) after a
    times = [(m.sonar, round(m.time_s, 12)) for m in rig.measurements()]
    assert times == [(0, 0.0), (1, 0.05), (0, 0.1), (1, 0.15), (0, 0.2), (1, 0.25), (0, 0.3)]
    table = {
        "body": {"trajectory": {"poses": [[0.1 * k, 0, 0, 0] for k in range(4)], "rate_hz": 10}},
        "sensors": [{"name": "a", "direct_path": False}, {"name": "b", "direct_path": False}],
        **POINT,
    }
    from_file = parse_scene(table).rig
    assert [s.firing for s in from_file.sonars] == [s.firing for s in rig.sonars]
    together = Rig((sonar("a"), sonar("b", 0.1)), poses=DRIVE, firing="simultaneous", rate_hz=5)
    assert [(m.sonar, m.time_s) for m in together.measurements()] == [
        (0, 0.0), (1, 0.0), (0, 0.2), (1, 0.2)
    ]  # fmt: skip
    # a sonar's own firing is kept
    own = Rig((sonar("a", firing=Firing(times_s=(0.05,))), sonar("b", 0.1)), poses=DRIVE)
    assert own.sonars[0].firing.times_s == (0.05,) and own.sonars[1].firing.offset_s == 0.05


@pytest.mark.parametrize(
    "firing, key, words",
    [
        (Firing(times_s=(0.0, 5.0)), "times_s", OUTSIDE),
        (Firing(rate_hz=10, count=5), "count", "fires at 0.4 s, outside the body's trajectory"),
        (
            Firing(rate_hz=10, offset_s=0.5),
            "offset_s",
            "never fires, outside the body's trajectory",
        ),
    ],
)
def test_firings_outside_the_bodys_trajectory_are_refused(firing, key, words):
    with pytest.raises(InputError) as err:
        Rig((sonar("a", firing=firing),), poses=DRIVE)
    assert err.value.key == f"Rig.sonars[0].firing.{key}" and words in err.value.reason
    # a body of one pose has no trajectory to leave: any time is its pose
    assert Rig((sonar("a", firing=firing),)).measurements()


def test_run_of_an_unknown_sonar_lists_the_rigs_sonars():
    rig = Rig((sonar("left", 0.2), sonar("right", -0.2)), crosstalk=False)
    scene = acousim.Scene(
        points=[acousim.PointItem((1.0, 0.0, 0.0))],
        simulation=acousim.Simulation(max_range_m=1.2),
        rig=rig,
    )
    run = RigSimulator(scene).run()
    assert [r.metadata["sensor"] for r in run.of("right")] == ["right"]
    with pytest.raises(InputError, match=r"RigRun.of.name = 'rigth': .*\(left, right\)"):
        run.of("rigth")


RIG = {
    "body": {"trajectory": {"poses": [[0.1 * k, 0, 0, 0] for k in range(4)], "rate_hz": 10}},
    **POINT,
}


@pytest.mark.parametrize(
    "sensors, key, words",
    [
        (
            [{"firing": {"rate_hz": 10, "times_s": [0.0]}}],
            "sensors[0].firing.times_s",
            "times_s and rate_hz both given",
        ),
        ([{"firing": {"times_s": [0.0, 5.0]}}], "sensors[0].firing.times_s", OUTSIDE),
        (
            [{"rate_hz": 10}],
            "sensors[0].rate_hz",
            "did you mean 'firing.rate_hz'? (a sonar's own: firing = { rate_hz = ... }",
        ),
        ([{"offset_s": 0.01}], "sensors[0].offset_s", "did you mean 'firing.offset_s'?"),
        ([{"name": "a"}, {"name": "front-left"}], "sensors[1].name", "must start with a letter"),
        (
            [
                {"name": "left", "sample_rate_hz": 150000},
                {"name": "side", "call": "default_20_80", "sample_rate_hz": 500000},
            ],
            "sensors[0].sample_rate_hz",
            "call of sonar 'side' (80000 Hz), which sonar 'left' hears (crosstalk)",
        ),
    ],
)
def test_a_rig_files_mistakes_name_file_key_and_value(tmp_path, sensors, key, words):
    with pytest.raises(SceneError) as err:
        parse_scene({**RIG, "sensors": sensors}, source=str(tmp_path / "rig.toml"))
    assert err.value.key == key and words in err.value.reason, str(err.value)
    assert str(err.value).startswith(f"{tmp_path / 'rig.toml'}: {key}")


def test_a_sample_rate_too_low_for_a_neighbours_call_is_fine_without_crosstalk():
    sensors = [
        {"name": "left", "sample_rate_hz": 150000},
        {"name": "side", "call": "default_20_80", "sample_rate_hz": 500000},
    ]
    rig = parse_scene({**RIG, "rig": {"crosstalk": False}, "sensors": sensors}).rig
    assert [s.sensor.sample_rate_hz for s in rig.sonars] == [150000, 500000]
