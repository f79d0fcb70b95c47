import numpy as np
import pytest

import processing as P
from processing.imaging.metrics import cell_solid_angles


def test_cell_solid_angles_cover_the_hemisphere():
    g = P.Grid.degrees(elevation=(-90, 90), step=0.5)
    assert cell_solid_angles(g.elevation_rad, g.azimuth_rad).sum() == pytest.approx(
        2 * np.pi, rel=1e-3
    )


def test_solid_angle_of_a_spherical_cap():
    # a spectrum that is 1 inside a cap of half-angle 10 deg around (0, 0), small outside
    g = P.Grid.degrees(elevation=(-90, 90), step=0.2)
    d = g.directions()
    p = np.where(d[..., 0] >= np.cos(np.deg2rad(10)), 1.0, 0.1)
    cap = 2 * np.pi * (1 - np.cos(np.deg2rad(10)))
    assert P.solid_angle_3db(p, g.elevation_rad, g.azimuth_rad) == pytest.approx(cap, rel=0.02)


def test_solid_angle_only_counts_the_region_connected_to_the_peak():
    g = P.Grid.degrees(elevation=(-90, 90), step=1.0)
    p = np.full(g.shape, 0.01)
    p[90, 90] = 1.0
    p[10, 10] = 0.9  # a separate lobe above -3 dB
    area = P.solid_angle_3db(p, g.elevation_rad, g.azimuth_rad)
    assert area == pytest.approx(np.deg2rad(1) * 2 * np.sin(np.deg2rad(0.5)), rel=1e-9)


def _image_from_profile(profile, step):
    power = np.asarray(profile, float)[:, None, None] * np.ones((1, 3, 3))
    return P.Image(
        power,
        np.arange(len(profile)) * step,
        np.zeros(3) + [-0.1, 0, 0.1],
        np.array([-0.1, 0, 0.1]),
        "das",
        3e4,
        step,
    )


def test_range_resolution_interpolates_half_power_points():
    img = _image_from_profile([0.0, 0.25, 1.0, 0.75, 0.0], step=0.01)
    # left crossing at 1 + (0.25-0.501)/(0.25-1)... between bins 1 and 2; right between 3 and 4
    half = 10**-0.3
    left = 0.01 * (2 - (1 - half) / (1 - 0.25))
    right = 0.01 * (3 + (0.75 - half) / 0.75)
    assert P.range_resolution(img) == pytest.approx(right - left, rel=1e-9)


def test_range_resolution_stops_at_the_energy_gate():
    img = _image_from_profile([0.9, 1.0, 0.8], step=0.005)
    assert P.range_resolution(img) == pytest.approx(0.01)


def test_max_attenuation_and_dynamic_range():
    ang = np.deg2rad(np.arange(-40, 41))
    cut = (
        1e-3
        + np.exp(-(((np.rad2deg(ang) + 15) / 3) ** 2))
        + 0.5 * np.exp(-(((np.rad2deg(ang) - 15) / 3) ** 2))
    )
    att = P.max_attenuation(cut, ang, np.deg2rad(-15), np.deg2rad(15))
    assert att == pytest.approx(10 * np.log10((0.5 + 1e-3) / (1e-3 + 2 * np.exp(-25))), rel=1e-3)
    merged = np.exp(-((np.rad2deg(ang) / 30) ** 2))
    assert P.max_attenuation(merged, ang, np.deg2rad(-5), np.deg2rad(5)) == 0.0
    assert P.dynamic_range_db(np.array([1e-6, 1.0])) == pytest.approx(60)
    assert P.dynamic_range_db(np.zeros(3)) == 0.0


def test_peaks_of_an_image():
    g = P.Grid.degrees(elevation=(-90, 90), step=2.0)
    power = np.full((4, *g.shape), 1e-4)
    power[1, 50, 60] = 1.0
    power[3, 20, 30] = 0.5
    img = P.Image(
        power, np.array([1.0, 1.01, 1.02, 1.03]), g.elevation_rad, g.azimuth_rad, "das", 3e4
    )
    pk = img.peaks(-10)
    assert len(pk) == 2
    assert np.rad2deg(pk.azimuth_rad[0]) == pytest.approx(-90 + 2 * 60)
    assert np.rad2deg(pk.elevation_rad[0]) == pytest.approx(-90 + 2 * 50)
    assert pk.range_m.tolist() == [1.01, 1.03]
    assert pk.level_db[1] == pytest.approx(-3.0103, abs=1e-3)
