"""Deprecated: the settings of a fast point measured for issue 39, kept for one version
(``FAST_SETTINGS``, with a ``DeprecationWarning``).

There is one "fast": the quality preset ``simulation.quality = "fast"`` (scene file,
Python, ``--quality`` on the command line), whose cost and error are measured on the
front (docs/physics.md, "Run time against error").  This point (the Doppler render at
complex baseband, the gain sets compressed to 1 %, paths 50 dB under the strongest
echo dropped, edges alone) was cheaper than the preset but off the accuracy bar the
preset keeps (-27 dB of the echoes' energy, 21 of 737 DAS peaks moved or lost); its
measurement stays in docs/physics.md, its settings written out there.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from acousim.scene.model import Diffraction
from processing.base.api import warn_deprecated

__all__: list[str] = []

_FAST_SETTINGS: Mapping[str, Any] = MappingProxyType(
    {
        "render_rate": "baseband",
        "render_tolerance": 0.01,
        "energy_floor_db": -50.0,
        "diffraction": Diffraction(order=1),
    }
)


def __getattr__(name: str) -> object:
    if name == "FAST_SETTINGS":
        warn_deprecated(
            "acousim.scene.fast.FAST_SETTINGS is deprecated and goes in the next version: "
            'use simulation.quality = "fast" (the measured preset), or set these '
            "settings yourself: render_rate='baseband', render_tolerance=0.01, "
            "energy_floor_db=-50, diffraction=Diffraction(order=1)"
        )
        return _FAST_SETTINGS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
