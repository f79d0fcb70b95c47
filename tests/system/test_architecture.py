"""The code's shape, checked over its text and imports (ast): function sizes,
parameter counts, import cycles and the direction of imports (docs/architecture.md).
A module's length is not checked: a module holds one concept, whatever its length
(the long ones are listed when run as a script).

Run as a script for the full report: ``python -m tests.system.test_architecture``.
"""

from __future__ import annotations

import ast
import sys
from functools import lru_cache
from pathlib import Path

from tests import REPO

ROOT = REPO
PACKAGES = ("acousim", "processing", "hardware")

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60
#: functions over MAX_FUNCTION_LINES allowed in all
MAX_LONG_FUNCTIONS = 10
MAX_PARAMETERS = 8

#: (importing package, imported package): never
FORBIDDEN = (
    ("acousim.synth", "acousim.trace"),
    ("acousim.synth", "acousim.scene"),
    ("acousim.trace", "acousim.synth"),
    ("acousim.trace", "acousim.kinematics"),
    ("acousim.kinematics", "acousim.synth"),
    ("acousim.core", "acousim.scene"),
    ("acousim.core", "acousim.trace"),
    ("acousim.core", "acousim.kinematics"),
    ("acousim.core", "acousim.synth"),
    ("acousim.scene", "acousim.trace"),
    ("acousim.scene", "acousim.kinematics"),
    ("acousim.scene", "acousim.synth"),
    ("processing.base", "processing.sensor"),
    ("processing.base", "processing.formats"),
    ("processing.base", "processing.imaging"),
    ("processing.sensor", "processing.formats"),
    ("processing.sensor", "processing.imaging"),
    ("processing.formats", "processing.imaging"),
    ("acousim.trace.world", "acousim.trace.rays"),
    ("acousim.trace.world", "acousim.trace.diffraction"),
    ("acousim.trace.world", "acousim.trace.motion"),
    ("acousim.trace.rays", "acousim.trace.diffraction"),
    ("acousim.trace.rays", "acousim.trace.motion"),
    ("acousim.trace.diffraction", "acousim.trace.motion"),
    ("processing", "acousim"),
    ("processing", "hardware"),
    ("hardware", "acousim"),
)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


@lru_cache(maxsize=1)
def modules() -> dict[str, tuple[Path, ast.Module]]:
    """Every module of the packages: name -> (path, syntax tree)."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            out[_module_name(path)] = (path, ast.parse(path.read_text(), str(path)))
    return out


def _is_package(name: str) -> bool:
    path, _ = modules()[name]
    return path.name == "__init__.py"


def _resolve(importer: str, node: ast.ImportFrom) -> str:
    """The absolute module an ImportFrom names (before its imported names)."""
    if not node.level:
        return node.module or ""
    base = importer.split(".")
    if not _is_package(importer):
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(name: str) -> set[str]:
    """The project modules `name` imports anywhere in its text (function bodies too),
    with the packages whose ``__init__`` such an import runs (those not enclosing
    the importer)."""
    _, tree = modules()[name]
    known = modules()
    found: set[str] = set()
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            mod = _resolve(name, node)
            targets = [mod]
            targets += [f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in known]
        for target in targets:
            parts = target.split(".")
            for k in range(1, len(parts) + 1):
                prefix = ".".join(parts[:k])
                if prefix not in known or prefix == name:
                    continue
                # a package enclosing the importer is initialised already
                if name.startswith(prefix + "."):
                    continue
                found.add(prefix)
    return found


def long_modules() -> list[str]:
    out = []
    for path, _ in modules().values():
        n = len(path.read_text().splitlines())
        if n > MAX_MODULE_LINES:
            out.append(f"{path.relative_to(ROOT)}: {n} lines")
    return out


def _functions():
    for path, tree in modules().values():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield path, node


def _compiled(path: Path, node) -> bool:
    """A compiled kernel: a numba-decorated function or a module of kernels."""
    if "kernel" in path.name:
        return True
    for d in node.decorator_list:
        text = ast.unparse(d)
        if "njit" in text or "jit" in text.split("(")[0]:
            return True
    return False


def long_functions() -> list[str]:
    out = []
    for path, node in _functions():
        n = node.end_lineno - node.lineno + 1
        if n > MAX_FUNCTION_LINES:
            out.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {n} lines")
    return out


def wide_functions() -> list[str]:
    out = []
    for path, node in _functions():
        if _compiled(path, node):
            continue
        a = node.args
        names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
        names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
        names = [n for n in names if n not in ("self", "cls")]
        if len(names) > MAX_PARAMETERS:
            out.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {len(names)}")
    return out


def cycles() -> list[list[str]]:
    """Strongly connected components of the import graph with more than one module."""
    graph = {m: sorted(imports(m)) for m in modules()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10000))

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def _inside(name: str, pkg: str) -> bool:
    return name == pkg or name.startswith(pkg + ".")


def layering() -> list[str]:
    out = []
    for name in modules():
        found = imports(name)
        # the deepest modules only (not the packages on the way to them)
        deepest = {t for t in found if not any(u.startswith(t + ".") for u in found)}
        for target in sorted(deepest):
            for a, b in FORBIDDEN:
                if _inside(name, a) and _inside(target, b):
                    out.append(f"{name} imports {target} ({a} must not import {b})")
    return out


def test_few_long_functions():
    found = long_functions()
    assert len(found) <= MAX_LONG_FUNCTIONS, "\n".join(found)


def test_few_parameters():
    assert wide_functions() == []


def test_no_import_cycle():
    assert cycles() == []


def test_layering():
    assert layering() == []


def test_checker_sees_a_cycle_and_a_wrong_import(tmp_path, monkeypatch):
    """The checker itself, on a made-up tree: a cycle through a package's
    ``__init__`` and an import against the layering are found."""
    pkg = tmp_path / "acousim"
    (pkg / "synth").mkdir(parents=True)
    (pkg / "trace").mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "synth" / "__init__.py").write_text("from .a import x\n")
    (pkg / "synth" / "a.py").write_text("x = 1\ndef f():\n    from acousim.trace.b import y\n")
    (pkg / "trace" / "__init__.py").write_text("")
    (pkg / "trace" / "b.py").write_text("from acousim.synth import x\ny = 2\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    monkeypatch.setattr(sys.modules[__name__], "PACKAGES", ("acousim",))
    modules.cache_clear()
    try:
        assert imports("acousim.trace.b") == {"acousim.synth"}
        assert imports("acousim.synth.a") == {"acousim.trace", "acousim.trace.b"}
        assert cycles() == [["acousim.synth", "acousim.synth.a", "acousim.trace.b"]]
        assert layering() == [
            "acousim.synth.a imports acousim.trace.b (acousim.synth must not import acousim.trace)",
            "acousim.trace.b imports acousim.synth (acousim.trace must not import acousim.synth)",
        ]
    finally:
        modules.cache_clear()


if __name__ == "__main__":
    for title, found in (
        ("modules over 600 lines (listed, not a failure)", long_modules()),
        (f"functions over 60 lines (at most {MAX_LONG_FUNCTIONS})", long_functions()),
        ("functions with more than 8 parameters", wide_functions()),
        ("import cycles", [" <-> ".join(c) for c in cycles()]),
        ("imports against the layering", layering()),
    ):
        print(f"## {title}: {len(found)}")
        for line in found:
            print("  ", line)
