"""peaks.csv's truth columns: a peak is matched to the traced reflector within the
image's resolution (range: half the STFT window as a range; angle: the array's
Rayleigh limit c / (f D)), a reflector behind the array as its mirror, and a maximum
on the grid's edge is flagged.  Positions and limits are worked out here by hand."""

import numpy as np
import pytest

import processing as P
from acousim.imaging.matching import image_resolution, match_peaks, on_grid_edge


def _recording(points_sensor, amplitudes, kinds):
    arr = P.paper_8x8()
    centre = arr.positions_m.mean(axis=0)
    pts = np.asarray(points_sensor, float) + centre  # the reflectors from the array centre
    truth = P.GroundTruth(pts, pts, np.asarray(amplitudes, float), np.ones(len(pts), int), kinds)
    rec = P.Recording(np.zeros((64, 4000)), 500e3, arr, P.paper_chirp(), 343.0, truth=truth)
    return rec


def _image(method="das", f=40e3):
    az = np.deg2rad(np.arange(-90, 90.1, 2.0))
    el = np.deg2rad(np.arange(-40, 40.1, 2.0))
    rng = np.array([1.0])
    return P.Image(np.ones((1, el.size, az.size)), rng, el, az, method, f, bin_range_m=0.01)


def _peaks(r, az_deg, el_deg):
    return P.Peaks(np.deg2rad(az_deg), np.deg2rad(el_deg), np.asarray(r, float), np.zeros(len(r)))


def test_the_resolution_is_the_window_and_the_rayleigh_limit():
    rec = _recording([[1, 0, 0]], [1.0], ["point"])
    res = image_resolution(rec, _image(f=40e3), window_samples=256)
    assert res.range_m == pytest.approx(343.0 * 256 / (2 * 500e3))
    # paper_8x8: 8 x 8 at half a wavelength of 40 kHz... its diagonal, worked out
    pos = P.paper_8x8().positions_m
    d = max(np.linalg.norm(a - b) for a in pos for b in pos)
    assert res.angle_rad == pytest.approx(343.0 / (40e3 * d))


def test_peaks_take_the_strongest_reflector_within_the_resolution():
    # in front at 1.0 m, azimuth +20; a weaker one 3 deg beside it; one behind the array
    # (x < 0) whose mirror is at azimuth -30; a strong one far off in range
    a20, a23, a150 = np.deg2rad([20.0, 23.0, 150.0])
    pts = [
        [np.cos(a20), np.sin(a20), 0.0],
        [np.cos(a23), np.sin(a23), 0.0],
        [np.cos(a150), np.sin(a150), 0.0],  # behind: mirror at azimuth 30 (x -> -x)
        [2.0, 0.0, 0.0],
    ]
    rec = _recording(pts, [0.5, 0.2, 0.4, 1.0], ["specular", "scatter", "specular", "point"])
    res = image_resolution(rec, _image(), 256)
    assert np.rad2deg(res.angle_rad) == pytest.approx(9.93, abs=0.01)  # 4.95 cm diagonal
    peaks = _peaks([1.0, 1.0, 1.0, 1.5], [21.0, 31.0, -60.0, 0.0], [0, 0, 0, 0])
    m = match_peaks(rec, peaks, res)  # the 31 deg peak is 11 deg from reflector 0
    assert list(m.index) == [0, 2, -1, -1]  # the strongest near 21 deg is reflector 0
    assert list(m.kind[:2]) == ["specular", "specular"] and list(m.behind) == [0, 1, 0, 0]
    np.testing.assert_allclose(m.offset_rad[:2], np.deg2rad([1.0, 1.0]), atol=1e-9)
    np.testing.assert_allclose(m.level_db[:2], 20 * np.log10([0.5, 0.4]), atol=1e-9)
    np.testing.assert_allclose(
        m.position_sensor_m[1], np.asarray(pts[2]) + rec.array.positions_m.mean(axis=0)
    )
    assert np.isnan(m.position_sensor_m[2]).all()


def test_a_maximum_on_the_grid_edge_is_flagged():
    img = _image()
    pk = _peaks([1.0, 1.0, 1.0, 1.0], [90.0, 10.0, -90.0, 0.0], [0.0, -40.0, 12.0, 4.0])
    assert list(on_grid_edge(img, pk)) == [True, True, True, False]
