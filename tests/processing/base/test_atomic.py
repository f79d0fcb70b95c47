"""The one atomic writer and the one input-error type."""

import os

import pytest

from processing.base.atomic import TEMP_PREFIX, atomic_path, write_text
from processing.base.errors import InputError


def test_atomic_write_renames_on_success(tmp_path):
    target = tmp_path / "out.txt"
    write_text(target, "hello")
    assert target.read_text() == "hello"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_atomic_write_removes_temporary_on_interrupt(tmp_path):
    target = tmp_path / "out.png"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as tmp:
        assert tmp.suffix == ".png" and tmp.name.startswith(TEMP_PREFIX)
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_atomic_write_never_follows_a_planted_symlink(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    for name in (".out.part.txt", ".out.txt.part", f".out.txt.{os.getpid()}.part"):
        (tmp_path / name).symlink_to(victim)
    write_text(tmp_path / "out.txt", "new")
    assert victim.read_text() == "precious"
    assert (tmp_path / "out.txt").read_text() == "new"


def test_input_error_names_file_key_and_value():
    err = InputError("must be positive", file="scene.toml", key="simulation.rays", value=-10)
    assert str(err) == "scene.toml: simulation.rays = -10: must be positive"
    assert isinstance(err, ValueError)
    assert (err.file, err.key, err.value) == ("scene.toml", "simulation.rays", -10)
    assert str(InputError("bad", key="--step")) == "--step: bad"


def test_atomic_write_gives_the_usual_file_mode(tmp_path):
    old = os.umask(0o022)
    try:
        write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644
