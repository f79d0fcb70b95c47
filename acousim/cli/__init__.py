"""The ``acousim`` command line: a thin layer that parses, calls the library, reports.

One module per command (``simulate``, ``image``, ...): its docstring is its help
(the first line in ``acousim --help``, the rest in ``acousim NAME --help``),
``register(sub)`` adds it (:func:`acousim.cli.common.add_command`) and declares its
arguments, and ``run(args)`` handles it: parse → call the library → report.
Shared helpers are in :mod:`acousim.cli.common`; options that set a declared setting
are generated from its declaration (:mod:`acousim.cli.options`).

Errors in what the user gave (a file, a key, a value) are
:class:`processing.base.errors.InputError`, caught once in :func:`main` and reported on one
line with exit code 2; every other exception is a bug and keeps its traceback.
Files are written under a temporary name and renamed when complete, so an error or
Ctrl-C leaves no partial output. Process-wide settings (the SIGINT handler) are made
here, at the entry point, never by a library object.
"""

from __future__ import annotations

# Light on purpose: nothing here imports numpy, scipy or h5py at import time. When
# this process is the acousim command, its Ctrl-C handler is installed first thing
# (below), before this package's other imports and main()'s: a Ctrl-C from then on
# is only recorded, then honoured as a later one (exit 130, one line), never a
# traceback of an import.  (Before it, the interpreter is still starting: its own.)
import sys

try:  # the C module signal wraps: imported at once (signal's own import takes ms)
    import _signal as _early_signal
except ImportError:  # pragma: no cover - an interpreter without it
    import signal as _early_signal

_early_interrupt = False


def _record_early(signum, frame) -> None:
    """SIGINT while the command imports what it needs: only remembered (never raised)."""
    global _early_interrupt
    _early_interrupt = True


def _is_the_command() -> bool:
    """Whether this process runs the ``acousim`` command (its console script, or
    ``python -m acousim.cli``): not a program that imports this package."""
    import os.path

    if os.path.splitext(os.path.basename(sys.argv[0] if sys.argv else ""))[0] == "acousim":
        return True
    args = iter(getattr(sys, "orig_argv", ())[1:])  # the interpreter's options first
    for a in args:
        if a in ("-m", "-macousim.cli"):
            return a == "-macousim.cli" or next(args, None) == "acousim.cli"
        if a in ("-X", "-W", "--check-hash-based-pycs"):
            next(args, None)  # its value
        elif not a.startswith("-") or a == "-c":
            return False  # a script or a command: the program's arguments follow
    return False


#: the SIGINT handler before the command's own (None: not installed at import)
_sigint_before = None
if _is_the_command():
    try:
        _sigint_before = _early_signal.signal(_early_signal.SIGINT, _record_early)
    except ValueError:  # not the main thread: main() decides
        pass
    else:
        import os

        if os.environ.get("ACOUSIM_PROGRESS_LINES", "") not in ("", "0"):
            print("acousim: loading", file=sys.stderr, flush=True)  # see common.PROGRESS_LINES

import os  # noqa: E402  (after the handler: the imports above are the command's first)
import signal  # noqa: E402
import threading  # noqa: E402

__all__ = [
    "main",
    "run",
    "build_parser",
    "UsageError",
    "ARRAY_PRESETS",
    "CALL_PRESETS",
    "PDM_FILTERS",
]

#: names this package offers, imported on first use (they import processing)
_LAZY = {
    "UsageError": "common",
    "ARRAY_PRESETS": "record",
    "CALL_PRESETS": "record",
    "PDM_FILTERS": "record",
}


def __getattr__(name: str) -> object:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _commands() -> tuple:
    """The command modules, in the order `acousim --help` lists them."""
    from acousim.cli import (
        calibrate,
        compare,
        dataset,
        demo,
        export,
        image,
        info,
        record,
        reproduce,
        scenes,
        simulate,
    )

    return (
        demo,
        simulate,
        image,
        export,
        scenes,
        info,
        record,
        compare,
        calibrate,
        dataset,
        reproduce,
    )


def _headless_vtk() -> None:
    """Pictures are rendered off screen: without a display on Linux, let VTK start with
    its EGL window instead of trying X first and warning "bad X server connection" on
    every run (same pixels).  A VTK_DEFAULT_OPENGL_WINDOW the user set is kept."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def build_parser():
    """The parser of every command (light: no numpy or scipy is imported)."""
    import argparse

    from acousim.bundled import version

    parser = argparse.ArgumentParser(
        prog="acousim",
        description="Simulate active in-air ultrasonic 3D sonars and image their recordings.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in _commands():
        command.register(sub)
    return parser


def main(argv: list[str] | None = None, *, restore_sigint: bool = True) -> int:
    """Parse, run one command; an InputError is one line on stderr and exit code 2,
    Ctrl-C exit code 130 with one line, anything else a bug with its traceback.

    Ctrl-C only sets a flag (:mod:`processing.base.interrupt`, installed here, the only
    place that changes the process's SIGINT handler but for the acousim command's own
    start, see :func:`_is_the_command`; restored on return unless `restore_sigint` is
    false); the work stops at its next checkpoint and no output file is replaced."""
    global _early_interrupt
    handled = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, _record_early) if handled else None  # first
    if previous is _record_early:  # installed as the command's process started
        previous = _sigint_before  # (a Ctrl-C since then stays recorded)
    else:
        _early_interrupt = False
    from acousim.cli import clock

    clock.start()  # the time a command reports counts from here, its imports included
    try:
        return _main(argv, handled)
    finally:
        if handled and previous is not None and restore_sigint:
            signal.signal(signal.SIGINT, previous)


def run() -> None:
    """The program's entry (the ``acousim`` command, ``python -m acousim.cli``): main()
    and its exit code; a Ctrl-C after the command has finished changes nothing."""
    try:
        code = main(restore_sigint=False)
    except BrokenPipeError:  # our output's reader has gone (`acousim ... | head -1`)
        code = _closed_output()
    finally:
        # done (or argparse's exit): a Ctrl-C now changes nothing. Ignored rather than
        # left to the flag handler, which the interpreter's finalisation resets to the
        # default (a Ctrl-C in those last milliseconds ended the process by the
        # signal, without a word)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    _exit(code)


#: the exit code of a command whose standard output was closed: 128 + SIGPIPE, what a
#: shell reports for a program ended by it (as `cat` or `find` are)
CLOSED_OUTPUT = 141


def _closed_output() -> int:
    """Stop as a Unix tool whose reader has gone: quietly (no traceback; stdout to
    /dev/null, so that the flush at exit writes nowhere), with
    :data:`CLOSED_OUTPUT`.  Files of ours being written are not renamed into place:
    the work stopped where it printed."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return CLOSED_OUTPUT


def _exit(code: int) -> None:
    """End the process with `code` as the interpreter would, less the teardown of
    every module and object (after ``acousim image``, about 0.3 s of freeing
    matplotlib's, numba's and the images' objects that nothing reads again).

    Only when this thread is the last: the exit handlers (:mod:`atexit`: h5py's,
    temporary folders' finalisers) run and the standard streams are flushed first,
    as at a normal exit; a stream that cannot be flushed (a closed pipe) takes the
    normal exit, which reports it.  Every file of ours is closed and renamed
    before the command returns."""
    run_exit_handlers = getattr(__import__("atexit"), "_run_exitfuncs", None)
    if threading.active_count() > 1 or run_exit_handlers is None:
        sys.exit(code)
    run_exit_handlers()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except OSError:
        sys.exit(code)
    os._exit(code)


def _main(argv: list[str] | None, handled: bool) -> int:
    from acousim.cli.common import announce, remove_made_dirs, set_quiet
    from processing.base import interrupt
    from processing.base.errors import InputError

    interrupt.reset()
    if handled:
        signal.signal(signal.SIGINT, interrupt.handler)
    if _early_interrupt:  # came while importing: now the same request
        interrupt.handler(signal.SIGINT, None)
    _headless_vtk()  # before any command imports VTK
    args = build_parser().parse_args(argv)
    announce(args.command)
    set_quiet(args.quiet)
    code = None
    try:
        interrupt.check()
        code = args.func(args)
        return code
    except InputError as exc:
        code = 2
        print(f"acousim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        code = 130
        # a command may say more (what it kept, how to resume): its `interrupted(args)`
        said = getattr(args, "interrupted", None)
        print(
            f"acousim {args.command}: interrupted; "
            + (said(args) if said else "no partial file was kept and no existing output replaced"),
            file=sys.stderr,
        )
        return 130
    finally:  # ended without its output: the empty folders it made go too
        remove_made_dirs(failed=code != 0)
