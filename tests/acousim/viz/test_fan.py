"""The fan of an image: what fan_only keeps of it draws the same fan."""

import numpy as np
import pytest

import processing as P
from acousim.imaging.matching import _grid_step
from acousim.viz.fan import (
    FAN_ELEVATION_BAND_RAD,
    fan_extent,
    fan_levels,
    fan_only,
    full_range_fan,
)


def _image(elevation_deg, seed=0):
    """A (R, E, A) image on the pictures' 2-degree grid, a few strong cells among
    weak ones, some strongest outside the fan's band, gated bins NaN-free (as made)."""
    gen = np.random.default_rng(seed)
    el = np.deg2rad(np.asarray(elevation_deg, float))
    az = np.deg2rad(np.arange(-90.0, 90.1, 2.0))
    rng = 0.5 + 0.0086 * np.arange(120)
    power = gen.random((rng.size, el.size, az.size)) ** 12
    power[40, np.argmax(np.abs(el)), 10] = 50.0  # the strongest cell, off the band
    return P.Image(power, rng, el, az, "music-fbss", 41e3, 0.0086)


@pytest.mark.parametrize("seed", range(3))
def test_fan_only_draws_the_same_fan(seed):
    image = _image(np.arange(-40.0, 40.1, 2.0), seed)
    small = fan_only(image)
    assert small.power.shape == (image.range_m.size, 2, image.azimuth_rad.size)
    assert np.all(np.abs(small.elevation_rad) <= FAN_ELEVATION_BAND_RAD)
    band = np.abs(image.elevation_rad) <= FAN_ELEVATION_BAND_RAD
    expected = image.power[:, band].max(axis=1)  # the fan's definition, written out
    for limit in (None, 1.2, 5.0):
        r0, f0 = full_range_fan(image, limit)
        r1, f1 = full_range_fan(small, limit)
        np.testing.assert_array_equal(r0, r1)
        np.testing.assert_array_equal(f0, f1)
    rows = np.rint(image.range_m / image.bin_range_m).astype(int)
    np.testing.assert_array_equal(full_range_fan(small)[1][rows], expected)
    extent = fan_extent(image, 1.5, 30.0)
    assert fan_extent(small, 1.5, 30.0) == extent
    a, b = fan_levels(image, 1.5, 30.0, 400, extent), fan_levels(small, 1.5, 30.0, 400, extent)
    np.testing.assert_array_equal(a.db, b.db)
    assert _grid_step(small) == _grid_step(image)  # the marks' cell


def test_fan_only_keeps_an_image_it_cannot_reduce():
    one = _image([0.0])  # a band of one elevation
    assert fan_only(one) is one
    uneven = _image([-40.0, -38.0, -10.0, 10.0, 40.0])  # the smallest step off the band
    assert fan_only(uneven) is uneven
