"""A new user's first hour: from an empty folder outside the checkout, every
``acousim`` line of the README's "What you can do with it" block runs as printed
(exit 0), then every Python block of README.md runs, in order, in that folder (the
files they read are the ones those commands wrote). Each page of docs/ runs on its
own, in a folder of its own: tests/system/test_docs.py.

One test, so that the commands run once even when the suite is spread over
processes (pytest-xdist): the blocks need the commands' files.  The commands run
with the venv's ``acousim`` script (``python -m acousim.cli`` where there is none),
importing the tree under test.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests import REPO

ROOT = REPO
DOCS = [ROOT / "README.md"]  # the pages of docs/, each on its own: tests/system/test_docs.py


def readme_commands() -> list[str]:
    """The ``acousim`` lines of the README's "What you can do with it" block, without
    their comments."""
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## What you can do with it") :]
    block = re.search(r"```sh\n(.*?)```", section, re.S).group(1)
    lines = [line.split("#", 1)[0].strip() for line in block.splitlines()]
    return [line for line in lines if line.startswith("acousim ")]


def python_blocks(path: Path) -> list[tuple[int, str]]:
    """(line number, code) of every ```python block of a Markdown file, in order."""
    text = path.read_text()
    return [
        (text[: m.start()].count("\n") + 2, m.group(1))
        for m in re.finditer(r"^```python\n(.*?)^```", text, re.S | re.M)
    ]


def _acousim() -> list[str]:
    script = shutil.which("acousim", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "acousim.cli"]


def test_readme_lists_the_commands_with_bundled_names_only():
    commands = readme_commands()
    assert len(commands) >= 9
    # nothing that needs the checkout: no scenes/ or datasets/ paths
    assert not [c for c in commands if "scenes/" in c or "datasets/" in c]


@pytest.mark.slow
def test_every_readme_command_then_its_python_block_runs_from_an_empty_folder(
    tmp_path, monkeypatch, capsys
):
    folder = tmp_path / "first_hour"
    folder.mkdir()
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    for line in readme_commands():
        argv = shlex.split(line)
        done = subprocess.run(
            [*_acousim(), *argv[1:]], cwd=folder, env=env, capture_output=True, text=True
        )
        assert done.returncode == 0, f"{line}\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    # what the commands wrote, as the docs read it
    for name in ("corridor.h5", "pictures/images.h5", "pictures/peaks.csv", "rec.h5"):
        assert (folder / name).is_file(), name
    assert (folder / "corridor_bag" / "metadata.yaml").is_file()
    assert (folder / "data" / "cs" / "manifest.json").is_file()
    # `record --emulate` wrote emulated recordings, not real ones
    import processing as P

    assert {r.provenance.kind for r in P.load_recordings(folder / "rec.h5")} == {"emulated"}
    monkeypatch.chdir(folder)
    ran = []
    for doc in DOCS:
        scope: dict = {"__name__": f"doc_{doc.stem}"}  # one namespace per document
        for line, code in python_blocks(doc):
            try:
                exec(compile(code, f"{doc.name}:{line}", "exec"), scope)
            except Exception as exc:
                raise AssertionError(f"{doc.relative_to(ROOT)} line {line}: {exc!r}") from exc
            ran.append(f"{doc.name}:{line}")
    assert len(ran) >= 1, ran  # README's "Processing in five lines"
    capsys.readouterr()
