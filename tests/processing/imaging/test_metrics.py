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
    alone = P.solid_angle_3db(p, g.elevation_rad, g.azimuth_rad)
    p[10, 10] = 0.9  # a separate lobe above -3 dB
    area = P.solid_angle_3db(p, g.elevation_rad, g.azimuth_rad)
    assert area == alone
    # a one-sample spike 20 dB over its neighbours is narrower than its cell
    assert area < np.deg2rad(1) * 2 * np.sin(np.deg2rad(0.5))


def _gaussian_beam(g, az0, el0, a, b, tilt=0.0):
    """Power of a beam whose level falls 3 dB on the ellipse of semi-axes `a` (along
    azimuth) and `b` (along elevation), rad, turned by `tilt`, centred on (az0, el0)."""
    x = g.azimuth_rad[None, :] - az0
    y = g.elevation_rad[:, None] - el0
    u = np.cos(tilt) * x + np.sin(tilt) * y
    v = -np.sin(tilt) * x + np.cos(tilt) * y
    return 10 ** (-0.3 * ((u / a) ** 2 + (v / b) ** 2))


def _ellipse_solid_angle(a, b, el0):
    """Exact solid angle of {(az-az0)^2/a^2 + (el-el0)^2/b^2 <= 1} on the unit sphere:
    the integral of cos(el) over it, 2 a pi J1(b) cos(el0)."""
    from scipy.special import j1

    return 2 * a * np.pi * j1(b) * np.cos(el0)


@pytest.mark.parametrize(
    "step, a_deg, b_deg, az0, el0, tilt",
    [
        (0.25, 0.1, 0.07, 0.03, -0.11, 0.0),  # the whole beam inside one 0.25 deg cell
        (0.25, 0.3, 0.12, 0.1, 0.05, 0.4),
        (1.0, 0.35, 0.6, 30.3, 30.2, 1.0),
        (2.0, 0.7, 0.5, 0.0, 0.0, 0.0),  # on a sample, under one cell
        (0.5, 6.0, 3.0, 60.1, 59.8, 0.2),  # many cells
    ],
)
def test_solid_angle_of_a_gaussian_beam_below_and_above_one_cell(
    step, a_deg, b_deg, az0, el0, tilt
):
    az0, el0 = np.deg2rad(az0), np.deg2rad(el0)
    half = 4 * max(a_deg, b_deg) + 6 * step
    g = P.Grid.degrees(
        (np.rad2deg(az0) - half, np.rad2deg(az0) + half),
        (np.rad2deg(el0) - half, min(np.rad2deg(el0) + half, 90)),
        step,
    )
    a, b = np.deg2rad(a_deg), np.deg2rad(b_deg)
    if tilt:  # a turned ellipse: the same area to first order in its size
        exact = np.pi * a * b * np.cos(el0)
        tol = 0.03
    else:
        exact = _ellipse_solid_angle(a, b, el0)
        tol = 0.02
    got = P.solid_angle_detail(
        _gaussian_beam(g, az0, el0, a, b, tilt), g.elevation_rad, g.azimuth_rad
    )
    assert got.solid_angle_sr == pytest.approx(exact, rel=tol)
    cell = np.deg2rad(step) ** 2 * np.cos(el0)
    assert got.sub_cell == (2 * min(a, b) < np.deg2rad(step)) or got.solid_angle_sr > cell


def test_solid_angle_of_a_separable_sinc_beam():
    """sinc^2(x/w1) sinc^2(y/w2), whose -3 dB region (about 1.8 deg x 1.15 deg) spans
    only 3-4 samples of a 0.5 deg grid, against a direct count on a 0.005 deg grid
    (a second implementation)."""
    w1, w2 = np.deg2rad(2.0), np.deg2rad(1.3)

    def beam(el, az):
        return (np.sinc(az[None, :] / w1) * np.sinc(el[:, None] / w2)) ** 2

    coarse = P.Grid.degrees((-10, 10), (-10, 10), 0.5)
    got = P.solid_angle_3db(
        beam(coarse.elevation_rad, coarse.azimuth_rad), coarse.elevation_rad, coarse.azimuth_rad
    )
    d = np.deg2rad(0.005)
    x = np.arange(-3, 3, 0.005) * np.pi / 180 + d / 2
    inside = beam(x, x) >= 10**-0.3
    ref = float((inside * np.cos(x)[:, None]).sum() * d * d)
    assert got == pytest.approx(ref, rel=0.03)


def test_a_caller_spectrum_is_evaluated_on_the_fine_grid():
    """The coarse samples of a narrow non-Gaussian peak (1 / (1 + (r/w)^2): -3 dB at
    r = w) cannot say its width; the spectrum function can."""
    w = np.deg2rad(0.05)

    def lorentz(el, az):
        return 1 / (1 + (el[:, None] ** 2 + az[None, :] ** 2) / w**2)

    g = P.Grid.degrees((-5, 5), (-5, 5), 0.5)
    p = lorentz(g.elevation_rad, g.azimuth_rad)
    got = P.solid_angle_detail(p, g.elevation_rad, g.azimuth_rad, spectrum=lorentz)
    assert got.solid_angle_sr == pytest.approx(np.pi * w**2, rel=0.03)
    assert not got.sub_cell
    assert P.solid_angle_detail(p, g.elevation_rad, g.azimuth_rad).sub_cell


def test_a_region_at_the_grid_edge_is_marked_truncated():
    g = P.Grid.degrees((0, 10), (0, 10), 1.0)
    p = _gaussian_beam(g, 0.0, np.deg2rad(5), np.deg2rad(2), np.deg2rad(2))
    got = P.solid_angle_detail(p, g.elevation_rad, g.azimuth_rad)
    assert got.truncated and not got.sub_cell
    assert got.cells >= got.solid_angle_sr * 0.5


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
