"""What the scene's settings say about the render, declared where both the scene
(:mod:`acousim.scene.model`, which checks a scene's choices) and the renderer
(:mod:`acousim.synth`, which implements them; :mod:`acousim.synth.render`'s docstring
describes each interpolator) may read it: the fractional-delay interpolators' names,
the render's rate and domain and its gain sets' compression."""

from __future__ import annotations

from typing import Literal, get_args

from processing.base.errors import InputError

__all__ = [
    "COMPRESS_TOLERANCE",
    "RenderRate",
    "RenderDomain",
    "FractionalDelay",
    "ShapedDelay",
    "INTERPOLATORS",
    "SHAPED_INTERPOLATORS",
    "DEFAULT_INTERPOLATOR",
    "check_interpolator",
]

#: the gain sets are compressed to this relative amplitude of what is left out
#: (-63 dB): the renderer's error against the exact reference stays below -65 dB at
#: 2 m/s and 180 deg/s (BENCHMARKS.md, motion: its time against error, 3e-4 -> -71 dB
#: with 8 sets instead of 6 on the corridor)
COMPRESS_TOLERANCE = 7e-4

RenderRate = Literal["full", "baseband"]
"""How the renderer makes the samples: 'full', fractional-delay impulses and FFTs at
the sample rate; 'baseband', the band the call occupies at complex baseband,
converted up once per microphone (:mod:`acousim.synth.baseband`).  At either rate,
echoes few enough that their sum in time is estimated cheaper than the transforms
(:data:`RenderDomain` 'auto', or 'time') are summed in time at the sample rate."""

RenderDomain = Literal["auto", "frequency", "time"]
"""Where the render sums the echoes: 'frequency', by transforms (at the full rate,
impulses per gain set and microphone and FFTs over the span the echoes reach; at
baseband, :mod:`acousim.synth.baseband`); 'time', each path's filtered call added at
its fractional delay at the sample rate (cost per path, microphone and call sample:
for few paths, :mod:`acousim.synth.timedomain`); 'auto', the sum in time where it is
estimated to cost less than the full rate's transforms (at the full rate the same
signals either way, within -100 dB)."""

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
