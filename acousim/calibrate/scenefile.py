"""Writing a calibrated scene: the input file's text with only the fitted values
changed, each followed by its uncertainty in a comment.

The text is edited line by line, not re-serialised, so comments, order, spacing and
every other value stay as they were.  A fitted key's line (a value spanning several
lines, a multi-line table, included) becomes ``key = value  # fitted +- sigma
(acousim calibrate; was ...)``; a key the material did not give is added after its
``name``.  The result is checked before it is written: read back, it must equal the
input with only the fitted keys changed.  Written atomically
(:func:`processing.base.atomic.write_text`).
"""

from __future__ import annotations

import os
import re
import tomllib
from collections.abc import Collection, Sequence
from pathlib import Path

import numpy as np

from processing.base.atomic import write_text
from processing.base.errors import InputError

__all__ = ["write_scene", "edit_scene_text", "with_warnings", "WARNING_PREFIX"]

_HEADER = re.compile(r"^\s*\[\[?\s*([A-Za-z0-9_.\"' -]+?)\s*\]\]?\s*(#.*)?$")
_MATERIALS = re.compile(r"^\s*\[\[\s*materials\s*\]\]\s*(#.*)?$")
DIGITS = 4


def _fmt(v) -> str:
    if np.ndim(v):
        return "[" + ", ".join(_fmt(x) for x in np.ravel(v)) + "]"
    return f"{float(v):.{DIGITS}g}"


def _blocks(lines: list[str]) -> list[tuple[int, int]]:
    """(first line, end line) of every ``[[materials]]`` block, in file order."""
    out = []
    for i, line in enumerate(lines):
        if _MATERIALS.match(line):
            end = next((j for j in range(i + 1, len(lines)) if _HEADER.match(lines[j])), len(lines))
            out.append((i, end))
    return out


def _value_span(lines: list[str], start: int, end: int, key: str) -> tuple[int, int] | None:
    """Lines [a, b) holding `key = ...` inside a block (brackets counted over lines)."""
    pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
    for i in range(start + 1, end):
        if pattern.match(lines[i]):
            depth, j = 0, i
            while True:
                code = lines[j].split("#", 1)[0]
                depth += code.count("[") - code.count("]")
                if depth <= 0 or j + 1 >= end:
                    return i, j + 1
                j += 1
    return None


def _comment(lines: list[str], a: int, b: int) -> str:
    """The trailing comment of a value's last line ('' when none)."""
    parts = lines[b - 1].split("#", 1)
    return parts[1].strip() if len(parts) > 1 else ""


WARNING_PREFIX = "# acousim calibrate warning: "
#: in the comment of every value written (a fitted scene is known by it)
FITTED_MARK = "(acousim calibrate; "
#: what only a scene file acousim calibrate wrote holds (acousim.cli.ours)
FITTED_NOTES = (FITTED_MARK, WARNING_PREFIX)


def with_warnings(text: str, warnings: Sequence[str]) -> str:
    """`text` with a comment line ``# acousim calibrate warning: ...`` per warning at
    its top, those of an earlier calibration removed."""
    lines = [x for x in text.splitlines(keepends=True) if not x.startswith(WARNING_PREFIX)]
    return "".join([f"{WARNING_PREFIX}{w}\n" for w in warnings] + lines)


def edit_scene_text(
    text: str, values: dict[str, dict[str, tuple]], warned: Collection[str] = ()
) -> str:
    """`text` with `values` = {material: {key: (value, sigma or None)}} written into
    its ``[[materials]]`` blocks (the implicit ``default`` material, of the meshes
    that name none, gets a block of its own at the end); a ``material.key`` in
    `warned` has its comment say so.  Raises InputError naming a material the text
    does not define."""
    defined = [m.get("name") for m in tomllib.loads(text).get("materials", [])]
    if "default" in values and "default" not in defined:
        note = "meshes that name no material (block added by acousim calibrate)"
        text = text.rstrip("\n") + f'\n\n[[materials]]\nname = "default"  # {note}\n'
    lines = text.splitlines()
    parsed = tomllib.loads(text).get("materials", [])
    blocks = _blocks(lines)
    names = [m.get("name") for m in parsed]
    edits = []  # (a, b, new lines), applied from the bottom up
    for material, keys in values.items():
        if material not in names or len(blocks) != len(parsed):
            raise InputError(
                "no [[materials]] block of this name in the scene file: add one, or leave "
                "the material out of the fitted parameters",
                key="materials",
                value=material,
            )
        start, end = blocks[names.index(material)]
        name_line = _value_span(lines, start, end, "name")
        for key, (value, sigma) in keys.items():
            span = _value_span(lines, start, end, key)
            indent = re.match(r"^\s*", lines[span[0] if span else start]).group(0)
            note = "the fitted table's points" if sigma is None else f"fitted +- {_fmt(sigma)}"
            if f"{material}.{key}" in warned:
                note += " (warned: see the top of the file)"
            if span:
                old = " ".join(line.split("#", 1)[0].strip() for line in lines[slice(*span)])
                was = old.split("=", 1)[1].strip()
                extra = _comment(lines, *span)
                note += f" {FITTED_MARK}was {was})" + (f"; {extra}" if extra else "")
                edits.append((*span, [f"{indent}{key} = {_fmt(value)}  # {note}"]))
            else:
                at = name_line[1] if name_line else start + 1
                note += f" {FITTED_MARK}not given before)"
                edits.append((at, at, [f"{indent}{key} = {_fmt(value)}  # {note}"]))
    for a, b, new in sorted(edits, key=lambda e: (e[0], e[1]), reverse=True):
        lines[a:b] = new
    out = "\n".join(lines) + ("\n" if text.endswith("\n") else "")
    _check(text, out, values)
    return out


def _check(before: str, after: str, values: dict) -> None:
    """Read back, `after` equals `before` but for the fitted keys."""
    a, b = tomllib.loads(before), tomllib.loads(after)
    ma, mb = a.pop("materials", []), b.pop("materials", [])
    ok = a == b and len(ma) == len(mb)
    for x, y in zip(ma, mb):
        keys = values.get(x.get("name"), {})
        ok &= {k: v for k, v in x.items() if k not in keys} == {
            k: v for k, v in y.items() if k not in keys
        }
        for k, (v, _) in keys.items():
            ok &= np.allclose(np.ravel(y[k]), np.ravel(v), rtol=10 ** (1 - DIGITS), atol=0)
    if not ok:  # pragma: no cover - a bug in the editor, never the user's
        raise RuntimeError("the edited scene does not read back as intended")


def _relative_files(data, out_dir: Path, src_dir: Path) -> list[str]:
    """Relative ``file`` entries that do not resolve next to the output."""
    bad = []
    if isinstance(data, dict):
        for k, v in data.items():
            if k == "file" and isinstance(v, str) and not Path(v).is_absolute():
                if (src_dir / v).exists() and not (out_dir / v).exists():
                    bad.append(v)
            else:
                bad += _relative_files(v, out_dir, src_dir)
    elif isinstance(data, list):
        for v in data:
            bad += _relative_files(v, out_dir, src_dir)
    return bad


def _repointed(text: str, source: Path, out: Path) -> str:
    """`text` with each relative ``file = "..."`` that `out`'s folder does not hold
    pointed from there to the file beside `source` (a relative path; absolute where
    there is none), so that the fitted scene loads wherever it is written."""
    src_dir, out_dir = source.resolve().parent, out.resolve().parent
    for name in dict.fromkeys(_relative_files(tomllib.loads(text), out_dir, src_dir)):
        target = src_dir / name
        try:
            new = Path(os.path.relpath(target, out_dir)).as_posix()
        except ValueError:  # another drive
            new = target.as_posix()
        literal = '"' + new.replace("\\", "\\\\").replace('"', '\\"') + '"'
        pattern = r"(\bfile\s*=\s*)([\"'])" + re.escape(name) + r"\2"
        text = re.sub(pattern, lambda m, lit=literal: m.group(1) + lit, text)
    return text


def write_scene(source: str | Path, out: str | Path, calibration) -> Path:
    """Write the scene file `source` to `out` with the fitted materials of
    `calibration` (:class:`~.run.Calibration`) and its warnings as comments at the
    top (:func:`with_warnings`; a value a warning names says so in its comment); the
    files it names relative to its folder are pointed to from `out`'s folder
    (:func:`_repointed`)."""
    source, out = Path(source), Path(out)
    try:
        text = source.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read the scene: {exc.strerror}", file=source) from None
    text = _repointed(text, source, out)
    values = {}
    fitted = [p.name for p in calibration.parameters]
    for name, m in calibration.materials.items():
        s_r, s_d = calibration.material_sigma[name]
        keys = {
            key: (getattr(m, key), s)
            for key, s in (("reflection", s_r), ("diffuse", s_d))
            if any(p.split("@")[0] == f"{name}.{key}" for p in fitted)
        }
        if m.frequency_dependent:
            keys = {"frequencies_khz": (m.frequencies_khz, None), **keys}
        values[name] = keys
    warnings = calibration.warnings
    warned = {p.split("@")[0] for w in warnings for p in w.parameters}
    edited = edit_scene_text(text, values, warned)
    return write_text(out, with_warnings(edited, [w.message for w in warnings]))
