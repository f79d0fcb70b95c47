"""The command line with CHIRP files: export, info, image and compare."""

import h5py
import numpy as np

import processing as P
from acousim.bundled import resolve
from acousim.cli import main


def test_export_then_image_gives_the_same_image(tmp_path, capsys):
    rec = tmp_path / "wall.h5"
    assert main(["simulate", str(resolve("scenes", "wall")), "--out", str(rec)]) == 0
    chirp = tmp_path / "wall_chirp.h5"
    assert main(["export", str(rec), "--format", "chirp", "--out", str(chirp)]) == 0
    assert P.is_chirp(chirp)
    assert main(["info", str(chirp)]) == 0
    assert "CHIRP file, format 2.1, 1 capture(s)" in capsys.readouterr().out
    for f, out in ((rec, "a"), (chirp, "b")):
        args = ["image", str(f), "--out", str(tmp_path / out), "--method", "das,das-bb"]
        assert main([*args, "--no-3d", "--no-animation", "--images-h5"]) == 0
    with h5py.File(tmp_path / "a/images.h5") as a, h5py.File(tmp_path / "b/images.h5") as b:
        for name in ("das", "das-bb", "range_m"):
            key = f"recording_000000/{name}"
            np.testing.assert_array_equal(a[key][()], b[key][()])
    assert (tmp_path / "a/peaks.csv").read_text() == (tmp_path / "b/peaks.csv").read_text()


def test_call_asked_for(tmp_path, capsys):
    rec = tmp_path / "wall.h5"
    assert main(["simulate", str(resolve("scenes", "wall")), "--out", str(rec)]) == 0
    chirp = tmp_path / "bare.h5"
    assert main(["export", str(rec), "--format", "chirp", "--out", str(chirp)]) == 0
    with h5py.File(chirp, "a") as f:
        del f["acousim"], f["sensors/acoustic_transmitter_00"]
    capsys.readouterr()
    assert main(["info", str(chirp)]) == 0  # described, with what it lacks
    assert "its recordings cannot be read: the file has no transmitter signal" in (
        capsys.readouterr().out
    )
    args = ["image", str(chirp), "--out", str(tmp_path / "img"), "--method", "das", "--no-3d"]
    assert main(args) == 2
    assert "give the call (--call" in capsys.readouterr().err
    assert main([*args, "--no-animation", "--call", "default_25_50"]) == 0


def test_compare_at_the_recorded_poses(tmp_path, capsys):
    """A CHIRP file with odometry (not of ours) against the scene: simulated at each
    capture's own pose (recordings 1 and 2 of the drive, odometry in a file whose
    recording 0 is pose 2: the poses come from the file, not the scene's order)."""
    sim = tmp_path / "drive.h5"
    scene = str(resolve("scenes", "corridor"))
    assert main(["simulate", scene, "--poses", "2", "--out", str(sim)]) == 0
    chirp = tmp_path / "drive_chirp.h5"
    assert main(["export", str(sim), "--format", "chirp", "--out", str(chirp)]) == 0
    with h5py.File(chirp, "a") as f:
        del f["acousim"]
    out = tmp_path / "cmp"
    assert main(["compare", str(chirp), "--scene", scene, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "mean envelope correlation 1.00" in text
    assert "d_range +0.0 cm" in text


def test_export_never_overwrites_the_input_or_a_file_it_did_not_write(tmp_path, capsys):
    """--out an existing file: refused (exit 2, one line naming it, the file's bytes
    unchanged) when it is the input or not a CHIRP file acousim wrote; an earlier
    CHIRP export of ours is replaced, as `simulate` replaces its own files."""
    rec = tmp_path / "wall.h5"
    assert main(["simulate", str(resolve("scenes", "wall")), "--out", str(rec)]) == 0
    mine = tmp_path / "mine.txt"
    mine.write_text("my notes\n")
    foreign = tmp_path / "foreign.h5"  # a CHIRP file not of ours (no acousim group)
    with h5py.File(foreign, "w") as f:
        f.attrs["format"] = "chirp"
    for out, why in (
        (rec, f"--out {str(rec)!r} is the input file {str(rec)!r}"),
        (mine, f"--out {str(mine)!r} exists already and is not a CHIRP file acousim wrote"),
        (foreign, f"--out {str(foreign)!r} exists already and is not a CHIRP file acousim"),
    ):
        before = out.read_bytes()
        capsys.readouterr()
        assert main(["export", str(rec), "--format", "chirp", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert why in err and len(err.strip().splitlines()) == 1, err
        assert out.read_bytes() == before
    chirp = tmp_path / "wall_chirp.h5"
    assert main(["export", str(rec), "--format", "chirp", "--out", str(chirp)]) == 0
    first = chirp.read_bytes()
    assert main(["export", str(rec), "--format", "chirp", "--out", str(chirp)]) == 0
    assert chirp.read_bytes() == first  # same recordings, same bytes
    assert main(["export", str(chirp), "--format", "chirp", "--out", str(chirp)]) == 2
    assert f"--out {str(chirp)!r} is the input file" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["wall.h5", "mine.txt", "foreign.h5", "wall_chirp.h5"]
    )


def test_export_to_chirp_refuses_the_imaging_options(tmp_path, capsys):
    """--help says the imaging options do not apply to a CHIRP export: given, each is
    refused by name and value (a valid --method too, not only an unknown one)."""
    from acousim.cli.export import IMAGING_OPTIONS

    rec = tmp_path / "wall.h5"
    assert main(["simulate", str(resolve("scenes", "wall")), "--out", str(rec), "-q"]) == 0
    out = tmp_path / "c.h5"
    given = {
        "--method": ("foo", "'foo'"),
        "--step": ("2", "2.0"),
        "--energy-fraction": ("0.5", "0.5"),
        "--min-range": ("0.3", "0.3"),
        "--max-range": ("2", "2.0"),
        "--peak-threshold": ("-20", "-20.0"),
        "--dynamic-range-db": ("30", "30.0"),
        "--image-method": ("das", "'das'"),
        "--azimuth": ("-60 60", "[-60.0, 60.0]"),
        "--elevation": ("-60 60", "[-60.0, 60.0]"),
        "--frequency-khz": ("31.25", "31250.0"),
        "--n-sources": ("2", "2"),
        "--subarray": ("4 4", "[4.0, 4.0]"),
    }
    assert sorted(given) == sorted(option for _, option in IMAGING_OPTIONS)
    for option, (text, shown) in given.items():
        capsys.readouterr()
        args = ["export", str(rec), "--format", "chirp", "--out", str(out), option, *text.split()]
        assert main(args) == 2
        err = capsys.readouterr().err.strip()
        assert f"{option} = {shown}: does not apply to --format chirp" in err, err
        assert not out.exists()
    assert (
        main(["export", str(rec), "--method", "das", "--format", "chirp", "--out", str(out)]) == 2
    )
    help_text = " ".join(_help("export").split())
    assert "the imaging options (--method, --azimuth" in help_text and "are refused" in help_text


def _help(command: str) -> str:
    """`acousim COMMAND --help`'s text."""
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.suppress(SystemExit):
        main([command, "--help"])
    return buf.getvalue()
