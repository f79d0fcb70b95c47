"""Speed of sound in humid air against published values and ideal-gas theory."""

import numpy as np
import pytest

from acousim.core.air import speed_of_sound, water_vapour_mole_fraction


@pytest.mark.parametrize(
    "t, h, expected",
    [
        # Cramer (1993): dry air, 0 deg C, 101.325 kPa (here with 400 ppm CO2, his
        # 331.46 m/s is for 314 ppm: -0.007 m/s for the extra CO2)
        (0.0, 0.0, 331.45),
        # NPL's calculator (Cramer's equations, 400 ppm CO2): 20 deg C, 50 %
        (20.0, 50.0, 343.99),
    ],
)
def test_published_values(t, h, expected):
    assert speed_of_sound(t, h) == pytest.approx(expected, abs=0.015)


def _ideal_gas_mixture(t_c: float, x_w: float) -> float:
    """sqrt(gamma R T / M) for dry air mixed with water vapour (both ideal gases,
    heat capacities at constant pressure 3.5 R and 4.04 R): written for this test."""
    R, T = 8.314462618, t_c + 273.15
    m = (1 - x_w) * 28.9647e-3 + x_w * 18.01528e-3
    cp = (1 - x_w) * 3.5 + x_w * 4.04
    gamma = cp / (cp - 1)
    return np.sqrt(gamma * R * T / m)


@pytest.mark.parametrize("t", [0.0, 10.0, 20.0, 30.0, 35.0])
def test_humidity_raises_the_speed_as_an_ideal_gas_mixture_does(t):
    """The humidity term (c at 90 % minus c in dry air) against an ideal-gas mixture of
    the same water content: within 5 % (the old linear term was 1.5-1.8 times too big)."""
    x_w = water_vapour_mole_fraction(t, 90.0)
    expected = _ideal_gas_mixture(t, x_w) - _ideal_gas_mixture(t, 0.0)
    got = speed_of_sound(t, 90.0) - speed_of_sound(t, 0.0)
    assert got == pytest.approx(expected, rel=0.05)


def test_temperature_slope_is_that_of_an_ideal_gas():
    """Dry air from 0 to 30 deg C: c proportional to sqrt(T) within 0.05 %."""
    c0 = speed_of_sound(0.0, 0.0)
    for t in (10.0, 20.0, 30.0):
        assert speed_of_sound(t, 0.0) / c0 == pytest.approx(
            np.sqrt((t + 273.15) / 273.15), rel=5e-4
        )


def test_water_vapour_at_saturation():
    """Saturation vapour pressure of water at 20 deg C is 2339 Pa (steam tables)."""
    x_w = water_vapour_mole_fraction(20.0, 100.0)
    assert x_w * 101325 == pytest.approx(2339 * 1.0045, rel=2e-3)


def test_scene_environment_passes_its_pressure():
    """Cramer's pressure dependence is weak but real: a scene at 80 kPa uses it
    (the same function of the three values, not of two)."""
    from acousim.core.air import speed_of_sound
    from acousim.scene.model import Environment

    env = Environment(temperature_c=25.0, humidity_percent=80.0, pressure_kpa=80.0)
    assert env.speed_of_sound_m_s == speed_of_sound(25.0, 80.0, 80.0)
    assert env.speed_of_sound_m_s != speed_of_sound(25.0, 80.0, 101.325)
