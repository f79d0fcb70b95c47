"""Near misses get a suggestion, once: scene names, dataset specs, methods, array
presets, calls; a missing path named like a bundled file names the bundled one."""

import re

import pytest

import processing as P
from acousim.bundled import bundled_names, resolve
from processing.base.errors import InputError, did_you_mean


@pytest.mark.parametrize(
    "typed,choices,expected",
    [
        ("corridr", ["corridor", "wall", "points"], "corridor"),
        ("Corridor", ["corridor", "wall"], "corridor"),
        ("capon_fbss", ["capon-fbss", "capon-fss", "das"], "capon-fbss"),
        ("zzzz", ["corridor", "wall"], None),
    ],
)
def test_did_you_mean(typed, choices, expected):
    assert did_you_mean(typed, choices) == expected


@pytest.mark.parametrize(
    "call,value,suggested",
    [
        (P.check_method, "dass", "das"),
        (P.check_method, "music_fbss", "music-fbss"),
        (P.preset, "urtis", "urtis_v1"),
        (P.rtis_call, "default_25-50", "default_25_50"),
    ],
)
def test_a_near_miss_is_named_once_with_a_suggestion(call, value, suggested):
    with pytest.raises(InputError) as err:
        call(value)
    text = str(err.value)
    assert f"did you mean {suggested!r}?" in text
    assert text.count(repr(value)) == 1  # the bad value once
    if call is P.check_method:  # no list of all 21 methods: only the suggestion
        assert [m for m in P.METHODS if f" {m}," in text or f"{m!r}" in text] == [suggested]


def test_an_unknown_method_far_from_all_does_not_list_all():
    with pytest.raises(InputError) as err:
        P.check_method("beamforming")
    text = str(err.value)
    assert f"none of the {len(P.METHODS)} is close" in text
    assert sum(m in text for m in P.METHODS if m not in ("das", "capon", "music")) < 5


def test_bundled_names_resolve_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # an empty folder: no scenes/ here
    assert {"corridor", "wall", "ertis_sample"} <= set(bundled_names("scenes"))
    assert resolve("scenes", "wall").name == "wall.toml"
    assert resolve("datasets", "corridor_small").name == "corridor_small.toml"


@pytest.mark.parametrize(
    "kind,typed,message",
    [
        (
            "scenes",
            "corridr",
            "no such file, nor a bundled scene of that name; did you mean 'corridor'?",
        ),
        ("scenes", "scenes/wall.toml", "a bundled scene has that file name: give 'wall'"),
        (
            "datasets",
            "datasets/corridor_small.toml",
            "a bundled dataset spec has that file name: give 'corridor_small'",
        ),
        ("datasets", "corridor_smal", "did you mean 'corridor_small'?"),
    ],
)
def test_a_missing_scene_or_spec_says_which_bundled_name_to_use(
    tmp_path, monkeypatch, kind, typed, message
):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError) as err:
        resolve(kind, typed)
    assert message in str(err.value)
    assert str(err.value).startswith(f"{typed}: ")  # the value named once, first


@pytest.mark.parametrize(
    "argv,bad,expected",
    [
        (
            ["simulate", "corridr"],
            "corridr",
            "corridr: no such file, nor a bundled scene of that name; did you mean 'corridor'?",
        ),
        (
            ["simulate", "scenes/wall.toml"],
            "scenes/wall.toml",
            "a bundled scene has that file name: give 'wall'",
        ),
        (
            ["dataset", "corridor_smal", "--out", "d"],
            "corridor_smal",
            "did you mean 'corridor_small'?",
        ),
        (
            ["image", "x.h5", "--method", "das,dass"],
            "dass",
            "--method = 'dass': unknown method; did you mean 'das'?",
        ),
        (
            ["record", "--array", "urtis", "--count", "1", "--out", "r.h5"],
            "urtis",
            "'urtis': unknown array preset; did you mean 'urtis_v1'?",
        ),
        (
            ["record", "--call", "default_2550", "--count", "1", "--out", "r.h5"],
            "default_2550",
            "did you mean 'default_25_50'?",
        ),
    ],
)
def test_the_command_line_suggests_the_name(tmp_path, monkeypatch, capsys, argv, bad, expected):
    from acousim.cli import main

    monkeypatch.chdir(tmp_path)  # an empty folder
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert expected in err
    assert len(re.findall(re.escape(bad) + r"(?!\w)", err)) == 1, err  # named once
