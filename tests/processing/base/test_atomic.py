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


def test_files_staged_by_a_forked_worker_are_renamed_with_the_group(tmp_path):
    """A file a forked child writes (atomic_path, inside the stage) is renamed into
    place only when the enclosing group commits, with the parent's own file; the
    stage is gone after the block."""
    import multiprocessing as mp

    from processing.base.atomic import atomic_path, committed_together, staged

    def child(folder):
        with atomic_path(folder / "theirs.txt") as tmp:
            tmp.write_text("theirs")

    with committed_together():
        with atomic_path(tmp_path / "mine.txt") as tmp:
            tmp.write_text("mine")
        with staged(tmp_path) as stage:
            worker = mp.get_context("fork").Process(target=child, args=(stage.folder,))
            worker.start()
            worker.join()
            assert worker.exitcode == 0
            assert (stage.folder / "theirs.txt").read_text() == "theirs"  # whole, staged
            stage.adopt(stage.folder / "theirs.txt", tmp_path / "theirs.txt")
        assert not (tmp_path / "theirs.txt").exists()  # not before the group commits
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.txt", "theirs.txt"]
    assert (tmp_path / "theirs.txt").read_text() == "theirs"


def test_a_stage_left_by_an_error_or_a_killed_worker_leaves_nothing(tmp_path):
    """An error after a file was adopted (the group removes it) and a worker killed
    in the middle of writing (the stage removes what it left): the folder holds only
    what was there before."""
    import multiprocessing as mp
    import signal

    from processing.base.atomic import atomic_path, committed_together, staged

    (tmp_path / "old.txt").write_text("old")

    def child(folder, ready):
        with atomic_path(folder / "half.txt") as tmp:
            tmp.write_text("half")
            ready.set()
            signal.pause()  # killed here, mid-file

    with pytest.raises(RuntimeError, match="later"):
        with committed_together():
            with staged(tmp_path) as stage:
                (stage.folder / "done.txt").write_text("done")
                stage.adopt(stage.folder / "done.txt", tmp_path / "done.txt")
                ready = mp.get_context("fork").Event()
                worker = mp.get_context("fork").Process(target=child, args=(stage.folder, ready))
                worker.start()
                assert ready.wait(60)
                os.kill(worker.pid, signal.SIGKILL)
                worker.join()
            raise RuntimeError("later")
    assert [p.name for p in tmp_path.iterdir()] == ["old.txt"]
