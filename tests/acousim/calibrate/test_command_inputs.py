"""``acousim calibrate`` on bad input: one line naming what is wrong, and nothing
created (no --out folder) before the inputs are read; the scene file never written
over by its own fit."""

from __future__ import annotations

import dataclasses
import shutil

import pytest

import processing as P
from acousim.bundled import find_scene
from acousim.cli import main
from acousim.scene.load import load_scene
from acousim.simulator import Simulator


@pytest.fixture(scope="module")
def two_poses_file(tmp_path_factory):
    """Two recordings of a trajectory of two poses (pose_index 0 and 1), the wall
    moved between them: what a recording session writes."""
    tmp = tmp_path_factory.mktemp("rec")
    wall = load_scene(find_scene("wall"))
    recs = []
    for k in (0, 1):
        (rec,) = Simulator(wall).run()
        recs.append(dataclasses.replace(rec, metadata={**rec.metadata, "pose_index": k}))
    P.save_recordings(tmp / "two.h5", recs)
    return tmp / "two.h5"


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


@pytest.mark.parametrize("content", [None, b"not hdf5 at all", b"\x89HDF\r\n\x1a\n" + bytes(64)])
def test_a_missing_or_broken_recording_creates_no_folder(tmp_path, capsys, content):
    rec = tmp_path / "rec.h5"
    if content is not None:
        rec.write_bytes(content)
    out = tmp_path / "newdir" / "sub" / "fitted.toml"
    assert main(["calibrate", str(rec), "--scene", "wall", "--out", str(out)]) == 2
    assert str(rec) in _err(capsys)
    assert not (tmp_path / "newdir").exists()


def test_out_naming_the_scene_file_is_refused(tmp_path, capsys, two_poses_file):
    scene = tmp_path / "g2.toml"
    shutil.copy(find_scene("wall"), scene)
    before = scene.read_bytes()
    args = ["calibrate", str(two_poses_file), "--scene", str(scene)]
    assert main([*args, "--out", str(tmp_path / "." / "g2.toml"), "--poses", "0,0"]) == 2
    err = _err(capsys)
    assert "--out" in err and "g2.toml" in err and "is the scene file --scene" in err
    assert scene.read_bytes() == before


def test_a_pose_the_scene_lacks_is_said_to_be_the_recordings_pose_index(
    tmp_path, capsys, two_poses_file
):
    """The bundled wall has one pose; the file's recording 1 says pose_index 1."""
    out = tmp_path / "f.toml"
    assert main(["calibrate", str(two_poses_file), "--scene", "wall", "--out", str(out)]) == 2
    err = _err(capsys)
    assert "recording 1 is at pose 1, its pose_index (in the file)" in err
    assert "the scene has 1 pose(s)" in err and "--poses" in err
    assert not out.exists()
