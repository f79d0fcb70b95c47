"""The fractional-delay interpolators' names: a scene's ``simulation.fractional_delay``
is checked against them (:mod:`acousim.scene`), the renderer implements them
(:mod:`acousim.synth.render`, whose docstring describes each)."""

from __future__ import annotations

from typing import Literal, get_args

from processing.base.errors import InputError

__all__ = [
    "FractionalDelay",
    "ShapedDelay",
    "INTERPOLATORS",
    "SHAPED_INTERPOLATORS",
    "DEFAULT_INTERPOLATOR",
    "check_interpolator",
]

ShapedDelay = Literal["sinc", "lagrange", "nearest"]
"""Interpolators that take a path response (absorption, directivity): the choices
of a scene's ``simulation.fractional_delay``."""
FractionalDelay = Literal["reference", "exact", "sinc", "lagrange", "fft", "nearest"]
"""Every fractional-delay interpolator of :func:`acousim.synth.render.render`."""
INTERPOLATORS: tuple[str, ...] = get_args(FractionalDelay)
SHAPED_INTERPOLATORS: tuple[str, ...] = get_args(ShapedDelay)
DEFAULT_INTERPOLATOR: ShapedDelay = "sinc"


def check_interpolator(
    interpolator: object,
    allowed: tuple[str, ...] = INTERPOLATORS,
    *,
    need: str = "",
    key: str = "interpolator",
) -> FractionalDelay:
    """`interpolator` if it is one of `allowed`, else :class:`InputError` naming `key`
    (`need`: why only `allowed`, e.g. "a path response"): the one check of the
    fractional-delay option."""
    if not isinstance(interpolator, str) or interpolator not in allowed:
        why = f"{need} needs" if need else "unknown fractional-delay interpolator; choose"
        raise InputError(f"{why} one of {', '.join(allowed)}", key=key, value=interpolator)
    return interpolator  # type: ignore[return-value]
