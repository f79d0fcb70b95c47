"""Every page of docs/ runs on its own, as a reader who opens only that page runs it:
in an empty folder, its code blocks top to bottom, the ``acousim`` lines of its
shell blocks as commands and its Python blocks in one fresh namespace, so that a
block uses only what the page imported and made before it. (README.md's commands
and Python block: tests/system/test_first_hour.py, from an empty folder too.)

Lines a test machine cannot run (a real sensor, a remote cluster, a file that stands
for the reader's own recording) are listed in SKIP with the reason. Running the pages
is slow (minutes: they simulate and image the corridor); a quick check reads every
page's Python blocks, README's included, in order as one program and fails on a name
used before the page imported or defined it (ruff's F821)."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tests import REPO

ROOT = REPO
DOCS = sorted((ROOT / "docs").glob("*.md"))

#: (page, the start of a line) that is not run here, and why
SKIP = {
    ("compare.md", "acousim calibrate run.h5"): "run.h5 and room.toml stand for the reader's",
    ("dataset-format.md", "acousim dataset my_spec.toml"): "a Dask scheduler at tcp://host",
    ("hardware.md", "acousim record --count"): "needs a real sensor on USB",
    ("hardware.md", "acousim record --device"): "needs a real sensor on USB",
}


def blocks(path: Path) -> list[tuple[int, str, str]]:
    """(line number, language, code) of every fenced block of a Markdown page, in
    order."""
    text = path.read_text()
    return [
        (text[: m.start()].count("\n") + 2, m.group(1), m.group(2))
        for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, re.S | re.M)
    ]


def commands(path: Path, code: str) -> list[str]:
    """The ``acousim`` lines of a shell block (comments and continuations joined),
    without those SKIP lists."""
    joined = code.replace("\\\n", " ")
    lines = [line.split("#", 1)[0].strip() for line in joined.splitlines()]
    return [
        line
        for line in lines
        if line.startswith("acousim ")
        and not any(page == path.name and line.startswith(s) for page, s in SKIP)
    ]


def _acousim() -> list[str]:
    import shutil

    script = shutil.which("acousim", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "acousim.cli"]


def _pages():
    for path in DOCS:
        if any(lang in ("python", "sh") for _, lang, _ in blocks(path)):
            yield pytest.param(path, id=path.name)


WITH_PYTHON = [p for p in (ROOT / "README.md", *DOCS) if "```python" in p.read_text()]


@pytest.mark.parametrize("path", WITH_PYTHON, ids=lambda p: p.name)
def test_a_page_uses_no_name_before_it_imports_or_makes_it(path, tmp_path):
    code = [c for _, lang, c in blocks(path) if lang == "python"]
    program = tmp_path / f"{path.stem}.py"
    program.write_text("\n".join(code))
    done = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--isolated", "--select", "F821", str(program)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, f"{path.name}: {done.stdout}"


def test_skipped_lines_are_on_their_pages():
    """Each SKIP entry still names a line of its page (no stale exception)."""
    for page, start in SKIP:
        text = (ROOT / "docs" / page).read_text().replace("\\\n", " ")
        assert re.search(rf"^{re.escape(start)}", text, re.M), (page, start)


@pytest.mark.slow
@pytest.mark.parametrize("path", list(_pages()))
def test_a_page_runs_on_its_own(path, tmp_path, monkeypatch, capsys):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env.pop("ACOUSIM_PROGRESS_LINES", None)
    monkeypatch.chdir(tmp_path)
    scope: dict = {"__name__": f"doc_{path.stem}"}  # what the page made so far
    for line, lang, code in blocks(path):
        where = f"{path.relative_to(ROOT)} line {line}"
        if lang == "sh":
            for command in commands(path, code):
                done = subprocess.run(
                    [*_acousim(), *shlex.split(command)[1:], "--quiet"],
                    cwd=tmp_path,
                    env=env,
                    capture_output=True,
                    text=True,
                )
                assert done.returncode == 0, f"{where}: {command}\n{done.stderr[-3000:]}"
        elif lang == "python":
            try:
                exec(compile(code, where, "exec"), scope)
            except Exception as exc:
                raise AssertionError(f"{where}: {exc!r}") from exc
    capsys.readouterr()
