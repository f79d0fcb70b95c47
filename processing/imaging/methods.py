"""Imaging methods: every name declared once, parsed once into what it means.

A method name reads ``base[-smoothing][-cf][-wb|-bb]``: narrowband ``das``,
``music[-fss|-fbss]``, ``capon[-fss|-fbss]`` (:mod:`processing.imaging.doa`); wideband
``capon[-fbss]-wb``, ``music[-fbss]-wb`` (:mod:`processing.imaging.wideband`); broadband
``das[-cf]-bb``, ``dmasN[-cf]-bb`` (N = 2..5, :mod:`processing.imaging.broadband.energyscape`).
:func:`parse_method` checks a name against :data:`METHODS` and returns its
:class:`MethodSpec` (family, base, order, coherence factor, smoothing); callers ask
the spec, never the spelling.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Literal, get_args

from processing.base.errors import InputError, unknown_choice

__all__ = [
    "NarrowbandMethod",
    "WidebandMethod",
    "BroadbandMethod",
    "Method",
    "METHODS",
    "NARROWBAND_METHODS",
    "WIDEBAND_METHODS",
    "BROADBAND_METHODS",
    "Family",
    "MethodSpec",
    "parse_method",
    "check_method",
    "requires_ura",
]

NarrowbandMethod = Literal[
    "das", "music", "music-fss", "music-fbss", "capon", "capon-fss", "capon-fbss"
]
WidebandMethod = Literal["capon-wb", "capon-fbss-wb", "music-wb", "music-fbss-wb"]
BroadbandMethod = Literal[
    "das-bb",
    "das-cf-bb",
    "dmas2-bb",
    "dmas3-bb",
    "dmas4-bb",
    "dmas5-bb",
    "dmas2-cf-bb",
    "dmas3-cf-bb",
    "dmas4-cf-bb",
    "dmas5-cf-bb",
]
#: every imaging method's name (a ``typing.Literal``): narrowband, wideband, broadband
Method = Literal[NarrowbandMethod, WidebandMethod, BroadbandMethod]
#: The narrowband methods, exactly as spelled in :data:`NarrowbandMethod` (no case or
#: underscore variants: every caller checks names against these tuples).
NARROWBAND_METHODS: tuple[str, ...] = get_args(NarrowbandMethod)
#: the wideband methods (``-wb``: incoherent sums over the band's STFT bins)
WIDEBAND_METHODS: tuple[str, ...] = get_args(WidebandMethod)
#: the broadband methods (``-bb``: time-domain energyscapes)
BROADBAND_METHODS: tuple[str, ...] = get_args(BroadbandMethod)
#: Every imaging method: narrowband (processing.imaging.doa), wideband (``-wb``), broadband
#: (``-bb``).  Callers (command line, dataset specs) check names against this tuple.
METHODS: tuple[str, ...] = get_args(Method)  # nested Literals flatten

Family = Literal["narrowband", "wideband", "broadband"]
Smoothing = Literal["", "fss", "fbss"]


@dataclass(frozen=True)
class MethodSpec:
    """What a method name means.

    family : narrowband, wideband (``-wb``) or broadband (``-bb``).
    base : 'das', 'music', 'capon' or 'dmas'.
    order : 1 (DAS and the narrowband methods), 2-5 (DMAS of that order).
    coherence_factor : the broadband power times the coherence factor (``-cf``).
    smoothing : '' (none), 'fss' (forward) or 'fbss' (forward-backward spatial
        smoothing: needs a URA).
    """

    name: str
    family: Family
    base: str
    order: int
    coherence_factor: bool
    smoothing: Smoothing

    @property
    def requires_ura(self) -> bool:
        return self.smoothing != ""


@cache  # one entry per name of METHODS
def _spec(name: str) -> MethodSpec:
    parts = name.split("-")
    family: Family = "narrowband"
    if parts[-1] in ("wb", "bb"):
        family = "wideband" if parts.pop() == "wb" else "broadband"
    cf = "cf" in parts
    smoothing = next((p for p in parts if p in ("fss", "fbss")), "")
    head = parts[0]
    order = int(head[len("dmas") :]) if head.startswith("dmas") else 1
    base = "dmas" if head.startswith("dmas") else head
    return MethodSpec(name, family, base, order, cf, smoothing)  # type: ignore[arg-type]


def parse_method(name: str) -> MethodSpec:
    """The :class:`MethodSpec` of `name`, or an InputError naming it when it is not
    one of :data:`METHODS`."""
    return _spec(check_method(name))


def check_method(name: str) -> Method:
    """`name` when it is one of :data:`METHODS`, else an InputError naming it."""
    if name not in METHODS:
        raise InputError(
            unknown_choice("method", name, METHODS) + " (all: processing.METHODS)",
            key="method",
            value=name,
        )
    return name  # type: ignore[return-value]


def requires_ura(method: str) -> bool:
    """True for the spatially smoothed methods (``-fss``, ``-fbss``), which need a URA."""
    return parse_method(method).requires_ura
