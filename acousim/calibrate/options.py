"""The settings of a material calibration, declared once
(:func:`processing.base.settings.setting`): the library call and the command line read
them from here."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, get_args

from acousim.calibrate.features import DEFAULT_AZIMUTHS_DEG, DEFAULT_ELEVATIONS_DEG, Directions
from processing.base.errors import InputError
from processing.base.settings import setting, validate

__all__ = ["CalibrationSettings", "Loss", "LOSSES"]

Loss = Literal["soft_l1", "huber", "cauchy", "arctan", "linear"]
"""Robust losses of :func:`scipy.optimize.least_squares`."""
LOSSES: tuple[str, ...] = get_args(Loss)


@dataclass(frozen=True)
class CalibrationSettings:
    """What to fit and how.

    parameters : what is free, each ``material`` (its reflection and diffuse),
        ``material.reflection`` or ``material.diffuse``; empty: every material a
        mesh uses, both.
    tables : {material: table frequencies in kHz}: fit that material as a table
        over frequency at these points (else as the scene has it).
    bands : frequency bands of the energy features; 0: one, or twice the largest
        table's points when a table is fitted.
    min_range_m, max_range_m, bin_m : the range gate (the direct path and the
        crosstalk lie before `min_range_m`) and the bins; max 0: the recording's end.
    azimuth_deg, elevation_deg : the look directions.
    loss, loss_scale : the robust loss and its scale (natural log of energy: 0.5 is
        2.2 dB); a bin off by much more counts about linearly, not squared.
    align : shift the recording to the simulation (the direct path's lag,
        :func:`acousim.compare.alignment.align`).
    fit_level : also fit one overall level (a real recording's unknown gain); it
        trades against the reflections: leave it off for simulated recordings.
    max_evaluations : of the solver.
    """

    parameters: tuple[str, ...] = setting((), doc="free parameters", kind="strings")
    tables: dict = field(default_factory=dict)
    bands: int = setting(0, "", 0, 32, "frequency bands; 0: automatic")
    min_range_m: float = setting(0.5, "m", 0, 100, "range gate start")
    max_range_m: float = setting(0.0, "m", 0, 100, "range gate end; 0: the recording's end")
    bin_m: float = setting(0.1, "m", 0.005, 10, "range bin width")
    azimuth_deg: tuple[float, ...] = setting(
        DEFAULT_AZIMUTHS_DEG, "deg", -180, 180, "look azimuths", kind="vector"
    )
    elevation_deg: tuple[float, ...] = setting(
        DEFAULT_ELEVATIONS_DEG, "deg", -90, 90, "look elevations", kind="vector"
    )
    loss: Loss = setting("soft_l1", choices=LOSSES, doc="robust loss")
    loss_scale: float = setting(0.5, "", 1e-3, 100, "robust loss scale (log energy)")
    align: bool = setting(True, doc="align the recording on the simulation's direct path")
    fit_level: bool = setting(False, doc="also fit one overall level")
    max_evaluations: int = setting(60, "", 1, 10000, "solver evaluations")

    def __post_init__(self) -> None:
        validate(self)
        for name, points in self.tables.items():
            if not isinstance(points, tuple | list) or not points:
                raise InputError("must be a list of kHz", key=f"tables[{name}]", value=points)

    @property
    def directions(self) -> Directions:
        return Directions(tuple(self.azimuth_deg), tuple(self.elevation_deg))

    def free(self, available: list[str]) -> dict[str, tuple[bool, bool]]:
        """{material: (fit reflection, fit diffuse)} for the `available` materials;
        InputError naming a parameter that is not one of theirs."""
        if not self.parameters:
            return {m: (True, True) for m in available}
        out: dict[str, list[bool]] = {}
        for p in self.parameters:
            name, _, what = p.partition(".")
            if name not in available or what not in ("", "reflection", "diffuse"):
                raise InputError(
                    f"must be MATERIAL, MATERIAL.reflection or MATERIAL.diffuse with MATERIAL "
                    f"one of {', '.join(available)}",
                    key="parameters",
                    value=p,
                )
            flags = out.setdefault(name, [False, False])
            flags[0] |= what in ("", "reflection")
            flags[1] |= what in ("", "diffuse")
        return {k: (a, b) for k, (a, b) in out.items()}
