"""Air: speed of sound (Cramer 1993) and atmospheric absorption (ISO 9613-1)."""

from __future__ import annotations

import numpy as np

__all__ = ["speed_of_sound", "water_vapour_mole_fraction", "absorption_db_per_m"]


#: Cramer (1993), J. Acoust. Soc. Am. 93(5) 2510-2516, eq. on p. 2514: zero-frequency
#: speed of sound as a polynomial in t (deg C), p (Pa), x_w and x_c (mole fractions)
_CRAMER = (
    331.5024, 0.603055, -0.000528,  # a0..a2: t
    51.471935, 0.1495874, -0.000782,  # a3..a5: x_w
    -1.82e-7, 3.73e-8, -2.93e-10,  # a6..a8: p
    -85.20931, -0.228525, 5.91e-5,  # a9..a11: x_c
    -2.835149, -2.15e-13, 29.179762, 0.000486,  # a12..a15: x_w^2, p^2, x_c^2, x_w p x_c
)  # fmt: skip
#: mole fraction of carbon dioxide in the air (400 ppm)
CO2_MOLE_FRACTION = 400e-6


def water_vapour_mole_fraction(
    temperature_c: float, humidity_percent: float, pressure_kpa: float = 101.325
) -> float:
    """Mole fraction of water vapour x_w from relative humidity (Cramer 1993, with
    the saturation vapour pressure of Davis 1992, Metrologia 29, 67-70)."""
    t, T, p = temperature_c, temperature_c + 273.15, pressure_kpa * 1e3
    p_sv = np.exp(1.2378847e-5 * T**2 - 1.9121316e-2 * T + 33.93711047 - 6.3431645e3 / T)
    enhancement = 1.00062 + 3.14e-8 * p + 5.6e-7 * t**2
    return float(humidity_percent / 100 * enhancement * p_sv / p)


def speed_of_sound(
    temperature_c: float = 20.0, humidity_percent: float = 50.0, pressure_kpa: float = 101.325
) -> float:
    """Zero-frequency speed of sound in humid air, m/s (Cramer 1993).

    Steps: 1. the mole fraction of water vapour from relative humidity
    (:func:`water_vapour_mole_fraction`); 2. Cramer's polynomial in temperature,
    pressure, water vapour and CO2 (:data:`CO2_MOLE_FRACTION`).  Cramer fitted it for
    0 to 30 deg C, 75 to 102 kPa and x_w below 0.06, within 300 ppm of his exact
    values; outside (hot humid air) it is an extrapolation.  20 deg C and 50 %:
    343.99 m/s.
    """
    a = _CRAMER
    t, p, xc = temperature_c, pressure_kpa * 1e3, CO2_MOLE_FRACTION
    xw = water_vapour_mole_fraction(temperature_c, humidity_percent, pressure_kpa)
    c = (
        a[0]
        + a[1] * t
        + a[2] * t**2
        + (a[3] + a[4] * t + a[5] * t**2) * xw
        + (a[6] + a[7] * t + a[8] * t**2) * p
        + (a[9] + a[10] * t + a[11] * t**2) * xc
        + a[12] * xw**2
        + a[13] * p**2
        + a[14] * xc**2
        + a[15] * xw * p * xc
    )
    return float(c)


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
