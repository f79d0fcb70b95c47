"""The public API's two promises, kept in one place for every package.

* A misspelled keyword of a public constructor or function gets the scene file's
  answer, not a plain ``TypeError``: the key named, a did-you-mean and the allowed
  keys (:func:`processing.base.settings.refuse_unknown`, the loader's own check), raised
  as a :class:`KeywordError` (an :class:`~processing.base.errors.InputError` and a
  ``TypeError``). Each package applies :func:`check_keywords` to the names of its
  ``__all__`` once, in its ``__init__`` (functions, and classes' constructors and
  public methods).
* A keyword that moved into an options object keeps working for one version with a
  ``DeprecationWarning`` (:func:`folded_keywords`); CHANGELOG.md says since when.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import sys
import types
import warnings
from collections.abc import Callable, Iterable, MutableMapping
from typing import Any, TypeVar

from processing.base.errors import InputError
from processing.base.settings import refuse_unknown

__all__ = ["KeywordError", "check_keywords", "checked", "folded_keywords", "warn_deprecated"]

F = TypeVar("F", bound=Callable[..., Any])

_MARK = "__keywords_checked__"
_DEPRECATED = "__deprecated_keywords__"
_NAMED = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)


class KeywordError(InputError, TypeError):
    """A keyword a public constructor or function does not take: the message names it,
    the closest allowed keyword and every allowed one (no units: a name)."""


def _allowed(fn: Callable[..., Any]) -> set[str] | None:
    """The keywords `fn` takes (with the deprecated ones it still accepts), None when it
    takes any (``**kwargs``) or has no signature."""
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params):
        return None
    names = {p.name for p in params if p.kind in _NAMED} - {"self", "cls"}
    return names | set(getattr(fn, _DEPRECATED, ()))


def checked(fn: F, where: str) -> F:
    """`fn` refusing an unknown keyword with a :class:`KeywordError` keyed ``where.key``
    (itself when it takes any keyword or is already checked)."""
    allowed = _allowed(fn)
    if allowed is None or getattr(fn, _MARK, False):
        return fn
    # (a private field, such as one dataclasses.replace passes on, is taken, not shown)
    shown = sorted(k for k in allowed - set(getattr(fn, _DEPRECATED, ())) if k[0] != "_")

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        for k in kwargs:
            if k not in allowed:
                try:
                    refuse_unknown({k: None}, shown, where=where)
                except InputError as exc:
                    raise KeywordError(exc.reason, key=exc.key) from None
        return fn(*args, **kwargs)

    setattr(wrapper, _MARK, True)
    return wrapper  # type: ignore[return-value]  # functools.wraps keeps the signature


def check_keywords(namespace: MutableMapping[str, Any], names: Iterable[str]) -> None:
    """Make every public class and function among `names` of a package's `namespace`
    refuse unknown keywords (:func:`checked`): a class's own ``__init__`` is replaced
    in place (every import of the class sees it), a function in the namespace by its
    checked wrapper. Exceptions, constants and type aliases are left alone."""
    for name in names:
        obj = namespace.get(name)
        if inspect.isclass(obj):
            if not issubclass(obj, BaseException):
                _check_class(obj)
        elif inspect.isfunction(obj):
            fn: types.FunctionType = obj
            namespace[name] = wrapped = checked(fn, fn.__name__)
            home = sys.modules.get(fn.__module__)
            if getattr(home, fn.__name__, None) is fn:  # pickled by reference: one object
                setattr(home, fn.__name__, wrapped)


def _check_class(cls: type) -> None:
    """:func:`checked` on the class's own ``__init__`` and public methods (class and
    static methods too: ``Grid.degrees``), replaced in place."""
    for attr, value in list(vars(cls).items()):
        if attr.startswith("_") and attr != "__init__":
            continue
        where = cls.__name__ if attr == "__init__" else f"{cls.__name__}.{attr}"
        if inspect.isfunction(value):
            setattr(cls, attr, checked(value, where))
        elif isinstance(value, classmethod | staticmethod):
            kind = type(value)
            setattr(cls, attr, kind(checked(value.__func__, where)))


#: the packages whose frames are not the user's (their code, and the functions they
#: generate: a dataclass's ``__init__``)
_OURS = ("processing", "acousim", "hardware")


def _internal(frame: types.FrameType) -> bool:
    """Whether `frame` runs our packages' code or the import system's."""
    module = str(frame.f_globals.get("__name__", ""))
    return module.split(".")[0] in _OURS or frame.f_code.co_filename.startswith("<frozen importlib")


def warn_deprecated(message: str) -> None:
    """A ``DeprecationWarning`` attributed to the user's own line: the first frame
    outside the packages (their wrappers, checks and module aliases) and the import
    system.  Python's default filters show a DeprecationWarning raised in
    ``__main__`` (a script, a notebook cell), which a fixed stack level would miss
    behind a wrapper."""
    frame: types.FrameType | None = sys._getframe(1)
    level = 2
    while frame is not None and _internal(frame):
        # warnings.warn's own count passes over the import system's frames
        level += not frame.f_code.co_filename.startswith("<frozen importlib")
        frame = frame.f_back
    warnings.warn(message, DeprecationWarning, stacklevel=level)


def folded_keywords(
    into: str, options: type, names: Iterable[str], *, since: str
) -> Callable[[F], F]:
    """A decorator: the keywords `names`, which moved into the options object `into`
    (a frozen dataclass of type `options`), are still accepted, with a
    DeprecationWarning, and folded into it (over the given or default options).

    Example: ``@folded_keywords("options", SubspaceOptions, ("subarray",), since="0.1.0")``
    lets ``doa_spectrum(..., subarray=(4, 4))`` mean
    ``doa_spectrum(..., options=SubspaceOptions(subarray=(4, 4)))``.
    """
    old = tuple(names)

    def decorate(fn: F) -> F:
        default = inspect.signature(fn).parameters[into].default

        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            given = {k: kwargs.pop(k) for k in old if k in kwargs}
            if given:
                keys = ", ".join(f"{k}=" for k in given)
                if kwargs.get(into) is not None:  # which one was meant?
                    raise KeywordError(
                        f"{keys.rstrip('=')} and {into}= both given: pass it in "
                        f"{into}={options.__name__}({keys}...) only",
                        key=f"{fn.__name__}.{next(iter(given))}",
                    )
                warn_deprecated(
                    f"{fn.__name__}({keys}...) is deprecated since {since}: pass "
                    f"{into}={options.__name__}({keys}...) (CHANGELOG.md)"
                )
                base = kwargs.get(into, default)
                if base is inspect.Parameter.empty or base is None:
                    base = options()
                kwargs[into] = dataclasses.replace(base, **given)
            return fn(*args, **kwargs)

        setattr(wrapper, _DEPRECATED, (*getattr(fn, _DEPRECATED, ()), *old))
        return wrapper  # type: ignore[return-value]

    return decorate
