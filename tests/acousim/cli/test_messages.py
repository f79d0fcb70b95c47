"""What costs a newcomer minutes, said on the first try: the bundled dataset specs
listed, a comparison that writes only where asked and says what it fitted, errors
that name the scene file and the pose (or the mesh file and its format), and a
malformed attribute met with the one-line error by every command that reads files."""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest

import processing as P
from acousim.cli import main
from tests import REPO

ROOT = REPO
SCENES = ROOT / "scenes"


def test_scenes_lists_the_bundled_dataset_specs(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    assert "dataset specs (acousim dataset NAME --out FOLDER):" in out
    spec = tomllib.loads((ROOT / "datasets" / "corridor_small.toml").read_text())
    samples, size = spec["dataset"]["samples"], spec["dataset"]["shard_size"]
    shards = -(-samples // size)
    images = ", ".join(spec["store"]["images"])
    line = next(ln for ln in out.splitlines() if ln.startswith("corridor_small.toml"))
    assert line.split(None, 1)[1] == (
        f"{samples} samples in {shards} shard(s) of corridor (random poses): images {images}"
    )


# --- compare -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory) -> Path:
    """The points scene simulated with two noise seeds: a "real" and a simulated run."""
    folder = tmp_path_factory.mktemp("two_runs")
    for seed, name in ((1, "real.h5"), (2, "sim.h5")):
        args = ["simulate", str(SCENES / "points.toml"), "--out", str(folder / name)]
        assert main([*args, "--seed", str(seed), "-q"]) == 0
    return folder


def _floor_db(profile: np.ndarray, reference: float) -> float:
    """The median power over the last quarter of a profile's bins, dB re `reference`
    (written here again from the definition docs/compare.md gives)."""
    tail = profile[len(profile) - len(profile) // 4 :] if len(profile) % 4 == 0 else None
    if tail is None:
        tail = profile[int(len(profile) * 0.75) :]
    return 10 * np.log10(np.median(tail) / reference)


def test_compare_writes_nothing_unasked_and_says_what_was_fitted(
    two_runs, tmp_path, monkeypatch, capsys
):
    from acousim.compare.comparison import compare

    monkeypatch.chdir(tmp_path)  # an empty folder: nothing may appear in it
    real, sim = two_runs / "real.h5", two_runs / "sim.h5"
    assert main(["compare", str(real), "--sim", str(sim), "-q"]) == 0
    assert list(tmp_path.iterdir()) == []
    out = capsys.readouterr().out
    assert "(nothing written: --out FOLDER writes the JSON report and the picture)" in out
    assert re.search(r"fitted to this pair: the emission time \(shift -?[\d.]+ samples\)", out)
    assert "agrees on that echo by construction" in out
    assert "predicted, not fitted:" in out
    # the noise floors printed are those of the two aligned range profiles
    _, arrays = compare(P.load_recording(real), P.load_recording(sim), ("das",))
    ref = arrays.profile_real.max()
    want_real, want_sim = _floor_db(arrays.profile_real, ref), _floor_db(arrays.profile_sim, ref)
    assert f"real {want_real:.1f} dB, simulated {want_sim:.1f} dB" in out
    # the other echoes and the side lobes: counted, not fitted
    # (the peaks of the two points off axis are paired too, but the simulation's peak
    # table finds no traced path in their cells: not counted as matched echoes)
    assert re.search(r"das: besides the strongest matched echo \(\d\.\d{3} m\) (no|\d+) other", out)
    assert re.search(r"side lobes: \d+ real", out)
    # with --out: the files, in that folder only
    assert main(["compare", str(real), "--sim", str(sim), "--out", "cmp", "-q"]) == 0
    assert sorted(p.name for p in tmp_path.rglob("*")) == [
        "cmp",
        "comparison.json",
        "comparison.png",
    ]


# --- errors that say where -------------------------------------------------------------


def _box_scene(folder: Path) -> Path:
    """A closed 1 m box at the origin and three poses; the last one inside the box."""
    import trimesh

    trimesh.creation.box((1.0, 1.0, 1.0)).export(folder / "box.stl")
    (folder / "drive.csv").write_text("-2.0,0,0,0\n-1.5,0,0,0\n0,0,0,0\n")
    path = folder / "inbox.toml"
    path.write_text(
        '[scene]\nname = "inbox"\n[sensor]\narray = "urtis_v1"\ndirect_path = false\n'
        '[sensor.trajectory]\nfile = "drive.csv"\nrate_hz = 10\n'
        "[simulation]\nmax_range_m = 3.0\n"
        '[[meshes]]\nfile = "box.stl"\n'
    )
    return path


def test_a_sensor_inside_a_mesh_names_the_scene_file_and_the_pose(tmp_path, capsys):
    scene = _box_scene(tmp_path)
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(
        f"acousim simulate: error: {scene}: pose 2: the sensor at [0.0, 0.0, 0.0] m is inside "
        "a closed mesh"
    ), err
    assert len(err.splitlines()) == 1
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5"), "--poses", "0:2"]) == 0


def test_a_sensor_inside_a_mesh_in_python_names_the_scene_and_the_pose(tmp_path):
    import acousim
    from processing.base.errors import InputError

    scene = acousim.load_scene(_box_scene(tmp_path))
    with pytest.raises(InputError, match=r"inbox.toml: pose 2: the sensor at"):
        acousim.Simulator(scene).simulate_pose(scene.sensor.poses[2], 2)


@pytest.mark.parametrize("suffix,fmt", [(".stl", "STL"), (".obj", "OBJ")])
def test_a_file_that_is_not_a_mesh_says_its_format(tmp_path, capsys, suffix, fmt):
    (tmp_path / f"notes{suffix}").write_text("shopping list: eggs, milk\n")
    scene = tmp_path / "s.toml"
    scene.write_text(
        (SCENES / "wall.toml").read_text().replace("meshes/wall.stl", f"notes{suffix}")
    )
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        f"acousim simulate: error: {tmp_path / f'notes{suffix}'}: could not be read as {fmt} "
        "(no faces found in it)"
    )


def test_a_file_its_reader_refuses_says_its_format_and_why(tmp_path, capsys):
    """A GLB that is not one (its reader raises, rather than finding no faces): the
    same words, with the reader's reason (it said "cannot read mesh")."""
    (tmp_path / "notes.glb").write_bytes(b"shopping list: eggs, milk\n" * 8)
    scene = tmp_path / "s.toml"
    scene.write_text((SCENES / "wall.toml").read_text().replace("meshes/wall.stl", "notes.glb"))
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(
        f"acousim simulate: error: {tmp_path / 'notes.glb'}: could not be read as GLB ("
    )
    assert len(err.splitlines()) == 1, err


# --- a malformed attribute ------------------------------------------------------------------


@pytest.fixture(scope="module")
def malformed(tmp_path_factory) -> Path:
    """A recording file whose root `schema` attribute is an array of strings (a
    hand-edited or foreign file), and one whose `format` is an array of numbers."""
    folder = tmp_path_factory.mktemp("malformed")
    rec = P.Recording(np.zeros((64, 3000)), 500e3, P.paper_8x8(), P.paper_chirp())
    for name, key, value in (
        ("schema.h5", "schema", np.array(["acousim.recordings", "x"], dtype=h5py.string_dtype())),
        ("format.h5", "format", np.array([1, 2])),
    ):
        P.save_recording(folder / name, rec)
        with h5py.File(folder / name, "a") as f:
            f.attrs[key] = value
    P.save_recording(folder / "ok.h5", rec)
    shutil.copy(SCENES / "wall.toml", folder / "wall.toml")
    shutil.copytree(SCENES / "meshes", folder / "meshes")
    return folder


COMMANDS = [
    ["info", "{f}"],
    ["image", "{f}", "--out", "{d}/img", "--method", "das"],
    ["export", "{f}", "--format", "chirp", "--out", "{d}/c.h5"],
    ["export", "{f}", "--out", "{d}/bag"],
    ["compare", "{f}", "--sim", "{f}"],
    ["compare", "{m}/ok.h5", "--sim", "{f}"],
    ["calibrate", "{f}", "--scene", "{m}/wall.toml", "--out", "{d}/fit.toml"],
]


@pytest.mark.parametrize("args", COMMANDS, ids=lambda a: "-".join(a[:2]))
def test_a_schema_attribute_that_is_an_array_is_one_line(malformed, tmp_path, capsys, args):
    f = malformed / "schema.h5"
    assert main([a.format(f=f, d=tmp_path, m=malformed) for a in args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"{f}: schema = ['acousim.recordings', 'x']: not a recording file" in err, err


def test_a_format_attribute_that_is_an_array_is_no_chirp_file(malformed, capsys):
    """is_chirp compared an array with "chirp" (an array, whose truth is ambiguous)."""
    f = malformed / "format.h5"
    assert not P.is_chirp(f)
    assert main(["info", str(f)]) == 0  # a recording file, with a stray attribute
    assert "paper_8x8" in capsys.readouterr().out


def test_a_malformed_attribute_of_our_chirp_or_images_file_is_one_line(tmp_path, capsys):
    """The fuzzed attributes that still met a traceback: a CHIRP file's URA pitch as an
    array of strings (info and image read it), an images.h5's `units` as an array."""
    rec = P.Recording(np.zeros((64, 3000)), 500e3, P.paper_8x8(), P.paper_chirp())
    chirp = P.write_chirp(tmp_path / "c.h5", [rec])
    with h5py.File(chirp, "a") as f:
        bad = np.array([["a", "b"], ["c", "d"]], dtype=h5py.string_dtype())
        f["acousim/array/grid_index"].attrs["pitch_m"] = bad
    assert main(["image", str(chirp), "--out", str(tmp_path / "i"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"{chirp}: /acousim/array/grid_index.pitch_m = " in err and "metres" in err
    assert main(["info", str(chirp)]) == 0  # info describes the file, and says so
    said = capsys.readouterr().out
    assert "its recordings cannot be read: must be the pitch (dz, dy) in metres" in said
    images = tmp_path / "images.h5"
    with h5py.File(images, "w") as f:
        f.attrs["format"] = "acousim-images"
        g = f.create_group("recording_000000")
        g.create_dataset("das", data=np.zeros((2, 3, 4), np.float32)).attrs["units"] = "dB"
        g.create_dataset("azimuth_deg", data=np.zeros(4)).attrs["units"] = np.array([1, 2])
    assert main(["info", str(images)]) == 0  # the stray attribute is not an image's
    out = capsys.readouterr().out
    assert "images of 1 recording(s)" in out and "das (range x elevation x azimuth (2, 3, 4)" in out


def test_a_closed_output_ends_the_command_quietly():
    """`acousim scenes | head -0`: the reader has gone before the command prints; it
    stops as a Unix tool does, without a traceback, with 128 + SIGPIPE."""
    import os
    import subprocess
    import sys

    from acousim.cli import CLOSED_OUTPUT

    read, write = os.pipe()
    os.close(read)  # nobody reads: the first write fails, whatever the timing
    try:
        done = subprocess.run(
            [sys.executable, "-m", "acousim.cli", "scenes"],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
        )
    finally:
        os.close(write)
    assert done.returncode == CLOSED_OUTPUT == 141
    assert done.stderr == ""


def test_image_refusing_its_input_creates_nothing_and_says_what_it_was_given(tmp_path, capsys):
    """`image` given a bag folder, an images.h5, a folder or a sonar the file lacks:
    exit 2, one line naming the input and what it is, and no --out folder made."""
    from acousim.bundled import resolve
    from acousim.cli.ours import IMAGES_FORMAT
    from acousim.export.images import FORMAT

    assert IMAGES_FORMAT == FORMAT  # spelt out in the command line's module (acousim.cli.ours)
    rec = tmp_path / "wall.h5"
    assert main(["simulate", str(resolve("scenes", "wall")), "--out", str(rec), "-q"]) == 0
    bag = tmp_path / "bag"  # a rosbag2 folder's layout (its files' content is not read)
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bag / "bag.mcap").write_bytes(b"")
    images = tmp_path / "images.h5"
    with h5py.File(images, "w") as f:
        f.attrs["format"] = FORMAT
    plain = tmp_path / "plain"
    plain.mkdir()
    reads = "give a recording file (.h5 of `acousim simulate` or `record`) or a CHIRP file"
    cases = (
        ([str(rec), "--sensor", "front_left"], "--sensor = 'front_left': no recording of sonar"),
        (
            [str(bag)],
            f"{bag}: a ROS 2 bag (a folder, as `acousim export` writes it), which "
            f"this command does not read; {reads}",
        ),
        (
            [str(images)],
            f"{images}: an images.h5 (images written by `acousim image "
            f"--images-h5`), not a recording file; {reads}",
        ),
        ([str(plain)], f"{plain}: a folder, not a file; {reads}"),
    )
    for n, (args, message) in enumerate(cases):
        out = tmp_path / "new" / f"img{n}"
        capsys.readouterr()
        assert main(["image", *args, "--out", str(out), "--no-3d", "-q"]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1, err
        assert not (tmp_path / "new").exists()
    # export reads the same files: the same words, and no folder made for --out
    import importlib.util

    outs = [["--format", "chirp", "--out", str(tmp_path / "new/c.h5")]]
    if importlib.util.find_spec("rosbags"):  # the bag's writer (else: refused for it)
        outs.append(["--out", str(tmp_path / "new/b")])
    for out in outs:
        assert main(["export", str(bag), *out]) == 2
        assert f"{bag}: a ROS 2 bag" in capsys.readouterr().err
        assert not (tmp_path / "new").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag", "images.h5", "plain", "wall.h5"]
