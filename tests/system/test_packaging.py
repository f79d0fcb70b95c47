"""The wheel works away from the source tree, and the command line's defaults do not
overwrite what is committed.

The wheel test builds the project (no build isolation, no network), installs it with
``--no-deps`` into a fresh virtual environment that borrows this environment's
third-party packages through a ``.pth`` file (never its acousim), and runs the
installed ``acousim`` from an unrelated folder.
"""

import json
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from acousim.cli import build_parser, main
from processing.base.errors import InputError
from tests import REPO

ROOT = REPO
SOURCES = ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md")
PACKAGES = ("processing", "acousim", "hardware", "scenes", "datasets")


def _run(cmd, cwd, **kw):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600, **kw)
    assert proc.returncode == 0, f"{cmd}: exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    import setuptools

    if tuple(int(v) for v in setuptools.__version__.split(".")[:2]) < (77, 0):
        pytest.skip("building needs setuptools >= 77 (pyproject.toml's build requirement)")
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        shutil.copy(ROOT / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.so", "*.pyc")
    for name in PACKAGES:
        shutil.copytree(ROOT / name, src / name, ignore=ignore)
    pip = [sys.executable, "-m", "pip"]
    _run([*pip, "wheel", ".", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp)], src)
    wheel = next(tmp.glob("acousim-*.whl"))
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)], tmp)
    py = venv / "bin" / "python"
    site = Path(
        _run([str(py), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"], tmp).strip()
    )
    # third-party packages from this environment, after the venv's own (not its acousim:
    # a .pth line only appends a folder, it does not run that folder's .pth hooks)
    (site / "borrowed.pth").write_text(sysconfig.get_path("purelib") + "\n")
    _run([*pip, "--python", str(py), "install", "--no-deps", "-q", str(wheel)], tmp)
    elsewhere = tmp / "elsewhere"
    elsewhere.mkdir()
    return venv / "bin" / "acousim", py, elsewhere, wheel


@pytest.mark.slow
def test_the_installed_wheel_carries_its_scenes(installed):
    acousim, py, cwd, wheel = installed
    where = _run([str(py), "-c", "import acousim, processing; print(acousim.__file__)"], cwd)
    assert "site-packages" in where and str(ROOT) not in where
    assert _run([str(acousim), "--version"], cwd).strip() == "acousim 0.1.0"
    listing = _run([str(acousim), "scenes"], cwd)
    names = [line.split()[0] for line in listing.splitlines()]
    assert {"corridor.toml", "wall.toml", "shoebox.toml", "sphere.toml"} <= set(names)
    # a bundled scene by its name, with its mesh and trajectory found inside the package
    _run([str(acousim), "simulate", "wall", "--out", "wall.h5"], cwd)
    _run([str(acousim), "simulate", "corridor", "--poses", "0", "--out", "c.h5"], cwd)
    info = _run([str(acousim), "info", "c.h5"], cwd)
    assert "1 recording(s)" in info and "urtis_v1" in info
    _run([str(acousim), "image", "c.h5", "--method", "das", "--no-3d", "--out", "pics"], cwd)
    assert (cwd / "pics" / "fan.png").stat().st_size > 10_000
    spec = _run(
        [
            str(py),
            "-c",
            "from acousim.bundled import data_dir; "
            "print((data_dir('datasets') / 'corridor_small.toml').read_text())",
        ],
        cwd,
    )
    assert 'file = "../scenes/corridor.toml"' in spec


def test_the_wheel_is_marked_typed(installed):
    """PEP 561: each package carries its py.typed, so type checkers read its hints."""
    import zipfile

    names = set(zipfile.ZipFile(installed[3]).namelist())
    assert {f"{p}/py.typed" for p in ("processing", "acousim", "hardware")} <= names


def test_a_missing_scene_name_is_still_a_clear_error(tmp_path, capsys):
    assert main(["simulate", "no_such_scene", "--out", str(tmp_path / "x.h5")]) == 2
    assert "no_such_scene: no such file, nor a bundled scene" in capsys.readouterr().err


def test_reproduce_defaults_stay_out_of_docs(tmp_path, capsys):
    """The defaults write to ./reproduction, shown in --help; a --quick run refuses to
    overwrite the figures or the report of a full run."""
    args = build_parser().parse_args(["reproduce", "--quick"])
    assert args.out == "reproduction" and args.report is None
    full = tmp_path / "full"
    full.mkdir()
    (full / "study.json").write_text(json.dumps({"config": {"repetitions": 20}}))
    assert main(["reproduce", "--quick", "--out", str(full)]) == 2
    assert "holds the results of a full run" in capsys.readouterr().err
    report = tmp_path / "REPRODUCTION.md"
    committed = (ROOT / "docs" / "REPRODUCTION.md").read_text()
    report.write_text(committed)
    out = tmp_path / "quick"
    assert main(["reproduce", "--quick", "--out", str(out), "--report", str(report)]) == 2
    assert "--report" in capsys.readouterr().err
    assert report.read_text() == committed and not (out / "study.json").exists()


def test_names_of_bundled_files(tmp_path, monkeypatch):
    """A file the user has wins over a bundled one of the same name; a path with a
    folder is never looked up among the bundled files."""
    from acousim.bundled import data_dir, resolve, resolve_scene

    assert resolve_scene("wall") == data_dir("scenes") / "wall.toml"
    assert resolve_scene("wall.toml") == data_dir("scenes") / "wall.toml"
    assert resolve("datasets", "corridor_small") == data_dir("datasets") / "corridor_small.toml"
    monkeypatch.chdir(tmp_path)
    (tmp_path / "wall.toml").write_text("# the user's own")
    assert resolve_scene("wall.toml") == Path("wall.toml")
    with pytest.raises(InputError, match="sub/wall: no such file; a bundled scene has that"):
        resolve_scene("sub/wall")  # a folder: never looked up, but the name is suggested


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_makefile_checks_the_python_version(tmp_path):
    """`make` refuses a Python older than pyproject.toml's requires-python before it
    makes a venv with it (an interpreter that reports 3.9 is faked here)."""
    old = tmp_path / "python3.9"
    old.write_text(
        "#!/bin/sh\n"
        f"exec {sys.executable} -c \"import sys; sys.version_info = (3, 9, 18, 'final', 0); "
        'exec(sys.argv[1])" "$2"\n'
    )
    old.chmod(0o755)
    make = ["make", "-s", "-C", str(ROOT), "python-check"]
    proc = subprocess.run([*make, f"PYTHON={old}"], capture_output=True, text=True)
    assert proc.returncode != 0 and "acousim needs Python >= 3.11" in proc.stderr + proc.stdout
    assert "is 3.9" in proc.stderr + proc.stdout
    proc = subprocess.run([*make, f"PYTHON={sys.executable}"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert 'requires-python = ">=3.11"' in (ROOT / "pyproject.toml").read_text()


def test_scenes_lists_the_rest_when_one_cannot_load_here(monkeypatch, capsys, tmp_path):
    """Without network access (and an empty cache) the eRTIS layout cannot be fetched:
    `acousim scenes` says so for that scene and lists the others."""
    from processing.sensor import rtisdev

    def offline():
        raise RuntimeError("could not download rtisdev==2.15.1 with pip (exit 1): offline")

    monkeypatch.setenv("ACOUSIM_CACHE", str(tmp_path))
    monkeypatch.setattr(rtisdev, "wheel_path", offline)
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    sample = next(line for line in lines if line.startswith("ertis_sample.toml"))
    assert "could not download" in sample
    assert any(line.startswith("corridor.toml") and "urtis_v1" in line for line in lines)
