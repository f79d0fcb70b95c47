"""Facts of the CoSys-Lab RTIS sensors (eRTIS, uRTIS) that the simulator, the
hardware driver and the processing share, declared once here."""

from __future__ import annotations

__all__ = ["RTIS_SAMPLE_RATE_HZ"]

#: the microphones' sample rate of the RTIS sensors (Hz): their PDM streams at
#: 4.5 MHz decimated by 10 (:mod:`hardware.pdm`), the default of a scene's sensor
RTIS_SAMPLE_RATE_HZ = 450_000.0
