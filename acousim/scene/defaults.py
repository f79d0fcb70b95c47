"""What a simulation setting is when it is not given: the quality presets and the
memory limit from the environment.

``simulation.quality = "fast" | "default" | "reference"`` (a scene file's
``[simulation]`` table, ``Simulation(quality=...)``, ``--quality`` on the command
line) chooses a preset: a table of overrides of :class:`acousim.scene.Simulation`'s
declared settings (:data:`QUALITY_PRESETS`).  The settings given explicitly keep
their values whatever the preset; the others take the preset's value, else the
declared default.  ``dataclasses.replace(sim, quality=...)`` (or
``sim.with_quality(...)``) applies another preset to the settings that were not
given; a setting a replace changes counts as given from then on.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Mapping
from typing import Any, Literal, get_args

from processing.base.errors import InputError
from processing.base.settings import check, settings_of, validate

__all__ = [
    "Quality",
    "QUALITIES",
    "QUALITY_PRESETS",
    "given",
    "fill_unset",
    "record_given",
    "check_presets",
    "memory_limit_bytes",
]

Quality = Literal["fast", "default", "reference"]
"""A simulation's quality preset: a point on the run time against error front
(BENCHMARKS.md, "Run time against error"; docs/front.png)."""
QUALITIES: tuple[str, ...] = get_args(Quality)

#: Each quality preset: the ``[simulation]`` settings it sets (overrides of the
#: declared settings, each checked against its declaration when
#: :mod:`acousim.scene.model` is imported).  "default": the declared defaults;
#: "reference": every numerical knob at its most accurate (the front's reference; the
#: ray budget stays automatic: it stops once the diffuse tail's energy has converged,
#: and more rays draw another diffuse tail rather than a more accurate one; what the
#: model includes, the bounces and the orders of diffraction, stays as set); "fast":
#: cheaper knobs whose error stays small (BENCHMARKS.md, "Run time against error").
#: Adding a knob to a preset is one line here.
QUALITY_PRESETS: Mapping[str, Mapping[str, Any]] = {
    "fast": {
        "diffraction": {"step_m": 2e-3},
        "fractional_delay": "lagrange",
        "energy_floor_db": -75.0,
        "render_rate": "baseband",
        "render_tolerance": 5e-3,
    },
    "default": {},
    "reference": {
        "diffraction": {"step_m": 2.5e-4},
        "energy_floor_db": -120.0,
    },
}


def memory_limit_bytes() -> float:
    """Default memory limit of a simulation: ``$ACOUSIM_MAX_MEMORY_GB`` (gigabytes) or 8 GB."""
    text = os.environ.get("ACOUSIM_MAX_MEMORY_GB") or "8"  # unset or empty: 8
    try:
        gb = float(text)
    except ValueError:
        gb = math.nan
    if not (gb > 0 and math.isfinite(gb)):
        raise InputError(
            "must be a positive number of gigabytes", key="ACOUSIM_MAX_MEMORY_GB", value=text
        )
    return gb * 1e9


#: settings that are tables of their own (a dataclass of declared settings, one
#: field of the simulation; a preset gives some of its keys): ``diffraction``
TABLES = ("diffraction",)
#: the flat names the diffraction table's keys had before it existed (scene files'
#: ``[simulation]`` keys and ``Simulation``'s keywords, read for a version): old -> key
FLAT_DIFFRACTION = {
    "diffraction_step_m": "step_m",
    "diffraction_order": "order",
    "diffraction_reflections": "reflections",
}


def _settings(cls: Any) -> frozenset[str]:
    """The declared settings of `cls` and its tables' names."""
    return frozenset(settings_of(cls)) | frozenset(TABLES)


def _table(cls: type, name: str, values: Mapping[str, Any]) -> Any:
    """Table `name` of `cls` (its default object) with `values`, checked by its
    declarations."""
    field = next(f for f in dataclasses.fields(cls) if f.name == name)
    make: Any = field.default_factory
    return dataclasses.replace(make(), **values)


def given(sim: Any) -> frozenset[str]:
    """The names of the settings of `sim` given explicitly (the others: its preset's
    or the declared defaults)."""
    return sim.__dict__.get("_given", _settings(sim))


def _unset_values(cls: type, quality: str) -> dict[str, Any]:
    """What each setting of `cls` is when not given, under `quality`."""
    out = {name: decl.default for name, decl in settings_of(cls).items()}
    out["max_memory_gb"] = memory_limit_bytes() / 1e9
    preset = dict(QUALITY_PRESETS[quality])
    for name in TABLES:
        out[name] = _table(cls, name, preset.pop(name, {}))
    return {**out, **preset, "quality": quality}


def fill_unset(sim: Any) -> None:
    """From ``__post_init__``, its settings validated: the settings not given set to
    the preset's values or the declared defaults (a replace may carry another
    preset's), and the object's (quality, given names) kept for a later replace."""
    if sim.quality != "default" or sim._origin is not None:
        unset = _unset_values(type(sim), sim.quality)
        for name in unset.keys() - given(sim):
            object.__setattr__(sim, name, unset[name])
        validate(sim)  # the preset's values normalised as given ones are
    object.__setattr__(sim, "_origin", (sim.quality, given(sim)))


def _same(a: Any, b: Any) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and a != a and b != b)


def record_given(cls: type) -> type:
    """Wrap the dataclass's ``__init__`` to record which settings the caller gave
    (positionally or by name), so that a quality preset fills only the others.  A
    call with ``_origin`` (``dataclasses.replace``, which passes every field) keeps
    the names the copied object was given and adds those whose value it changes.
    Then check the presets against the declarations (:func:`check_presets`)."""
    init: Any = cls.__dict__["__init__"]
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    declared = _settings(cls)

    @functools.wraps(init)
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        origin = kwargs.get("_origin")
        if origin is None:
            names_given = frozenset(names[: len(args)]) | (kwargs.keys() & declared)
            if kwargs.keys() & FLAT_DIFFRACTION.keys():
                names_given |= {"diffraction"}
        else:
            quality, before = origin
            unset = _unset_values(cls, quality)
            changed = {
                n for n in kwargs.keys() & declared - before if not _same(kwargs[n], unset[n])
            }
            names_given = frozenset(before | changed)
        object.__setattr__(self, "_given", names_given)
        init(self, *args, **kwargs)

    setattr(cls, "__init__", __init__)  # noqa: B010  (mypy: no assignment to a method)
    check_presets(cls)
    return cls


def check_presets(cls: type) -> None:
    """Every preset's value checked against its setting's declaration in `cls` (at
    import: a misspelt or out-of-range line in :data:`QUALITY_PRESETS` fails at once)."""
    decls = settings_of(cls)
    if set(QUALITY_PRESETS) != set(QUALITIES):
        raise InputError("needs one table per quality", key="QUALITY_PRESETS")
    for quality, table in QUALITY_PRESETS.items():
        for name, value in table.items():
            key = f"QUALITY_PRESETS[{quality!r}].{name}"
            if name in TABLES:
                _table(cls, name, value)  # its own declarations check the values
                continue
            if name not in decls or name == "quality":
                raise InputError(f"is not a setting of {cls.__name__}", key=key)
            check(decls[name], value, key)
