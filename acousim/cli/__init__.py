"""The ``acousim`` command line: a thin layer that parses, calls the library, reports.

One module per command (``simulate``, ``image``, ...), each with ``register(sub)``,
which declares its arguments, and ``run(args)``: parse → call the library → report.
Shared helpers are in :mod:`acousim.cli.common`; options that set a declared setting
are generated from its declaration (:mod:`acousim.cli.options`).

Errors in what the user gave (a file, a key, a value) are
:class:`processing.errors.InputError`, caught once in :func:`main` and reported on one
line with exit code 2; every other exception is a bug and keeps its traceback.
Files are written under a temporary name and renamed when complete, so an error or
Ctrl-C leaves no partial output. Process-wide settings (the SIGINT handler) are made
here, at the entry point, never by a library object.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys

from processing.errors import InputError

from . import (
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
from .common import UsageError, on_interrupt, reset_interrupt
from .record import ARRAY_PRESETS, CALL_PRESETS, PDM_FILTERS

__all__ = ["main", "build_parser", "UsageError", "ARRAY_PRESETS", "CALL_PRESETS", "PDM_FILTERS"]

# in the order `acousim --help` lists them
COMMANDS = (demo, simulate, image, export, scenes, info, record, compare, dataset, reproduce)


def _headless_vtk() -> None:
    """Pictures are rendered off screen: without a display on Linux, let VTK start with
    its EGL window instead of trying X first and warning "bad X server connection" on
    every run (same pixels).  A VTK_DEFAULT_OPENGL_WINDOW the user set is kept."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command (light: no numpy or scipy is imported)."""
    from acousim.bundled import version

    parser = argparse.ArgumentParser(
        prog="acousim",
        description="Simulate active in-air ultrasonic 3D sonars and image their recordings.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse, run one command; an InputError is one line on stderr and exit code 2,
    Ctrl-C exit code 130, anything else a bug with its traceback."""
    _headless_vtk()  # before any command imports VTK
    parser = build_parser()
    args = parser.parse_args(argv)
    reset_interrupt()
    import threading

    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGINT, on_interrupt)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"acousim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"acousim {args.command}: interrupted; no partial file was kept", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
