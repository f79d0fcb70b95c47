"""Quality presets: ``simulation.quality`` in a scene file, ``Simulation(quality=...)``
and ``--quality`` on the command line (acousim.scene.defaults.QUALITY_PRESETS)."""

import dataclasses
import shutil

import pytest

from acousim.cli import main
from acousim.scene import Diffraction, Simulation, parse_scene
from acousim.scene.defaults import QUALITIES, QUALITY_PRESETS, given
from processing.base.errors import InputError
from processing.base.settings import settings_of
from tests import REPO

SCENES = REPO / "scenes"
DECLARED = {name: decl.default for name, decl in settings_of(Simulation).items()}
DECLARED_STEP_M = settings_of(Diffraction)["step_m"].default
POINT = {"points": [{"position_m": [1.0, 0.0, 0.0]}]}


def _has(sim, name, value) -> bool:
    """Whether setting `name` of `sim` holds a preset's `value` (a table: its keys)."""
    if isinstance(value, dict):
        return all(getattr(getattr(sim, name), k) == v for k, v in value.items())
    return getattr(sim, name) == value


def _step(sim) -> float:
    return sim.diffraction.step_m


def test_the_qualities_are_fast_default_and_reference_each_with_a_table():
    assert QUALITIES == ("fast", "default", "reference")
    assert set(QUALITY_PRESETS) == set(QUALITIES)
    assert QUALITY_PRESETS["default"] == {}  # the default preset is the declared defaults


@pytest.mark.parametrize("quality", ["fast", "reference"])
def test_a_preset_sets_its_declared_values(quality):
    table = QUALITY_PRESETS[quality]
    assert table, "a preset that changes nothing"
    sim = Simulation(quality=quality)
    assert sim.quality == quality
    for name, value in table.items():
        assert _has(sim, name, value), name
    # every other setting keeps its declaration's default
    for name, default in DECLARED.items():
        if name not in table and name not in ("quality", "max_memory_gb"):
            assert getattr(sim, name) == default, name
    if "diffraction" not in table:
        assert sim.diffraction == Diffraction()


def test_fast_is_cheaper_and_reference_finer_than_the_default():
    """The direction of each knob, read from the declarations' meaning: a smaller
    element step, a lower floor and more orders are finer."""
    fast, ref, default = (Simulation(quality=q) for q in ("fast", "reference", "default"))
    assert _step(fast) >= _step(default) >= _step(ref)
    assert fast.energy_floor_db >= default.energy_floor_db >= ref.energy_floor_db
    assert fast.diffraction.order <= default.diffraction.order <= ref.diffraction.order


def test_an_explicit_setting_overrides_the_preset_even_at_its_default_value():
    step = QUALITY_PRESETS["reference"]["diffraction"]["step_m"]
    sim = Simulation(quality="reference", diffraction=Diffraction(step_m=5e-3))
    assert _step(sim) == 5e-3
    assert sim.energy_floor_db == QUALITY_PRESETS["reference"]["energy_floor_db"]
    # the declared default given explicitly is kept too, not replaced by the preset
    floor = DECLARED["energy_floor_db"]
    assert Simulation(quality="fast", energy_floor_db=floor).energy_floor_db == floor
    assert _step(Simulation(quality="reference")) == step


def test_in_a_scene_file_the_table_s_own_keys_override_the_preset():
    floor = DECLARED["energy_floor_db"]
    sc = parse_scene({**POINT, "simulation": {"quality": "fast", "energy_floor_db": floor}})
    assert sc.simulation.quality == "fast"
    assert sc.simulation.energy_floor_db == floor  # given: kept
    for name, value in QUALITY_PRESETS["fast"].items():
        if name != "energy_floor_db":
            assert _has(sc.simulation, name, value), name


def test_with_quality_keeps_the_given_settings_and_takes_the_new_preset():
    sim = Simulation(quality="fast", energy_floor_db=-70.0, seed=4)
    ref = sim.with_quality("reference")
    assert (ref.quality, ref.energy_floor_db, ref.seed) == ("reference", -70.0, 4)
    assert _step(ref) == QUALITY_PRESETS["reference"]["diffraction"]["step_m"]
    back = ref.with_quality("default")
    assert _step(back) == DECLARED_STEP_M
    assert back.energy_floor_db == -70.0


def test_a_replace_keeps_the_preset_and_what_it_changes_counts_as_given():
    fast = Simulation(quality="fast")
    again = dataclasses.replace(fast, seed=5)
    assert again.seed == 5 and given(again) == {"quality", "seed"}
    for name, value in QUALITY_PRESETS["fast"].items():
        assert _has(again, name, value), name
    ref = dataclasses.replace(again, quality="reference")  # the new preset applies
    for name, value in QUALITY_PRESETS["reference"].items():
        assert _has(ref, name, value), name
    assert ref.seed == 5
    # the declared default set by a replace is a change from fast's -60 dB: kept
    floor = DECLARED["energy_floor_db"]
    kept = dataclasses.replace(fast, energy_floor_db=floor).with_quality("reference")
    assert kept.energy_floor_db == floor


def test_an_unknown_quality_names_the_key_the_value_and_the_allowed_ones():
    with pytest.raises(InputError) as info:
        Simulation(quality="best")
    msg = str(info.value)
    assert "Simulation.quality" in msg and "'best'" in msg
    assert all(q in msg for q in QUALITIES)
    with pytest.raises(InputError) as info:
        parse_scene({**POINT, "simulation": {"quality": "fats"}}, source="s.toml")
    msg = str(info.value)
    assert "s.toml" in msg and "simulation.quality" in msg and "'fats'" in msg
    assert "did you mean 'fast'" in msg


def test_the_command_line_flag_reaches_the_simulation(tmp_path, monkeypatch):
    """`acousim simulate --quality reference` on a scene file that sets
    ``absorption = false`` and ``max_range_m``: the simulation runs with the
    reference preset, the file's own settings kept."""
    import acousim.simulator

    shutil.copy(SCENES / "points.toml", tmp_path / "points.toml")
    seen = []
    real_run = acousim.simulator.Simulator.run

    def spy(self, *args, **kwargs):
        seen.append(self.scene.simulation)
        return real_run(self, *args, **kwargs)

    monkeypatch.setattr(acousim.simulator.Simulator, "run", spy)
    args = ["simulate", str(tmp_path / "points.toml"), "--out", str(tmp_path / "x.h5")]
    assert main([*args, "--quality", "reference", "--seed", "3"]) == 0
    (sim,) = seen
    assert sim.quality == "reference" and sim.seed == 3
    for name, value in QUALITY_PRESETS["reference"].items():
        assert _has(sim, name, value), name
    assert sim.absorption is False and sim.max_range_m == 1.5  # the file's, kept
    assert main(args) == 0
    assert seen[-1].quality == "default"


def test_an_unknown_quality_on_the_command_line_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["simulate", "points", "--quality", "best"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--quality" in err and "'best'" in err and "fast, default, reference" in err


def test_a_recording_says_which_preset_and_settings_made_it(tmp_path):
    """The metadata holds the quality and the [simulation] settings in effect: the fast
    preset's documented values (a 2 mm element step, Lagrange; docs/scene-format.md,
    "Quality presets"), the file's own energy floor over the preset's -70 dB, the
    rest at their declared defaults; read back from the file as written."""
    import processing as P
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    (tmp_path / "q.toml").write_text(
        '[sensor]\narray = "urtis_v1"\n[simulation]\nquality = "fast"\n'
        "energy_floor_db = -80.0\nmax_range_m = 2.0\nseed = 7\n"
        "[[points]]\nposition_m = [1.0, 0.0, 0.0]\n"
    )
    (rec,) = Simulator(load_scene(tmp_path / "q.toml")).run()
    P.save_recordings(tmp_path / "q.h5", [rec])
    meta = P.load_recording(tmp_path / "q.h5", 0).metadata
    assert meta["quality"] == "fast"
    sim = meta["simulation"]
    assert sim["fractional_delay"] == "lagrange" and sim["diffraction"]["step_m"] == 0.002
    assert sim["energy_floor_db"] == -80.0 and sim["max_range_m"] == 2.0 and sim["seed"] == 7
    assert sim["diffraction"]["enabled"] is True and sim["diffraction"]["order"] == 2
    assert sim["rays"] is None and sim["snr_db"] == float("inf") and sim["bounces"] == 3
    assert set(sim) == set(DECLARED) - {"quality", "max_memory_gb"} | {"diffraction"}
