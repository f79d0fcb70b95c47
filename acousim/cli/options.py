"""Command-line options generated from the settings' declarations.

An option's type, range, unit, default and help come from the dataclass field that
declares the setting (:mod:`processing.base.settings`), so the command line, the Python
constructor and the files accept and refuse the same values. The declaration is
imported only when an argument is parsed or ``--help`` is printed: building the
parser stays light (no numpy, no scipy), so Ctrl-C and ``--version`` answer at once.
"""

from __future__ import annotations

import argparse

from acousim.cli.common import DeclaredHelp, checked, declared

__all__ = ["DeclaredHelp", "add_declared", "add_quality"]


def add_declared(
    parser: argparse.ArgumentParser,
    flag: str,
    where: str,
    name: str,
    *,
    note: str = "",
    scale: float = 1,
    **more: object,
) -> argparse.Action:
    """Add `flag` for the setting `name` of the dataclass `where` ("module:Class"):
    parsed and checked by its declaration. It defaults to None (not given), so the
    declared default applies where the value is used: one home for each default.
    `scale`: the option's unit in the declaration's (1e3: kHz for a setting in Hz; say
    so in the `note`); `more`: add_argument's other keywords (``nargs=2`` and a
    ``metavar`` for an interval: each value checked against the declared range)."""
    module, cls = where.split(":")
    get = declared(module, cls, name)
    # the help text is made by DeclaredHelp from the declaration, when asked for
    parse = checked("number", declared=get, scale=scale)
    action = parser.add_argument(flag, type=parse, help="-", **more)
    action.declaration, action.note, action.scale = get, note, scale
    return action


def add_quality(parser: argparse.ArgumentParser, *, note: str = "") -> None:
    """The --quality option of a command that simulates: the scene's
    ``simulation.quality`` replaced (its explicitly given settings still apply);
    `note`: what not giving it means, when not the scene file's preset."""
    add_declared(
        parser,
        "--quality",
        "acousim.scene.model:Simulation",
        "quality",
        note=note
        or "not given: the scene file's; the file's explicit [simulation] settings apply "
        "whatever the preset",
    )
