"""What every command shares: the usage error, argument types checked by the settings'
declarations, output paths, progress bars, the Ctrl-C checkpoint and scene loading."""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from pathlib import Path
from typing import Literal

from acousim.cli.clock import elapsed, from_start, now, since_start  # noqa: F401  (for the commands)
from processing.base.errors import InputError


class UsageError(InputError):
    """Bad input on the command line: printed on one line by main(), exit code 2."""


def checked(
    kind: str, lo: float = -math.inf, hi: float = math.inf, *, declared=None, scale: float = 1
):
    """An argparse type: the text as a number checked by a setting declaration
    (`declared()` returns a :class:`processing.base.settings.Setting`, imported lazily so
    that building the parser stays light), else a range given here; a number given in
    a unit `scale` times the declaration's (1e3: kHz for Hz) is converted first. For a
    pair or list setting (an ``interval``, a ``vector``: an option of several values)
    each value is one number checked against the declared range."""

    def parse(text: str):
        from processing.base.settings import Setting, check

        decl = declared() if declared else Setting(kind, lo=lo, hi=hi)
        if decl.kind in ("interval", "vector"):
            decl = Setting("float", lo=decl.lo, hi=decl.hi, unit=decl.unit)
        try:
            value = text if decl.kind == "str" else int(text) if decl.kind == "int" else float(text)
        except ValueError:
            what = "a whole number" if decl.kind == "int" else "a number"
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if scale != 1:
            value = value * scale
        try:
            return check(decl, value, "")
        except InputError as exc:
            raise argparse.ArgumentTypeError(f"{text!r}: {exc.reason}") from None

    parse.__name__ = kind
    return parse


def declared(module: str, cls: str, name: str):
    """A function returning the declaration of `module.cls.name` (imported when called)."""

    def get():
        import importlib

        from processing.base.settings import settings_of

        return settings_of(getattr(importlib.import_module(module), cls))[name]

    return get


class DeclaredHelp(argparse.HelpFormatter):
    """Formats an option added by :func:`add_declared` with its declaration's text."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        get = getattr(action, "declaration", None)
        if get is None:
            return action.help
        decl = _in_option_units(get(), getattr(action, "scale", 1))
        note = getattr(action, "note", "")
        return f"{decl.doc} ({decl.describe()}{'; ' + note if note else ''})".replace("%", "%%")


#: the unit prefix of an option whose value is its declaration's times this scale
_PREFIXES = {1e3: "k", 1e6: "M", 1e-3: "m"}


def _in_option_units(decl, scale: float):
    """The declaration `decl` as an option given in `scale` times its unit sees it
    (range, default and unit: a setting in Hz given in kHz shows [0.001, 1e+06] kHz,
    default 31.25)."""
    if scale == 1:
        return decl
    import dataclasses

    def scaled(x):
        return x / scale if isinstance(x, (int, float)) and not isinstance(x, bool) else x

    unit = _PREFIXES.get(scale, f"{scale:g} ") + decl.unit if decl.unit else decl.unit
    return dataclasses.replace(
        decl, lo=scaled(decl.lo), hi=scaled(decl.hi), default=scaled(decl.default), unit=unit
    )


def add_command(sub, doc: str, run) -> argparse.ArgumentParser:
    """Register the command a module's docstring declares and return its parser.

    The docstring's first paragraph, "``acousim NAME``: HELP.", gives the command's
    name and its line in ``acousim --help``; the paragraphs after it are the
    description of ``acousim NAME --help``; `run(args)` handles it. Options added by
    :func:`acousim.cli.options.add_declared` get their help from their declarations
    (:class:`DeclaredHelp`)."""
    head, _, body = doc.strip().partition("\n\n")
    name, _, summary = " ".join(head.split()).partition(": ")
    parser = sub.add_parser(
        name.strip("`").split()[-1],
        help=summary.rstrip("."),
        description=" ".join(body.split()),
        formatter_class=DeclaredHelp,
    )
    parser.set_defaults(func=run)
    parser.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="no progress bar or progress line on stderr (results, on stdout, and errors are "
        "still printed)",
    )
    return parser


SEED = checked("int", declared=declared("acousim.scene.model", "Simulation", "seed"))
INDEX = checked("int", 0, 2**31 - 1)


def add_seed(parser: argparse.ArgumentParser) -> None:
    """The --seed option of a command that simulates (the scene's seed by default)."""
    parser.add_argument("--seed", type=SEED, default=None, help="noise seed (default: the scene's)")


def with_quality(scene, quality: str | None):
    """`scene` under the `quality` preset (None: as it is)."""
    if quality is None:
        return scene
    return dataclasses.replace(scene, simulation=scene.simulation.with_quality(quality))


def methods(option: str, text: str) -> tuple[str, ...]:
    """Comma-separated DOA methods, each checked by :func:`processing.check_method`."""
    import processing as P

    names = tuple(m.strip() for m in text.split(",") if m.strip())
    if not names:
        raise UsageError("no method given", key=option, value=text)
    try:
        return tuple(P.check_method(m) for m in names)
    except InputError as exc:  # the bad name once, with a suggestion
        raise UsageError(exc.reason, key=option, value=exc.value) from None


def choice(what: str, options: tuple[str, ...]):
    """An argparse type: one of `options`, else an error naming the value once with
    the nearest option ("did you mean 'urtis_v1'?")."""

    def parse(text: str) -> str:
        from processing.base.errors import unknown_choice

        if text not in options:
            raise argparse.ArgumentTypeError(f"{text!r}: {unknown_choice(what, text, options)}")
        return text

    parse.__name__ = what
    return parse


#: the folders this command made (:func:`writable_dir`), the deepest first: removed,
#: when empty, if the command ends without its output (:func:`remove_made_dirs`)
_made_dirs: list[Path] = []


def writable_dir(path: str | Path) -> Path:
    """An output folder, made if needed with its missing parents (as ``mkdir -p``),
    that can be written (tried with a temporary file); else a UsageError.  The
    folders it made are removed again, if empty, when the command fails or is
    interrupted (:func:`remove_made_dirs`)."""
    import tempfile

    from processing.base.atomic import TEMP_PREFIX

    out = Path(path)
    missing = [p for p in (out, *out.parents) if not p.exists()]
    try:
        out.mkdir(parents=True, exist_ok=True)
        _made_dirs.extend(p for p in missing if p not in _made_dirs)
        with tempfile.NamedTemporaryFile(dir=out, prefix=TEMP_PREFIX):  # exclusive, removed
            pass
    except OSError as exc:
        raise UsageError(
            f"output directory {str(out)!r} cannot be written ({exc.strerror})"
        ) from None
    return out


def remove_made_dirs(*, failed: bool = True) -> list[Path]:
    """At a command's end: if it `failed` (an error or Ctrl-C: no output), remove the
    folders :func:`writable_dir` made that are still empty, the deepest first (a
    folder holding anything, kept shards or measurements, stays, and so do its
    parents); either way forget them.  Returns the folders removed."""
    removed = []
    deepest_first = sorted(_made_dirs, key=lambda p: len(p.absolute().parts), reverse=True)
    _made_dirs.clear()
    for folder in deepest_first if failed else ():
        try:
            folder.rmdir()  # only an empty folder
        except OSError:
            continue
        removed.append(folder)
    return removed


def replaceable(
    option: str, path: str | Path, kind: str, *, folder: str | Path | None = None
) -> Path:
    """The one rule for an output that exists already: it is replaced only when it
    is an output of `kind` acousim wrote (known by its content:
    :data:`acousim.cli.ours.KINDS`), as a rerun replaces its own; anything else (a
    user's file, a folder) is refused with a UsageError naming `option` (given the
    output `folder`, when `path` is a file in it) and the path, and nothing is
    touched.  Returns the path."""
    from acousim.cli.ours import KINDS, is_ours

    out = Path(path)
    if not out.exists() and not out.is_symlink():
        return out
    where = f"{option} {str(folder)!r}: {str(out)!r}" if folder else f"{option} {str(out)!r}"
    if out.is_dir() and folder is None:
        raise UsageError("is a folder; give a file name", key=option, value=str(path))
    if out.is_dir() or not is_ours(kind, out):
        raise UsageError(
            f"{where} exists already and is not {KINDS[kind].what} acousim wrote; it is "
            f"never overwritten: name another {'folder' if folder else 'file'} or remove it"
        )
    return out


def replaceable_in(option: str, folder: str | Path, files: dict[str, str]) -> None:
    """:func:`replaceable` for each file an output `folder` may hold: `files` maps
    each name (relative to the folder) to its kind.  The folder's other files are
    left as they are."""
    for name, kind in files.items():
        replaceable(option, Path(folder) / name, kind, folder=folder)


def output_file(option: str, path: str | Path, kind: str) -> Path:
    """An output file path: absent, or one of ours of `kind` (:func:`replaceable`);
    its folder made and writable (:func:`writable_dir`: made now, so that a bad
    folder is said before the work, and removed again if the command fails)."""
    out = replaceable(option, path, kind)
    writable_dir(out.parent)
    return out


def bundled_scenes() -> Path:
    """The bundled scenes' folder (installed package data, or the source tree's)."""
    from acousim.bundled import data_dir

    return data_dir("scenes")


def load_scene(path: str | Path):
    """A scene file, or a bundled scene's name."""
    from acousim.bundled import resolve_scene
    from acousim.scene import load_scene as load

    return load(resolve_scene(path))


def parse_indices(option: str, text: str | None) -> list[int] | None:
    """Indices '0,3,5' or ranges '0:10' (end excluded); None when not given."""
    if text is None:
        return None
    out: list[int] = []
    expected = "expected indices like '0,3,5' or a range '0:10'"
    for part in text.split(","):
        a, colon, b = part.partition(":")
        try:
            lo = int(a)
            hi = int(b) if colon else lo + 1
        except ValueError:
            raise UsageError(expected, key=option, value=text) from None
        if lo < 0 or hi <= lo:
            raise UsageError(
                f"{part!r} selects nothing or a negative index; {expected}", key=option, value=text
            )
        out.extend(range(lo, hi))
    return out


# --- Ctrl-C and progress ----------------------------------------------------------

PROGRESS_LINES = "ACOUSIM_PROGRESS_LINES"
"""Environment variable: set to 1, every command says on stderr (one flushed line
each) when its Ctrl-C handler is installed (``acousim: loading``, by the command's
first line of code: :mod:`acousim.cli`), when it has started and each step of its
progress, e.g. ``acousim simulate: simulate 3/16``; for logs and for tests that
must act at a known point of a run."""


def _lines() -> bool:
    import os

    return os.environ.get(PROGRESS_LINES, "") not in ("", "0")


_command = "acousim"


def announce(command: str) -> None:
    """'acousim COMMAND: started' on stderr, with ACOUSIM_PROGRESS_LINES set."""
    global _command
    _command = f"acousim {command}"
    if _lines():
        print(f"acousim {command}: started", file=sys.stderr, flush=True)


def stop_if_interrupted() -> None:
    """A checkpoint: raise KeyboardInterrupt if Ctrl-C came (see processing.base.interrupt)."""
    from processing.base import interrupt

    interrupt.check()


_quiet = False


def set_quiet(quiet: bool) -> None:
    """--quiet: no progress bar and no final progress line (results and errors stay)."""
    global _quiet
    _quiet = bool(quiet)


class Progress:
    """A progress callback ``(done, total)`` and a Ctrl-C checkpoint.

    On a terminal (stderr): a tqdm bar with the count, the rate and the time left,
    kept as one line when done. Elsewhere (a log, a pipe): one line on stderr when
    done (stdout keeps the results a script reads), e.g. ``simulate: 60/60 poses in
    7.8 s (7.69 poses/s)``. With --quiet: nothing. With ACOUSIM_PROGRESS_LINES set:
    a line per step on stderr instead.
    `total` None (an open-ended count): call :meth:`finish` at the end. With
    `checkpoint` false it never raises KeyboardInterrupt (a caller that stops on
    Ctrl-C in its own way).

    The time and the count run from `start`: "now" (made just before the work: its
    first call comes after the first step) or "first" (the first call, whose count
    is the baseline: a resumed dataset's finished shards, frames after the stills)."""

    def __init__(
        self,
        desc: str,
        unit: str = "it",
        *,
        checkpoint: bool = True,
        start: Literal["now", "first"] = "now",
    ) -> None:
        self.desc, self.unit, self.checkpoint = desc, unit, checkpoint
        self._bar = None
        self._t0: float | None = now() if start == "now" else None
        self._first = 0
        self._done = 0
        self._total: int | None = None
        self._finished = False
        self._called = False

    def __call__(self, done: int, total: int | None) -> None:
        if self.checkpoint:
            stop_if_interrupted()
        self._called = True
        if self._t0 is None:
            self._t0, self._first = now(), done
        self._done, self._total = done, total
        if _lines():
            of = "" if total is None else f"/{total}"
            print(f"{_command}: {self.desc} {done}{of}", file=sys.stderr, flush=True)
        elif not _quiet and sys.stderr.isatty():
            self._draw(done, total)
        if total is not None and done >= total:
            self.finish()

    def _draw(self, done: int, total: int | None) -> None:
        from tqdm import tqdm

        if self._bar is None:
            sized = _terminal_columns() > 0  # a terminal that says no size: 80 x 24
            self._bar = tqdm(
                total=total,
                initial=self._first,
                desc=self.desc,
                unit=self.unit,
                file=sys.stderr,
                dynamic_ncols=sized,
                ncols=None if sized else 80,
                nrows=None if sized else 24,  # (0 rows: tqdm draws no bar at all)
                leave=True,
                mininterval=0,  # every step drawn: steps are seconds apart
            )
            # the rate and the time from our start (tqdm's clock is time.time)
            self._bar.start_t = self._bar.last_print_t = time.time() - (now() - self._t0)
        if total != self._bar.total:
            self._bar.total = total
        self._bar.update(done - self._bar.n)

    def say(self, text: str) -> None:
        """A stage line on stderr, ``DESC: TEXT`` (a part of a long run done): above
        the bar on a terminal, else a line of its own (with ACOUSIM_PROGRESS_LINES
        too, after the command's name); nothing with --quiet."""
        if _lines():
            print(f"{_command}: {self.desc}: {text}", file=sys.stderr, flush=True)
        elif _quiet:
            return
        elif self._bar is not None:
            self._bar.write(f"{self.desc}: {text}", file=sys.stderr)
        else:
            print(f"{self.desc}: {text}", file=sys.stderr, flush=True)

    def note(self, text: str) -> None:
        """What is running now, shown after the bar on a terminal."""
        if self._bar is not None:
            self._bar.set_postfix_str(text)

    def finish(self) -> None:
        """The end: the bar closed on a terminal, else the one final line."""
        if self._finished or not self._called:
            return
        self._finished = True
        if self._bar is not None:
            self._bar.close()
            return
        if _quiet or _lines() or sys.stderr.isatty():
            return
        print(self.summary(now() - self._t0), file=sys.stderr, flush=True)

    def summary(self, seconds: float) -> str:
        """``DESC: DONE/TOTAL UNITs in S s (RATE UNITs/s)``: the final line."""
        made = self._done - self._first
        of = "" if self._total is None else f"/{self._total}"
        rate = f"{made / seconds:.3g} {self.unit}s/s" if seconds > 0 and made else "-"
        return f"{self.desc}: {self._done}{of} {self.unit}s in {seconds:.1f} s ({rate})"


def _terminal_columns() -> int:
    """The columns of the terminal on stderr (0: it says none, or it is not one)."""
    try:
        return os.get_terminal_size(sys.stderr.fileno()).columns
    except (OSError, ValueError):
        return 0


def progress(
    desc: str,
    unit: str = "it",
    *,
    checkpoint: bool = True,
    start: Literal["now", "first"] = "now",
) -> Progress:
    """A :class:`Progress` for `desc` counting `unit`s."""
    return Progress(desc, unit, checkpoint=checkpoint, start=start)


def preload_simulation() -> None:
    """Import what a simulation needs before its work starts and set the process's
    policy (:func:`acousim.process.configure`); Ctrl-C meanwhile is only recorded (see
    processing.base.interrupt: an import that catches BaseException, as trimesh's optional
    ones do, cannot swallow it), then honoured."""
    import trimesh  # noqa: F401

    import acousim.simulator  # noqa: F401
    from acousim.process import configure

    configure()  # a simulating process's policy: BLAS threads, the allocator
    stop_if_interrupted()


def simulate(scene, poses, seed, quality: str | None = None):
    """The recordings of `scene` at `poses` (None: all), with `seed` and the `quality`
    preset if given; a UsageError when no echo reaches the sensor."""
    from acousim.simulator import Simulator

    scene = with_quality(scene, quality)
    if seed is not None:
        scene = dataclasses.replace(
            scene, simulation=dataclasses.replace(scene.simulation, seed=seed)
        )
    if scene.rig is not None:  # a recording per firing of every sonar, in time order
        from acousim.rig import RigSimulator

        run = RigSimulator(scene).run(poses, progress=progress("simulate", "firing"))
        recs = list(run.recordings)
    else:
        recs = Simulator(scene).run(poses, progress=progress("simulate", "pose"))
    for r in recs:
        prov = r.provenance
        if not prov.n_paths:
            raise UsageError(
                f"scene {scene.name!r}: no echo reaches the sensor at pose "
                f"{prov.pose_index} (nothing within "
                f"{scene.simulation.max_range_m} m)"
            )
    return recs
