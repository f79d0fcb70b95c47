"""Long commands say where they are: a progress bar with the count, the rate and the
time left on a terminal (run here under a pseudo-terminal), one final line in a log,
nothing with --quiet; the time a command reports counts from its start.

The pseudo-terminal tests read the command's output until it closes it (no sleeps, no
clock): what it printed is then complete."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import shutil
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from acousim.cli import main
from tests import REPO

ROOT = REPO
SCENES = ROOT / "scenes"


def three_poses(folder: Path) -> Path:
    """The bundled points scene (3 point reflectors, paper_8x8) driven through three
    poses 1 cm apart: three quick recordings."""
    text = (SCENES / "points.toml").read_text()
    text = text.replace(
        "[sensor.pose]\nposition_m = [0.0, 0.0, 0.0]\n",
        '[sensor.trajectory]\nfile = "drive.csv"\nrate_hz = 10\n',
    )
    assert "drive.csv" in text
    (folder / "drive.csv").write_text("0,0,0,0\n0.01,0,0,0\n0.02,0,0,0\n")
    path = folder / "three.toml"
    path.write_text(text)
    return path


def run_on_a_terminal(args: list[str], cwd: Path, columns: int = 120) -> tuple[int, str]:
    """Run ``acousim ARGS`` with stdin, stdout and stderr on a pseudo-terminal
    (`columns` wide; 0: one that says no size); its exit code and everything it
    wrote, read until it closed the terminal."""
    master, slave = pty.openpty()
    rows = 24 if columns else 0
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, columns, 0, 0))
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    env.pop("ACOUSIM_PROGRESS_LINES", None)
    proc = subprocess.Popen(
        [sys.executable, "-m", "acousim.cli", *args],
        stdin=slave,
        stdout=slave,
        stderr=slave,
        cwd=cwd,
        env=env,
    )
    os.close(slave)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # EIO: the command closed its end
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(master)
    return proc.wait(), b"".join(chunks).decode(errors="replace")


def test_a_terminal_shows_a_bar_with_count_rate_and_time_left(tmp_path):
    scene = three_poses(tmp_path)
    code, text = run_on_a_terminal(["simulate", scene.name, "--out", "x.h5"], tmp_path)
    assert code == 0, text
    states = [s for s in re.split(r"[\r\n]+", text) if s.startswith("simulate:")]
    # after the first pose: a count, an estimate of the time left (not '?') and a rate
    first = next(s for s in states if " 1/3 " in s)
    assert re.search(r"\| 1/3 \[\d\d:\d\d<\d\d:\d\d, +[\d.]+(pose/s|s/pose)\]", first), first
    # the finished bar stays, then the result
    assert re.search(r"simulate: 100%\|.*\| 3/3 \[\d\d:\d\d<00:00, +[\d.]+(pose/s|s/pose)\]", text)
    assert "3 recording(s) of 'points' written to x.h5" in text


def test_a_terminal_that_says_no_size_still_shows_the_bar(tmp_path):
    """A pseudo-terminal of 0 x 0 (as some CI runners and `script` give): the bar is
    drawn 80 columns wide, not as nothing."""
    scene = three_poses(tmp_path)
    args = ["simulate", scene.name, "--out", "x.h5"]
    code, text = run_on_a_terminal(args, tmp_path, columns=0)
    assert code == 0, text
    bar = r"simulate: 100%\|.*\| 3/3 \[\d\d:\d\d<00:00, +[\d.]+(pose/s|s/pose)\]"
    drawn = [ln for ln in re.split(r"[\r\n]+", text) if re.search(bar, ln)]
    assert drawn and all(len(ln.strip()) <= 80 for ln in drawn), text


def test_image_shows_its_write_phase_on_a_terminal(tmp_path):
    """`image` under a terminal: a bar for the imaging, then for the pictures (by
    picture) and images.h5 (by recording), each kept when done; with --quiet, only
    the files written."""
    scene = three_poses(tmp_path)
    code, text = run_on_a_terminal(["simulate", scene.name, "--out", "x.h5", "-q"], tmp_path)
    assert code == 0, text
    args = ["image", "x.h5", "--method", "das", "--no-3d", "--no-animation", "--out", "img"]
    args.append("--images-h5")
    code, text = run_on_a_terminal(args, tmp_path)
    assert code == 0, text
    for desc, done in (("image", "3/3"), ("images.h5", "3/3"), ("pictures", "2/2")):
        rate = r"[\d.]+(recording/s|s/recording|picture/s|s/picture)"
        bar = rf"{re.escape(desc)}: 100%\|.*\| {done} \[\d\d:\d\d<00:00, +{rate}\]"
        assert re.search(bar, text), (desc, text)
    assert text.index("pictures: 100%") < text.index("images.h5: 100%")
    code, text = run_on_a_terminal([*args, "--quiet"], tmp_path)
    assert code == 0, text
    lines = [ln.strip() for ln in re.split(r"[\r\n]+", text) if ln.strip()]
    *files, total = lines  # the files written, then how many and the wall time
    assert files and all(ln.startswith("img/") or ln.startswith("(") for ln in files), lines
    assert re.fullmatch(r"\d+ file\(s\) written to img \([\d.]+ s from the start\)", total)


TINY_SPEC = """
[dataset]
name = "tiny"
samples = 2
shard_size = 1
seed = 3

[[scenes]]
file = "{scene}"

[store]
images = ["das"]
step_deg = 6.0
max_bins = 32
"""


def _remove_outputs(folder: Path) -> None:
    """What the commands below wrote (each refuses or keeps an existing output)."""
    for made in ("ds", "bag", "c.h5", "r.h5", "fitted.toml"):
        if (folder / made).is_file():
            (folder / made).unlink()
        shutil.rmtree(folder / made, ignore_errors=True)


def test_every_long_command_shows_its_bar_on_a_terminal(tmp_path):
    """export (a bag, a CHIRP file), record, compare, calibrate and dataset under a
    pseudo-terminal: each a bar with its count, rate and time left, kept when done,
    then its result; with --quiet the result alone (simulate and image: above)."""
    scene = three_poses(tmp_path)
    for made, name in (("x.h5", scene.name), ("w.h5", "wall")):
        code, text = run_on_a_terminal(["simulate", name, "--out", made, "-q"], tmp_path)
        assert code == 0, text
    (tmp_path / "tiny.toml").write_text(TINY_SPEC.format(scene=scene))
    runs = {  # command: (its bars: desc, count, unit), the start of its result line
        ("export", "x.h5", "--method", "das", "--out", "bag"): (
            [("image", "3/3", "recording"), ("bag", "3/3", "recording")],
            "3 recording(s) written to the ROS 2 bag",
        ),
        ("export", "x.h5", "--format", "chirp", "--out", "c.h5"): (
            [("CHIRP", "6/6", "step")],
            "3 recording(s) written to the CHIRP file",
        ),
        ("record", "--emulate", "wall", "--count", "2", "--out", "r.h5"): (
            [("record", "2/2", "measurement")],
            "2 measurement(s) written to r.h5",
        ),
        ("compare", "x.h5", "--sim", "x.h5", "--method", "das", "--all"): (
            [("compare", "3/3", "pair")],
            "(",
        ),
        ("calibrate", "w.h5", "--scene", "wall", "--out", "fitted.toml"): (
            [("calibrate", "1/1", "pose")],
            "fitted scene written to fitted.toml",
        ),
        ("dataset", "tiny.toml", "--out", "ds", "--workers", "1"): (
            [("shards", "2/2", "shard")],
            "2 samples in 2 shards in ds",
        ),
    }
    for args, (bars, result) in runs.items():
        code, text = run_on_a_terminal(list(args), tmp_path)
        assert code == 0, (args, text)
        for desc, done, unit in bars:
            rate = rf"[\d.]+({unit}/s|s/{unit})"
            bar = rf"{re.escape(desc)}: 100%\|.*\| {done} \[\d\d:\d\d<00:00, +{rate}\]"
            assert re.search(bar, text), (args, desc, text)
        lines = [ln.strip() for ln in re.split(r"[\r\n]+", text) if ln.strip()]
        assert any(ln.startswith(result) for ln in lines), (args, lines)
        _remove_outputs(tmp_path)
        code, text = run_on_a_terminal([*args, "--quiet"], tmp_path)
        assert code == 0, (args, text)
        assert "100%|" not in text and "it/s" not in text, (args, text)
        _remove_outputs(tmp_path)


def test_quiet_on_a_terminal_prints_only_the_result(tmp_path):
    scene = three_poses(tmp_path)
    code, text = run_on_a_terminal(["simulate", scene.name, "--out", "x.h5", "--quiet"], tmp_path)
    assert code == 0, text
    lines = [ln for ln in re.split(r"[\r\n]+", text) if ln]
    assert len(lines) == 1 and lines[0].startswith("3 recording(s) of 'points' written"), lines


def test_a_log_gets_one_final_line_per_stage(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("ACOUSIM_PROGRESS_LINES", raising=False)
    scene = three_poses(tmp_path)
    out = tmp_path / "x.h5"
    assert main(["simulate", str(scene), "--out", str(out)]) == 0
    said = capsys.readouterr()  # progress on stderr (no bar drawn into a log), results on stdout
    lines = said.err.splitlines()
    assert len(lines) == 1 and len(said.out.splitlines()) == 1, said
    m = re.fullmatch(r"simulate: 3/3 poses in ([\d.]+) s \(([\d.e+]+) poses/s\)", lines[0])
    assert m, lines[0]
    seconds, rate = float(m.group(1)), float(m.group(2))
    if seconds >= 0.5:  # the rate is the count over the time (both as printed, rounded)
        assert rate == pytest.approx(3 / seconds, rel=0.15)
    assert said.out.startswith("3 recording(s) of 'points' written")
    # image: one line for the imaging; the animation's frames get theirs
    args = ["image", str(out), "--method", "das", "--out", str(tmp_path / "img"), "--no-3d"]
    assert main([*args, "--images-h5"]) == 0
    said = capsys.readouterr()
    lines = said.err.splitlines()
    assert len(lines) == 3, said  # the files written, on stdout
    assert re.fullmatch(
        r"5 file\(s\) written to .*img \([\d.]+ s from the start\)", said.out.splitlines()[-1]
    )
    assert re.fullmatch(r"image: 3/3 recordings in [\d.]+ s \([\d.e+]+ recordings/s\)", lines[0])
    # the write phase: the pictures (fan, el-az of das, the animation) by picture,
    # then images.h5 by recording (its label maps made meanwhile)
    assert re.fullmatch(r"pictures: 3/3 pictures in [\d.]+ s \(.*\)", lines[1]), lines
    assert re.fullmatch(r"images.h5: 3/3 recordings in [\d.]+ s \(.*\)", lines[2]), lines
    # export: the imaging, then the bag's recordings
    assert main(["export", str(out), "--method", "das", "--out", str(tmp_path / "bag")]) == 0
    said = capsys.readouterr()
    lines = said.err.splitlines()
    assert re.fullmatch(r"image: 3/3 recordings in [\d.]+ s \(.*\)", lines[0]), lines
    assert re.fullmatch(r"bag: 3/3 recordings in [\d.]+ s \(.*\)", lines[1]), lines
    assert re.fullmatch(
        r"3 recording\(s\) written to the ROS 2 bag .* \(MCAP\) \([\d.]+ s from the start\)",
        said.out.strip(),
    )
    # a CHIRP file: its 3 captures' samples and 3 recordings' own data, then the result
    args = ["export", str(out), "--format", "chirp", "--out", str(tmp_path / "c.h5")]
    assert main(args) == 0
    said = capsys.readouterr()
    assert re.fullmatch(r"CHIRP: 6/6 steps in [\d.]+ s \(.*\)", said.err.strip()), said
    assert re.fullmatch(
        r"3 recording\(s\) written to the CHIRP file .* \([\d.]+ s from the start\)",
        said.out.strip(),
    )


def test_quiet_in_a_log_prints_only_the_result(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("ACOUSIM_PROGRESS_LINES", raising=False)
    scene = three_poses(tmp_path)
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5"), "-q"]) == 0
    said = capsys.readouterr()
    assert said.err == "" and len(said.out.splitlines()) == 1, said


def test_record_counts_its_measurements(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("ACOUSIM_PROGRESS_LINES", raising=False)
    shutil.copy(SCENES / "wall.toml", tmp_path / "wall.toml")
    shutil.copytree(SCENES / "meshes", tmp_path / "meshes")
    args = ["record", "--emulate", str(tmp_path / "wall.toml"), "--count", "2"]
    assert main([*args, "--out", str(tmp_path / "r.h5")]) == 0
    out = capsys.readouterr().err.splitlines()
    assert re.fullmatch(r"simulate: 1/1 poses in [\d.]+ s \(.*\)", out[0]), out  # its one pose
    assert re.fullmatch(r"record: 2/2 measurements in [\d.]+ s \(.*\)", out[1]), out


def test_the_reported_time_counts_the_preparation(tmp_path, capsys, monkeypatch):
    """`simulate` reports the wall time since the command started: loading the scene
    (made to take 50 s on a clock of the test's own) is counted, as are the imports."""
    from acousim.cli import clock, simulate

    now = [1000.0]
    monkeypatch.setattr(clock, "_clock", lambda: now[0])
    real_load = simulate.load_scene

    def slow_load(path):
        now[0] += 50.0
        return real_load(path)

    monkeypatch.setattr(simulate, "load_scene", slow_load)
    scene = three_poses(tmp_path)
    assert main(["simulate", str(scene), "--out", str(tmp_path / "x.h5"), "-q"]) == 0
    out = capsys.readouterr().out
    assert out.strip().endswith("(50.0 s from the start)"), out


def test_calibrate_reports_its_time_from_the_start(tmp_path, capsys, monkeypatch):
    """`calibrate` ends with its wall time from the start as `simulate` does: loading
    the scene (50 s on the test's clock) counted, not only the fit's evaluations."""
    from acousim.cli import calibrate, clock

    monkeypatch.delenv("ACOUSIM_PROGRESS_LINES", raising=False)
    shutil.copy(SCENES / "wall.toml", tmp_path / "wall.toml")
    shutil.copytree(SCENES / "meshes", tmp_path / "meshes")
    wall = str(tmp_path / "wall.toml")
    assert main(["simulate", wall, "--out", str(tmp_path / "w.h5"), "-q"]) == 0
    capsys.readouterr()
    now = [1000.0]
    monkeypatch.setattr(clock, "_clock", lambda: now[0])
    real_load = calibrate.load_scene

    def slow_load(path):
        now[0] += 50.0
        return real_load(path)

    monkeypatch.setattr(calibrate, "load_scene", slow_load)
    args = ["calibrate", str(tmp_path / "w.h5"), "--scene", wall, "--out"]
    assert main([*args, str(tmp_path / "fitted.toml"), "-q"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert re.fullmatch(r"fitted scene written to .*fitted\.toml \(50\.0 s from the start\)", last)


def test_the_clock_starts_before_the_command_imports_anything(monkeypatch):
    """main() starts the clock before _main() imports the processing package (numpy,
    scipy: seconds on a busy machine): those imports are in the reported time."""
    import acousim.cli as cli
    from acousim.cli import clock

    calls = []
    monkeypatch.setattr(clock, "start", lambda: calls.append("clock"))
    monkeypatch.setattr(cli, "_main", lambda argv, handled: calls.append("imports") or 0)
    assert cli.main(["scenes"]) == 0
    assert calls == ["clock", "imports"]
