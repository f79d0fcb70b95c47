"""A fast point of the settings (issue 39): :data:`FAST_SETTINGS`, each a
:class:`acousim.scene.model.Simulation` setting (``dataclasses.replace(scene.simulation,
**FAST_SETTINGS)``), measured on the corridor drive (docs/physics.md, speed)."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from acousim.scene.model import Diffraction

__all__ = ["FAST_SETTINGS"]

#: The Doppler render at complex baseband with a looser gain-set compression (1 %
#: instead of 0.07 %), paths 50 dB under the strongest echo dropped (not 80), edges
#: alone (no edge to edge).  Against the defaults on the corridor drive (paired,
#: alternating runs of `Simulator.run` over 40 poses on a loaded machine): 1.60x
#: as fast in CPU time, 1.62x in wall time; the waveform -65 dB of the recordings'
#: energy, -27 dB of the echoes'; of 737 DAS peaks above -30 dB, 716 in place.
FAST_SETTINGS: Mapping[str, Any] = MappingProxyType(
    {
        "render_rate": "baseband",
        "render_tolerance": 0.01,
        "energy_floor_db": -50.0,
        "diffraction": Diffraction(order=1),
    }
)
