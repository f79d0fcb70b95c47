"""find_peaks looks only at the cells above its threshold: the same peaks as the whole
image's 3x3x3 maximum filter (scipy), written out here as the reference."""

import numpy as np
import pytest
from scipy.ndimage import maximum_filter

import processing as P


def reference_peaks(power: np.ndarray, threshold_db: float):
    """(range, elevation, azimuth) indices and levels of the local maxima, strongest
    first, plateaus once (their first cell in index order): scipy's maximum filter
    over the whole image."""
    level = np.maximum(10 * np.log10(np.maximum(power, 0) / power.max()), -120.0)
    mask = (power >= maximum_filter(power, size=3, mode="nearest")) & (level >= threshold_db)
    out, seen = [], np.zeros(power.shape, bool)
    for r, e, a in np.argwhere(mask):
        box = tuple(slice(max(i - 1, 0), i + 2) for i in (r, e, a))
        if not seen[box].any():
            out.append((r, e, a))
        seen[r, e, a] = True
    lv = np.array([level[c] for c in out])
    order = np.argsort(-lv, kind="stable")
    return np.array(out).reshape(-1, 3)[order], lv[order]


@pytest.fixture(params=["compiled", "numpy"])
def kernel(request, monkeypatch):
    """find_peaks with its compiled scan (numba, when installed) and with its numpy
    twin: both must find the reference's peaks."""
    import processing.imaging.image as image_mod

    if request.param == "numpy":
        monkeypatch.setattr(image_mod, "optional_kernel", lambda *a: None)
    elif image_mod.optional_kernel("processing.imaging.peaks_kernel") is None:
        pytest.skip("numba is not installed")
    return request.param


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("threshold_db", [-3.0, -10.0, -25.0, -200.0])
@pytest.mark.parametrize("layout", ["C", "elevation-major"])
def test_find_peaks_matches_a_whole_image_maximum_filter(seed, threshold_db, layout, kernel):
    gen = np.random.default_rng(seed)
    shape = (30, 9, 13)
    power = gen.random(shape) ** 8  # a few strong cells among many weak ones
    power[gen.random(shape) < 0.05] = 0.5  # plateaus of equal cells
    power[0, 0, :3] = power.max()  # a plateau of the strongest at a corner
    if layout == "elevation-major":  # as the co-array images are: a transposed view
        power = np.ascontiguousarray(power.transpose(1, 0, 2)).transpose(1, 0, 2)
    az, el = np.linspace(-1.5, 1.5, shape[2]), np.linspace(-0.7, 0.7, shape[1])
    img = P.Image(power, np.linspace(0.3, 3.0, shape[0]), el, az, "das", 40e3)
    got = P.find_peaks(img, threshold_db)
    idx, lv = reference_peaks(power, threshold_db)
    assert len(got) == len(idx) > 0
    np.testing.assert_array_equal(got.range_m, img.range_m[idx[:, 0]])
    np.testing.assert_array_equal(got.elevation_rad, el[idx[:, 1]])
    np.testing.assert_array_equal(got.azimuth_rad, az[idx[:, 2]])
    np.testing.assert_allclose(got.level_db, lv, rtol=0, atol=1e-12)


def test_an_images_repr_is_one_short_line_of_its_shape_and_axes():
    img = P.Image(
        power=np.ones((3, 2, 4)),
        range_m=np.array([0.5, 0.6, 0.7]),
        elevation_rad=np.deg2rad([-10.0, 10.0]),
        azimuth_rad=np.deg2rad([-30.0, -10.0, 10.0, 30.0]),
        method="das",
        frequency_hz=31250.0,
    )
    assert repr(img) == (
        "Image('das', 3 x 2 x 4 (range x elevation x azimuth), 31250 Hz, range 0.5..0.7 m, "
        "elevation -10..10 deg, azimuth -30..30 deg)"
    )
    big = P.Image(np.zeros((0, 41, 91)), np.zeros(0), np.zeros(41), np.zeros(91), "music", 4e4)
    assert "0 x 41 x 91" in repr(big) and "range none" in repr(big) and len(repr(big)) < 200
