"""Every command's outputs: an existing output is replaced only when acousim wrote it
(a rerun); a file of the user's where a command would write is refused (exit 2, one
line naming the argument and the path) and kept byte for byte, and nothing is written."""

from __future__ import annotations

import json
import shutil

import h5py
import numpy as np
import pytest

import processing as P
from acousim.cli import main

FOREIGN = b"my own notes, not acousim's\n"


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    """A recording file of the bundled wall scene, written by `acousim simulate`."""
    path = tmp_path_factory.mktemp("wall") / "wall.h5"
    assert main(["simulate", "wall", "--out", str(path), "-q"]) == 0
    return path


def refused(capsys, args: list[str], option: str, path) -> str:
    """Run `args`: exit 2 and one line naming `option` and `path`; the line."""
    capsys.readouterr()
    assert main([*args, "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"{option} " in err and repr(str(path)) in err, err
    assert "is never overwritten" in err, err
    return err


def foreign_file(path) -> bytes:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(FOREIGN)
    return FOREIGN


def files(folder) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_simulate_refuses_a_foreign_file_and_replaces_its_own(tmp_path, capsys, wall):
    mine = tmp_path / "mine.txt"
    foreign_file(mine)
    refused(capsys, ["simulate", "wall", "--out", str(mine)], "--out", mine)
    assert mine.read_bytes() == FOREIGN and sorted(tmp_path.iterdir()) == [mine]
    # an HDF5 file that is not a recording file of ours: refused too
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = np.arange(3)
    before = other.read_bytes()
    err = refused(capsys, ["simulate", "wall", "--out", str(other)], "--out", other)
    assert "is not a recording file acousim wrote" in err
    assert other.read_bytes() == before
    # our own earlier output: replaced (by another scene's recording)
    out = tmp_path / "rec.h5"
    assert main(["simulate", "points", "--out", str(out), "-q"]) == 0
    assert len(P.load_recording(out).truth.position_sensor_m) == 3  # its three points
    assert main(["simulate", "wall", "--out", str(out), "-q"]) == 0
    np.testing.assert_array_equal(P.load_recording(out).samples, P.load_recording(wall).samples)


def test_record_refuses_a_foreign_file_and_replaces_its_own(tmp_path, capsys):
    base = ["record", "--emulate", "wall", "--count", "1", "--rate", "50"]
    mine = tmp_path / "mine.h5"
    foreign_file(mine)
    refused(capsys, [*base, "--out", str(mine)], "--out", mine)
    assert mine.read_bytes() == FOREIGN
    out = tmp_path / "rec.h5"
    assert main([*base, "--out", str(out), "-q"]) == 0
    first = out.stat().st_ino
    assert main([*base, "--out", str(out), "-q"]) == 0
    assert out.stat().st_ino != first  # a new file renamed into its place
    assert len(P.load_recordings(out)) == 1


def test_image_refuses_a_foreign_file_by_one_of_its_names_and_replaces_its_own(
    tmp_path, capsys, wall
):
    out = tmp_path / "img"
    base = ["image", str(wall), "--out", str(out), "--method", "das", "--no-3d"]
    for name in ("fan.png", "peaks.csv", "images.h5"):
        foreign_file(out / name)
        before = files(out)
        refused(capsys, base, "--out", out / name)
        assert files(out) == before  # nothing written, nothing replaced
        (out / name).unlink()
    (out / "notes.txt").write_bytes(FOREIGN)  # not one of our names: the user's, kept
    assert main([*base, "-q"]) == 0
    first = files(out)
    assert {"fan.png", "peaks.csv", "elaz_das.png", "notes.txt"} <= set(first)
    assert main([*base, "--dynamic-range-db", "20", "-q"]) == 0  # a rerun: replaced
    again = files(out)
    assert again["notes.txt"] == FOREIGN and again["fan.png"] != first["fan.png"]


def test_compare_refuses_a_foreign_report_and_replaces_its_own(tmp_path, capsys, wall):
    out = tmp_path / "cmp"
    base = ["compare", str(wall), "--sim", str(wall), "--out", str(out)]
    foreign_file(out / "comparison.json")
    refused(capsys, base, "--out", out / "comparison.json")
    assert files(out) == {"comparison.json": FOREIGN}
    (out / "comparison.json").unlink()
    assert main([*base, "-q"]) == 0
    first = files(out)
    assert set(first) == {"comparison.json", "comparison.png"}
    (out / "comparison.json").write_text(json.dumps({"alignment": 0, "channels": 0}))
    assert main([*base, "-q"]) == 0  # its own (by its keys): replaced
    assert files(out)["comparison.json"] == first["comparison.json"]


def test_calibrate_refuses_foreign_files_and_replaces_its_own(tmp_path, capsys, wall):
    scene = tmp_path / "other.toml"
    scene.write_text('[sensor]\narray = "urtis_v1"\n')  # a scene of the user's
    report = tmp_path / "notes.json"
    report.write_text(json.dumps({"my": "notes"}))
    base = ["calibrate", str(wall), "--scene", "wall"]
    keep = {p.name: p.read_bytes() for p in (scene, report)}
    refused(capsys, [*base, "--out", str(scene)], "--out", scene)
    fitted = tmp_path / "fitted.toml"
    refused(capsys, [*base, "--out", str(fitted), "--report", str(report)], "--report", report)
    assert {p.name: p.read_bytes() for p in (scene, report)} == keep
    assert not fitted.exists()
    ours = tmp_path / "report.json"
    args = [*base, "--out", str(fitted), "--report", str(ours), "-q"]
    assert main(args) == 0
    first = (fitted.read_text(), json.loads(ours.read_text()))
    assert main(args) == 0  # a rerun: both replaced, the same fit
    assert (fitted.read_text(), json.loads(ours.read_text())["parameters"]) == (
        first[0],
        first[1]["parameters"],
    )


def test_dataset_refuses_a_folder_with_a_foreign_manifest(tmp_path, capsys):
    out = tmp_path / "data"
    for name in ("manifest.json", "inputs.json"):
        foreign_file(out / name)
        refused(capsys, ["dataset", "corridor_small", "--out", str(out)], "--out", out / name)
        assert files(out) == {name: FOREIGN}
        (out / name).unlink()


def test_demo_refuses_a_foreign_file_by_one_of_its_names(tmp_path, capsys):
    out = tmp_path / "out"
    for name in ("corridor.h5", "drive.gif"):
        foreign_file(out / name)
        refused(capsys, ["demo", "--out", str(out)], "--out", out / name)
        assert files(out) == {name: FOREIGN}
        (out / name).unlink()


def test_reproduce_refuses_a_foreign_report_or_figure_file(tmp_path, capsys):
    out = tmp_path / "repro"
    report = tmp_path / "REPORT.md"
    foreign_file(report)
    args = ["reproduce", "--quick", "--out", str(out), "--report", str(report)]
    refused(capsys, args, "--report", report)
    report.unlink()
    table = out / "fig12_resolved_sources.csv"
    foreign_file(table)
    refused(capsys, args, "--out", table)
    assert files(out) == {table.name: FOREIGN} and not report.exists()


def test_a_bag_is_never_overwritten(tmp_path, capsys, wall):
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "notes.txt").write_bytes(FOREIGN)
    capsys.readouterr()
    assert main(["export", str(wall), "--out", str(bag), "-q"]) == 2
    assert f"--out {str(bag)!r} exists already" in capsys.readouterr().err
    assert files(bag) == {"notes.txt": FOREIGN}


def test_every_kind_knows_our_output_from_a_foreign_file(tmp_path, wall):
    """The tests of :data:`acousim.cli.ours.KINDS`: a foreign file is none of ours,
    and an HDF5 output is only the kind it is."""
    from acousim.cli.ours import KINDS, is_ours

    mine = tmp_path / "mine.txt"
    mine.write_bytes(FOREIGN)
    assert not any(is_ours(kind, mine) for kind in KINDS)
    assert [k for k in KINDS if is_ours(k, wall)] == ["recordings"]
    shutil.copy(wall, tmp_path / "copy.h5")
    assert is_ours("recordings", tmp_path / "copy.h5")
    assert not is_ours("recordings", tmp_path)  # a folder is no file of ours


def test_a_dataset_run_again_replaces_its_own_manifest(tmp_path, capsys):
    from tests import REPO

    spec = tmp_path / "spec.toml"
    spec.write_text(
        "[dataset]\nsamples = 1\nshard_size = 1\nseed = 3\n[[scenes]]\n"
        f'file = "{REPO / "scenes" / "points.toml"}"\n[store]\nimages = ["das"]\n'
        "step_deg = 10.0\ndepth_map = false\n"
    )
    args = ["dataset", str(spec), "--out", str(tmp_path / "data"), "--workers", "1", "-q"]
    assert main(args) == 0
    first = (tmp_path / "data" / "manifest.json").stat().st_ino
    assert main(args) == 0  # resumed, nothing to do: the manifest written again
    assert (tmp_path / "data" / "manifest.json").stat().st_ino != first


def test_the_committed_study_files_are_ours():
    """docs/reproduction and docs/REPRODUCTION.md, written by `acousim reproduce`,
    are known as its outputs (a rerun with --out docs/reproduction replaces them)."""
    from acousim.cli.ours import is_ours
    from acousim.cli.reproduce import _replaced
    from tests import REPO

    folder = REPO / "docs" / "reproduction"
    kinds = _replaced(folder)
    assert len(kinds) == len(list(folder.iterdir()))
    assert all(is_ours(kind, folder / name) for name, kind in kinds.items())
    assert is_ours("reproduction", REPO / "docs" / "REPRODUCTION.md")
    assert not is_ours("reproduction", REPO / "README.md")
