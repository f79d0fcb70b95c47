"""What the scene's settings say about the render, declared where both the scene
(:mod:`acousim.scene.model`) and the renderer (:mod:`acousim.synth`) may read it."""

from __future__ import annotations

from typing import Literal

__all__ = ["COMPRESS_TOLERANCE", "RenderRate"]

#: the gain sets are compressed to this relative amplitude of what is left out
#: (-63 dB): the renderer's error against the exact reference stays below -65 dB at
#: 2 m/s and 180 deg/s (BENCHMARKS.md, motion: its time against error, 3e-4 -> -71 dB
#: with 8 sets instead of 6 on the corridor)
COMPRESS_TOLERANCE = 7e-4

RenderRate = Literal["full", "baseband"]
"""How the renderer makes the samples: 'full', fractional-delay impulses and FFTs at
the sample rate; 'baseband', the band the call occupies at complex baseband,
converted up once per microphone (:mod:`acousim.synth.baseband`)."""
