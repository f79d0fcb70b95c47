"""The command line end to end: simulate -> image -> pictures, and its error paths."""

import shutil
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

import processing as P
from acousim.cli import main
from tests import REPO

SCENES = REPO / "scenes"


def copy_scene(tmp_path, name):
    shutil.copy(SCENES / f"{name}.toml", tmp_path / f"{name}.toml")
    if (SCENES / "meshes").exists():
        shutil.copytree(SCENES / "meshes", tmp_path / "meshes", dirs_exist_ok=True)
    for extra in SCENES.glob("*.csv"):
        shutil.copy(extra, tmp_path / extra.name)
    return tmp_path / f"{name}.toml"


def test_simulate_then_image_finds_the_point_reflectors(tmp_path, capsys):
    scene = copy_scene(tmp_path, "points")
    out = tmp_path / "pts.h5"
    assert main(["simulate", str(scene), "--out", str(out), "--seed", "3"]) == 0
    rec = P.load_recording(out)
    assert rec.metadata["scene_sha256"] and rec.metadata["seed"] is not None
    assert len(rec.truth.position_sensor_m) == 3
    assert (
        main(
            [
                "image",
                str(out),
                "--method",
                "das,music-fbss",
                "--out",
                str(tmp_path / "img"),
                "--step",
                "1",
                "--energy-fraction",
                "0.3",
            ]
        )
        == 0
    )
    img = P.acoustic_image(
        rec,
        "music-fbss",
        P.ProcessingSettings(
            energy_fraction=0.3,
            grid=P.Grid.degrees(elevation=(-90, 90), step=1.0),
            range_limits_m=(0.25, 2.0),
        ),
    )
    pk = img.peaks(-20)
    found = pk.range_m[:, None] * np.stack(
        [
            np.cos(pk.elevation_rad) * np.cos(pk.azimuth_rad),
            np.cos(pk.elevation_rad) * np.sin(pk.azimuth_rad),
            np.sin(pk.elevation_rad),
        ],
        axis=1,
    )
    centre = rec.array.positions_m.mean(axis=0)
    for t in rec.truth.position_sensor_m:
        assert np.min(np.linalg.norm(found + centre - t, axis=1)) < 0.05
    fan = imread(tmp_path / "img" / "fan.png")
    assert fan[..., :3].std() > 0.05  # not blank


def test_wall_pictures_show_the_mesh_and_the_peak_where_the_wall_is(tmp_path):
    from acousim.viz.render3d import PEAK_COLOR, TRUTH_COLOR

    scene = copy_scene(tmp_path, "wall")
    out = tmp_path / "wall.h5"
    assert main(["simulate", str(scene), "--out", str(out)]) == 0
    assert main(["image", str(out), "--out", str(tmp_path / "img"), "--method", "das"]) == 0
    pic = imread(tmp_path / "img" / "scene3d.png")[..., :3]
    background = np.all(pic > 0.97, axis=2)
    assert pic.shape[0] > 300 and background.mean() < 0.95, "blank picture"
    grey = (
        (np.abs(pic - pic.mean(axis=2, keepdims=True)).max(axis=2) < 0.03)
        & (pic.mean(axis=2) < 0.95)
        & (pic.mean(axis=2) > 0.3)
    )
    assert grey.mean() > 0.05, "the wall mesh is not visible"
    scene = np.ones(pic.shape[:2], bool)
    scene[-int(0.07 * pic.shape[0]) :] = False  # not the legend (below the view)
    red = np.all(np.abs(pic - np.array(PEAK_COLOR)) < 0.25, axis=2) & scene
    cyan = np.all(np.abs(pic - np.array(TRUTH_COLOR)) < 0.25, axis=2) & scene
    assert red.sum() > 20, "no image peak drawn"
    # the image peak is drawn on the ray-traced reflection point (cyan, partly hidden)
    ry, rx = np.nonzero(red)
    cy, cx = np.nonzero(cyan)
    assert cy.size, "ray-traced reflector not drawn"
    assert np.hypot(ry.mean() - cy.mean(), rx.mean() - cx.mean()) < 25


def test_trajectory_gives_an_animation(tmp_path):
    import imageio.v2 as imageio

    scene = copy_scene(tmp_path, "corridor")
    out = tmp_path / "c.h5"
    assert main(["simulate", str(scene), "--out", str(out), "--poses", "0:3"]) == 0
    assert len(P.load_recordings(out)) == 3
    assert (
        main(["image", str(out), "--out", str(tmp_path / "img"), "--method", "das", "--no-3d"]) == 0
    )
    frames = imageio.mimread(tmp_path / "img" / "drive.gif")
    assert len(frames) == 3 and np.asarray(frames[0]).std() > 10
    # the plan (left panel, below the title) is drawn in the sensor's frame: the
    # corridor moves past it, so frames differ there by far more than a title's change
    view = [np.asarray(f, float)[40:, 100:500] for f in frames]
    assert np.abs(view[2] - view[0]).mean() > 0.5
    # the 3D view instead, asked for: other pixels on the left, frames of one size
    three = ["image", str(out), "--out", str(tmp_path / "img3"), "--method", "das", "--no-3d"]
    assert main([*three, "--drive-view", "3d"]) == 0
    frames3 = imageio.mimread(tmp_path / "img3" / "drive.gif")
    assert len(frames3) == 3 and frames3[0].shape == frames[0].shape
    left3 = np.asarray(frames3[0], float)[40:, 100:500]
    assert np.abs(left3 - view[0]).mean() > 5


def test_the_animation_plays_at_the_drive_rate_and_a_second_run_leaves_no_stale_file(
    tmp_path, capsys
):
    """drive.gif's frame delay, read back with Pillow, is the corridor drive's pose
    interval (rate_hz = 10 in corridor.toml: 100 ms); imaging again into the folder
    with another method (and without --images-h5) removes our stale files and keeps
    the user's."""
    import tomllib

    from PIL import Image

    scene = copy_scene(tmp_path, "corridor")
    rate = tomllib.loads(scene.read_text())["sensor"]["trajectory"]["rate_hz"]
    out, img = tmp_path / "c.h5", tmp_path / "img"
    assert main(["simulate", str(scene), "--out", str(out), "--poses", "0:2"]) == 0
    base = ["image", str(out), "--out", str(img), "--no-3d", "--step", "4"]
    assert main([*base, "--method", "das", "--images-h5"]) == 0
    with Image.open(img / "drive.gif") as gif:
        delays = []
        for k in range(gif.n_frames):
            gif.seek(k)
            delays.append(gif.info["duration"])
    assert gif.n_frames == 2 and delays == [1000 / rate] * 2
    (img / "notes.txt").write_text("mine")
    (img / "elaz_mine.png").write_bytes(b"mine")  # not a method's name: the user's
    capsys.readouterr()
    assert main([*base, "--method", "capon", "--no-animation"]) == 0
    said = capsys.readouterr().out
    names = sorted(p.name for p in img.iterdir())
    assert names == [
        "elaz_capon.png",
        "elaz_mine.png",
        "fan.png",
        "notes.txt",
        "peaks.csv",
    ]  # images.h5, asked the first time only, is stale
    assert "removed, stale from an earlier run: drive.gif, elaz_das.png, images.h5" in said
    assert "replaced from an earlier run: fan.png, peaks.csv" in said


@pytest.mark.parametrize(
    "args,pattern",
    [
        (["simulate", "{tmp}/nope.toml"], "nope.toml: no such file, nor a bundled scene"),
        (["simulate", "{tmp}/bad.toml"], r"simulaton: unknown key.*did you mean 'simulation'"),
        (
            ["image", "{tmp}/r.h5", "--method", "das,bogus"],
            "--method = 'bogus': unknown method; none of the 21 is close",
        ),
        (["image", "{tmp}/r.h5", "--method", ""], "--method = '': no method given"),
        (["image", "{tmp}/r.h5", "--method", " , "], "--method = ' , ': no method given"),
        (["image", "{tmp}/r.h5", "--index", "1:0"], r"--index = '1:0': '1:0' selects nothing"),
        (["simulate", "{tmp}/points.toml", "--poses", "3:1"], r"--poses = '3:1'"),
        (["simulate", "{tmp}/points.toml", "--out", "{tmp}"], r"--out = .*is a folder"),
        (
            ["image", "{tmp}/r.h5", "--min-range", "2", "--max-range", "1"],
            r"--max-range = 1.0: must be above --min-range 2",
        ),
        (["image", "{tmp}/r.h5", "--out", "{tmp}/afile/sub"], "cannot be written"),
        (["image", "{tmp}/garbage.h5"], "not an HDF5 file"),
        (
            ["image", "{tmp}/r.h5", "--images-h5", "--no-data"],
            r"--images-h5 = True: --no-data skips every data file",
        ),
        (["image", "{tmp}/r.h5", "--index", "7"], r"--index = \[7\]: the file holds 1"),
        (["simulate", "{tmp}/empty.toml"], "no echo reaches the sensor"),
        (
            ["simulate", "{tmp}/huge.toml"],
            r"would need about 98(\.\d)? GB .* above the limit of 8 GB",
        ),
        (["simulate", "{tmp}/points.toml", "--poses", "x"], "--poses = 'x'"),
    ],
)
def test_errors_are_one_line_with_exit_code_2(tmp_path, capsys, args, pattern):
    import re

    (tmp_path / "bad.toml").write_text(
        '[simulaton]\nrays = 5\n[sensor]\narray = "urtis_v1"\n'
        "[[points]]\nposition_m = [1.0, 0.0, 0.0]\n"
    )
    (tmp_path / "empty.toml").write_text(
        '[sensor]\narray = "urtis_v1"\ndirect_path = false\n'
        "[simulation]\nmax_range_m = 1.0\n"
        "[[points]]\nposition_m = [5.0, 0.0, 0.0]\n"
    )
    (tmp_path / "huge.toml").write_text(  # each value allowed, together ~98 GB
        '[sensor]\narray = "urtis_v1"\nsample_rate_hz = 1e8\n'
        "[simulation]\nmax_range_m = 100.0\n"
        "[[points]]\nposition_m = [1.0, 0.0, 0.0]\n"
    )
    copy_scene(tmp_path, "points")
    (tmp_path / "garbage.h5").write_text("nope")
    (tmp_path / "afile").write_text("a file, not a folder")
    P.save_recording(
        tmp_path / "r.h5", P.Recording(np.zeros((64, 3000)), 500e3, P.paper_8x8(), P.paper_chirp())
    )
    before = set(tmp_path.rglob("*"))
    code = main([a.format(tmp=tmp_path) for a in args])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    # one line besides a finished stage's progress line ("simulate: 1/1 poses in ...")
    said = [ln for ln in lines if not re.fullmatch(r"\w+: \d+/\d+ \w+ in [\d.]+ s \(.*\)", ln)]
    assert len(said) == 1 and len(lines) <= 2 and re.search(pattern, said[0]), lines
    assert set(tmp_path.rglob("*")) - before <= {tmp_path / "out"}  # no partial files


@pytest.mark.parametrize(
    "args,pattern",
    [
        (["image", "r.h5", "--step", "0"], r"argument --step: '0': outside the allowed range"),
        (["image", "r.h5", "--step", "nan"], r"argument --step: 'nan': .*not NaN"),
        (["image", "r.h5", "--energy-fraction", "2"], r"argument --energy-fraction: '2'"),
        (["simulate", "s.toml", "--seed", "-1"], r"argument --seed: '-1': outside"),
        (["simulate", "s.toml", "--seed", "1.5"], r"argument --seed: '1.5' is not a whole"),
        (["record", "--count", "0", "--out", "x.h5"], r"argument --count: '0': outside"),
        (["record", "--duration", "-1", "--out", "x.h5"], r"argument --duration: '-1'"),
        (["record", "--duration", "nan", "--out", "x.h5"], r"argument --duration: 'nan'"),
        (["dataset", "d.toml", "--out", "d", "--workers", "0"], r"argument --workers: '0'"),
        (["compare", "rtisdev-sample", "--index", "-1"], r"argument --index: '-1'"),
    ],
)
def test_arguments_are_checked_when_parsed(capsys, args, pattern):
    """Numbers are checked by their declarations before any work: argparse's usage
    error, exit code 2, naming the argument (not another one) and the value."""
    import re

    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert re.search(pattern, err[-1]), err


def test_out_makes_its_folders_and_a_failed_run_removes_the_empty_ones(tmp_path, capsys):
    """`--out` makes the missing folders (as mkdir -p); a run that fails after making
    them (a pose index out of range) removes those it made, not the existing one."""
    copy_scene(tmp_path, "points")
    (tmp_path / "kept").mkdir()
    out = tmp_path / "kept" / "new" / "sub" / "x.h5"
    code = main(["simulate", str(tmp_path / "points.toml"), "--poses", "99", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "pose index 99 out of range: the scene has 1 pose(s)" in err, err
    assert (tmp_path / "kept").is_dir() and not (tmp_path / "kept" / "new").exists()
    assert main(["simulate", str(tmp_path / "points.toml"), "--out", str(out), "-q"]) == 0
    assert len(P.load_recordings(out)) == 1  # its one pose, in the folders made


def test_interrupted_write_leaves_no_file(tmp_path, monkeypatch, capsys):
    import processing.formats.native as rec_mod

    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(rec_mod, "_write_one", boom)
    scene = copy_scene(tmp_path, "points")
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5")]) == 130
    assert not any(p.name.startswith(("x.h5", ".x.h5")) for p in tmp_path.iterdir())


def test_info_and_scenes(tmp_path, capsys):
    rec = P.Recording(np.zeros((64, 300)), 500e3, P.paper_8x8(), P.paper_chirp())
    P.save_recording(tmp_path / "r.h5", rec)
    assert main(["info", str(tmp_path / "r.h5")]) == 0
    assert "paper_8x8 (64 mics)" in capsys.readouterr().out
    assert main(["scenes"]) == 0
    listing = capsys.readouterr().out
    for name in ("corridor", "shoebox", "wall", "sphere", "points"):
        assert f"{name}.toml" in listing


@pytest.mark.parametrize(
    "scene_file,pattern",
    [
        ("/etc/passwd", r"scene_file = '/etc/passwd': the recording's scene_file is not a scene"),
        ("{tmp}/fake.toml", r"fake.toml: not valid TOML"),
    ],
)
def test_image_follows_scene_file_only_to_a_scene(tmp_path, capsys, scene_file, pattern):
    """A recording's scene_file is opened only for the 3D view, and only a scene file."""
    import re

    (tmp_path / "fake.toml").write_text("root:x:0:0:root:/root:/bin/bash\n")
    rec = P.Recording(
        np.random.default_rng(0).normal(size=(64, 3000)),
        500e3,
        P.paper_8x8(),
        P.paper_chirp(),
        metadata={"scene_file": scene_file.format(tmp=tmp_path)},
    )
    P.save_recording(tmp_path / "r.h5", rec)
    args = ["image", str(tmp_path / "r.h5"), "--method", "das", "--out", str(tmp_path / "o")]
    assert main([*args, "--no-3d", "--no-animation"]) == 0
    capsys.readouterr()
    assert main([*args, "--no-animation"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    # one line besides the finished stages' progress lines ("image: 1/1 recordings in ...")
    said = [ln for ln in lines if not re.fullmatch(r"\w+: \d+/\d+ \w+ in [\d.]+ s \(.*\)", ln)]
    assert len(said) == 1 and re.search(pattern, said[0]), lines


def test_a_swallowed_ctrl_c_still_stops_the_command(tmp_path, monkeypatch, capsys):
    """trimesh's optional imports catch BaseException: an interrupt raised inside one is
    lost to Python, but the command line's SIGINT handler remembers it and stops at
    the next checkpoint (here: before the file is written)."""
    import os
    import signal
    import time

    import acousim.simulator

    real_run = acousim.simulator.Simulator.run

    def swallowing_run(self, *args, **kwargs):
        try:  # what an optional import guarded by `except BaseException` does
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)
        except BaseException:
            pass
        return real_run(self, *args, **kwargs)

    monkeypatch.setattr(acousim.simulator.Simulator, "run", swallowing_run)
    scene = copy_scene(tmp_path, "points")
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5")]) == 130
    assert not (tmp_path / "x.h5").exists()
    assert "interrupted" in capsys.readouterr().err


def test_unreachable_scheduler_is_refused_quickly(tmp_path, capsys):
    import socket

    with socket.socket() as sock:  # a port where nothing listens once closed
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    spec = tmp_path / "s.toml"
    spec.write_text(f"[[scenes]]\nfile = '{SCENES / 'points.toml'}'\n")
    args = ["dataset", str(spec), "--out", str(tmp_path / "d")]
    assert main([*args, "--scheduler", f"tcp://127.0.0.1:{port}"]) == 2
    assert f"--scheduler = 'tcp://127.0.0.1:{port}': no Dask scheduler" in capsys.readouterr().err
    assert main([*args, "--scheduler", "tcp://nohost"]) == 2
    assert "expected tcp://HOST:PORT" in capsys.readouterr().err


def test_preset_choices_match_the_library():
    from acousim.cli import ARRAY_PRESETS, CALL_PRESETS

    assert set(ARRAY_PRESETS) == set(P.PRESETS)
    for name in CALL_PRESETS:
        assert P.rtis_call(name).duration_s > 0
    from processing.base.errors import InputError

    with pytest.raises(InputError, match="call = 'default_10_20': unknown RTIS call preset"):
        P.rtis_call("default_10_20")


def test_a_bug_keeps_its_traceback_and_bad_input_is_one_line(tmp_path, monkeypatch, capsys):
    import acousim.dataset.info as info
    from processing.base.errors import InputError

    def bug(path):
        raise ValueError("a bug deep inside")

    monkeypatch.setattr(info, "describe", bug)
    with pytest.raises(ValueError, match="a bug deep inside"):
        main(["info", str(tmp_path)])

    def bad(path):
        raise InputError("not a recording", file=path)

    monkeypatch.setattr(info, "describe", bad)
    assert main(["info", str(tmp_path)]) == 2
    assert f"acousim info: error: {tmp_path}: not a recording" in capsys.readouterr().err


def test_dataset_takes_a_bundled_spec_by_name(tmp_path, monkeypatch):
    import acousim.dataset
    from acousim.bundled import data_dir

    seen = []

    def fake_generate(spec, out, **kw):
        seen.append(Path(spec))
        s = {"samples_computed": 0, "samples_per_second": 0.0, "bytes_per_sample": 0.0}
        return {"samples": 0, "shards": [], "summary": s}

    monkeypatch.setattr(acousim.dataset, "generate", fake_generate)
    assert main(["dataset", "corridor_small", "--out", str(tmp_path / "d")]) == 0
    assert seen == [data_dir("datasets") / "corridor_small.toml"]
