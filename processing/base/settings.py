"""One declaration per setting: type, unit, default, allowed range and meaning.

A setting is declared once, as a dataclass field, and that declaration validates
every way in: the Python constructor (``__post_init__`` calls :func:`validate`), a
TOML table (:func:`read_table`, with did-you-mean for unknown keys) and the command
line (:func:`check` on one argument). Every refusal is a
:class:`processing.base.errors.InputError` naming the file, the key and the value.

Adding a setting is one line in the dataclass that holds it::

    @dataclass(frozen=True)
    class Environment:
        temperature_c: float = setting(20.0, "degC", -20, 50, "air temperature")
        wind_m_s: float = setting(0.0, "m/s", 0, 30, "wind speed")      # <- the new line

    def __post_init__(self) -> None:
        validate(self)

The TOML loader then accepts ``[environment] wind_m_s = 3`` and refuses ``-1``,
``"fast"`` or ``nan`` with the file, key and value, and so does ``Environment(wind_m_s=-1)``.
Kinds: ``float`` and ``int`` (ranges inclusive; NaN always refused, infinity only when
a bound is infinite), ``bool`` (only true/false), ``str`` (optionally one of
`choices`), ``strings`` (a list of such strings), ``vector`` (`length` finite
numbers in range; any length when `length` is None, e.g. a reflection coefficient
per frequency band: ``setting((0.9, 0.8), "", 0, 1, "per band", kind="vector")``),
``scalar_or_vector`` (a number, or a list of numbers, each in range: a material's
reflection, constant or a table over frequency) and ``interval`` (a ``[low, high]``
pair of finite numbers inside the range, low <= high).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from processing.base.errors import InputError, did_you_mean

__all__ = [
    "Kind",
    "Setting",
    "setting",
    "check",
    "validate",
    "read_table",
    "refuse_unknown",
    "settings_of",
]

Kind = Literal["float", "int", "bool", "str", "strings", "vector", "scalar_or_vector", "interval"]
_KINDS = get_args(Kind)


@dataclass(frozen=True)
class Setting:
    """The declaration of one setting.

    default : the value when none is given (``dataclasses.MISSING``: required).
    optional : None is accepted as "not set" (:func:`setting` with a None default).
    unit : SI unit, or a file-boundary unit in the name (``deg``), "" when unitless.
    lo, hi : allowed range, inclusive (numbers, and every element of a vector).
    choices : allowed strings (``str`` kind).
    length : number of elements (``vector`` kind).
    """

    kind: Kind
    default: Any = None
    unit: str = ""
    lo: float = -math.inf
    hi: float = math.inf
    doc: str = ""
    choices: tuple[str, ...] | None = None
    length: int | None = None
    optional: bool = False

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise TypeError(f"setting kind {self.kind!r} is not one of {_KINDS}")

    def describe(self) -> str:
        """One line for docs and ``--help``: kind, unit, range, default."""
        parts: list[str] = [self.kind]
        if self.unit:
            parts.append(self.unit)
        if self.choices:
            parts.append("one of " + ", ".join(self.choices))
        elif self.kind in ("float", "int", "vector", "scalar_or_vector", "interval"):
            parts.append(f"[{_fmt(self.lo)}, {_fmt(self.hi)}]")
        if self.default not in (None, dataclasses.MISSING):
            parts.append(f"default {self.default!r}")
        elif self.optional:
            parts.append("default unset")
        return ", ".join(parts)


def _fmt(x: float) -> str:
    if isinstance(x, int):
        return str(x)
    return "inf" if x == math.inf else "-inf" if x == -math.inf else f"{x:g}"


def setting(
    default: Any = dataclasses.MISSING,
    unit: str = "",
    lo: float = -math.inf,
    hi: float = math.inf,
    doc: str = "",
    *,
    kind: Kind | None = None,
    choices: Iterable[str] | None = None,
    length: int | None = None,
) -> Any:
    """A dataclass field carrying its :class:`Setting`; the kind follows the default's
    type unless given (an int default with a fractional range: pass ``kind="float"``)."""
    if kind is None:
        kind = (
            "bool"
            if isinstance(default, bool)
            else "int"
            if isinstance(default, int)
            else "float"
            if isinstance(default, float)
            else "str"
            if isinstance(default, str)
            else "vector"
        )
    decl = Setting(
        kind,
        default,
        unit,
        lo,  # kept as given: an int bound compares exactly with an int value
        hi,
        doc,
        None if choices is None else tuple(choices),
        length,
        optional=default is None,
    )
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata={"setting": decl})
    return dataclasses.field(default=default, metadata={"setting": decl})


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) or _is_np_number(v)


def _is_np_number(v: Any) -> bool:
    return isinstance(v, np.integer | np.floating)


def check(decl: Setting, value: Any, key: str, file: str | Path | None = None) -> Any:
    """The value, normalised (int, float, bool, str, tuple), or an InputError naming
    `file`, `key` and `value`."""

    def fail(msg: str) -> InputError:
        return InputError(msg, file=file, key=key, value=value)

    rng = f"[{_fmt(decl.lo)}, {_fmt(decl.hi)}]"
    if value is None and decl.optional:  # an optional setting left unset
        return None
    if decl.kind == "bool":
        if isinstance(value, bool | np.bool_):
            return bool(value)
        raise fail("must be true or false")
    if decl.kind == "str":
        if not isinstance(value, str):
            raise fail("must be a string")
        _one_of(decl, value, fail, "")
        return value
    if decl.kind in ("float", "int"):
        return _scalar(decl, value, fail, rng)
    if decl.kind == "scalar_or_vector":
        if _is_number(value):
            return _scalar(
                Setting("float", lo=decl.lo, hi=decl.hi, unit=decl.unit), value, fail, rng
            )
        try:
            return check(Setting("vector", lo=decl.lo, hi=decl.hi), value, key, file)
        except InputError:
            raise fail(f"must be a number or a list of numbers in {rng}") from None
    if decl.kind == "strings":
        if isinstance(value, str) or not isinstance(value, Iterable):
            raise fail("must be a list of strings")
        out = tuple(value)
        for v in out:
            if not isinstance(v, str):
                raise fail("must be a list of strings")
            _one_of(decl, v, fail, f"{v!r} ")
        return out
    return _numbers(decl, value, fail, rng)  # vector or interval


def _one_of(decl: Setting, value: str, fail, what: str) -> None:
    """Raise `fail` ("`what`is not one of ..."; did you mean ...) unless `value` is one
    of the declared choices (any string where none are declared)."""
    if decl.choices is not None and value not in decl.choices:
        close = did_you_mean(value, decl.choices)
        hint = f"; did you mean {close!r}?" if close else ""
        raise fail(f"{what}is not one of {', '.join(decl.choices)}{hint}")


def _numbers(decl: Setting, value: Any, fail, rng: str) -> tuple[float, ...]:
    """A ``vector`` or ``interval`` setting's value checked: a tuple of floats."""
    try:
        items = None if isinstance(value, str | bytes | Mapping) else list(value)
    except TypeError:
        items = None
    n = 2 if decl.kind == "interval" else decl.length
    if decl.kind == "interval":
        what = "[low, high]"
    else:
        what = "a list of finite numbers" if n is None else f"a list of {n} finite numbers"
    if math.isfinite(decl.lo) or math.isfinite(decl.hi):
        what += f" in {rng}"
    if items is None or (n is not None and len(items) != n):
        raise fail(f"must be {what}")
    if not all(_is_number(x) for x in items):
        raise fail(f"must be {what}")
    out = tuple(float(x) for x in items)
    if any(not math.isfinite(x) or not decl.lo <= x <= decl.hi for x in out):
        raise fail(f"must be {what}")
    if decl.kind == "interval" and out[0] > out[1]:
        raise fail("low is above high")
    return out


def _scalar(decl: Setting, value: Any, fail, rng: str) -> float | int:
    integer = decl.kind == "int"
    kind = "a whole number" if integer else "a number"
    if not _is_number(value):
        raise fail(f"must be {kind} in {rng}")
    try:
        v = float(value)
    except OverflowError:  # an int beyond any float
        raise fail(f"outside the allowed range {rng}") from None
    if math.isnan(v):
        raise fail(f"must be {kind} in {rng}, not NaN")
    if integer and not v.is_integer():
        raise fail(f"must be {kind} in {rng}")
    exact = int(value) if integer else v  # 2**63 is not float(2**63 - 1)
    if not decl.lo <= exact <= decl.hi:
        unit = f" {decl.unit}" if decl.unit else ""
        raise fail(f"outside the allowed range {rng}{unit}")
    return int(value) if integer else v


def settings_of(cls: type) -> dict[str, Setting]:
    """The declared settings of a dataclass (type or instance), by field name."""
    return {
        f.name: f.metadata["setting"] for f in dataclasses.fields(cls) if "setting" in f.metadata
    }


def validate(obj: Any, *, file: str | Path | None = None, prefix: str | None = None) -> None:
    """Check every declared setting of a (frozen) dataclass instance and store the
    normalised values; call it from ``__post_init__``. Keys read ``Class.field``."""
    where = type(obj).__name__ if prefix is None else prefix
    for name, decl in settings_of(obj).items():
        value = check(decl, getattr(obj, name), f"{where}.{name}", file)
        object.__setattr__(obj, name, value)


def read_table(
    cls: type,
    table: Any,
    *,
    where: str,
    file: str | Path | None = None,
    extra: Iterable[str] = (),
) -> dict[str, Any]:
    """The declared settings of `cls` found in a TOML `table`, checked and normalised
    (a dict for ``cls(**...)``). Keys that are neither declared nor in `extra` (keys
    the caller reads itself) are refused with a did-you-mean."""
    if not isinstance(table, Mapping):
        raise InputError("must be a table", file=file, key=where or "<file>", value=table)
    decls = settings_of(cls)
    refuse_unknown(table, [*decls, *extra], where=where, file=file)
    return {
        name: check(decl, table[name], f"{where}.{name}" if where else name, file)
        for name, decl in decls.items()
        if name in table
    }


def refuse_unknown(
    table: Mapping, allowed: Iterable[str], *, where: str, file: str | Path | None = None
) -> None:
    """An InputError with a did-you-mean for the first key of `table` not in `allowed`."""
    allowed = sorted(set(allowed))
    for k in table:
        if k not in allowed:
            close = did_you_mean(str(k), allowed)
            hint = f"; did you mean {close!r}?" if close else ""
            listed = f"allowed: {', '.join(allowed)}" if allowed else "it takes none"
            raise InputError(
                f"unknown key {k!r}{hint} ({listed})",
                file=file,
                key=f"{where}.{k}" if where else str(k),
            )
