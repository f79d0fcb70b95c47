"""Air: speed of sound and atmospheric absorption (ISO 9613-1)."""

from __future__ import annotations

import numpy as np

__all__ = ["speed_of_sound", "absorption_db_per_m"]


def speed_of_sound(temperature_c: float = 20.0, humidity_percent: float = 50.0) -> float:
    """Speed of sound in air, m/s (Cramer's humidity correction is below 0.3 %:
    the ideal-gas value with a linear humidity term is used)."""
    t = temperature_c + 273.15
    c_dry = 331.3 * np.sqrt(t / 273.15)
    return float(c_dry * (1 + 0.0016 * humidity_percent / 100 * np.exp(0.0617 * temperature_c)))


def absorption_db_per_m(
    frequency_hz: np.ndarray,
    temperature_c: float = 20.0,
    humidity_percent: float = 50.0,
    pressure_kpa: float = 101.325,
) -> np.ndarray:
    """Pure-tone atmospheric absorption coefficient alpha(f) in dB/m (ISO 9613-1, eq. 5).

    Valid for 50 Hz to 10 MHz, -20 to 50 °C, 10 to 100 % relative humidity.
    """
    f = np.asarray(frequency_hz, dtype=float)
    T = temperature_c + 273.15
    T0, T01 = 293.15, 273.16
    pa = pressure_kpa / 101.325
    # molar concentration of water vapour (%), from relative humidity
    psat = 10 ** (-6.8346 * (T01 / T) ** 1.261 + 4.6151)
    h = humidity_percent * psat / pa
    fro = pa * (24 + 4.04e4 * h * (0.02 + h) / (0.391 + h))
    frn = pa * (T / T0) ** -0.5 * (9 + 280 * h * np.exp(-4.170 * ((T / T0) ** (-1 / 3) - 1)))
    return (
        8.686
        * f**2
        * (
            1.84e-11 / pa * (T / T0) ** 0.5
            + (T / T0) ** -2.5
            * (
                0.01275 * np.exp(-2239.1 / T) / (fro + f**2 / fro)
                + 0.1068 * np.exp(-3352.0 / T) / (frn + f**2 / frn)
            )
        )
    )
