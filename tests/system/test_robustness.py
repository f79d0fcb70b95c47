"""Regression tests of issue 15's robustness findings: non-finite input, images with
no range bins, the zenith, extreme magnitudes, the solid angle at the poles."""

import numpy as np
import pytest

import processing as P
from processing.imaging.doa import doa_spectrum
from processing.imaging.metrics import cell_solid_angles
from tests.oracles.analytic import echo_recording, plane_wave_snapshot

F = 31250.0


def test_non_finite_samples_name_channel_and_sample():
    rec = echo_recording(P.paper_8x8(), [(0, 0, 1.0, 1.0)], n_samples=2048)
    x = rec.samples.copy()
    x[17, 1234] = np.nan
    with pytest.raises(P.InputError, match="channel 17, sample 1234"):
        rec.with_samples(x)
    x[17, 1234] = 0.0
    x[3, 5] = np.inf
    with pytest.raises(P.InputError, match="channel 3, sample 5"):
        rec.with_samples(x)
    snaps = np.ones((64, 4), complex)
    snaps[9, 2] = np.nan
    for method in ("das", "music", "capon", "music-fbss", "capon-fbss"):
        with pytest.raises(P.InputError, match="microphone 9, range bin 2"):
            doa_spectrum(
                snaps, P.paper_8x8(), F, P.Grid.degrees(elevation=(-90, 90), step=10), method
            )


def test_range_resolution_of_an_image_without_range_bins():
    g = P.Grid.degrees(elevation=(-90, 90), step=10)
    img = P.Image(np.zeros((0, *g.shape)), np.zeros(0), g.elevation_rad, g.azimuth_rad, "das", F)
    with pytest.raises(ValueError, match="no range bins"):
        P.range_resolution(img)
    assert P.range_profile(img).shape == (0,)


@pytest.mark.parametrize("method", ["capon", "capon-fbss", "das", "music-fbss"])
def test_one_peak_for_a_source_at_the_zenith(method):
    arr = P.paper_8x8()
    g = P.Grid.degrees(elevation=(-90, 90), step=2.0)
    x = plane_wave_snapshot(arr, 0, 90, F)[:, None]
    x = x + 0.01 * np.random.default_rng(0).standard_normal(x.shape)
    p = doa_spectrum(x, arr, F, g, method)
    img = P.Image(p, np.ones(1), g.elevation_rad, g.azimuth_rad, method, F)
    pk = img.peaks(threshold_db=-1)
    assert len(pk) == 1
    assert np.rad2deg(pk.elevation_rad[0]) == pytest.approx(90)


def test_cell_area_at_the_poles_is_the_cap_area():
    g = P.Grid.degrees((-180, 179), (-90, 90), 1.0)  # the full sphere
    a = cell_solid_angles(g.elevation_rad, g.azimuth_rad)
    cap = 2 * np.pi * (1 - np.cos(np.deg2rad(0.5)))  # the cells above 89.5 deg
    assert a[-1].sum() == pytest.approx(cap * 359 / 360, rel=1e-9)
    assert a[0].sum() == pytest.approx(cap * 359 / 360, rel=1e-9)
    assert a.sum() == pytest.approx(4 * np.pi * 359 / 360, rel=1e-9)


@pytest.mark.parametrize("method", P.NARROWBAND_METHODS)
def test_extreme_magnitudes_give_the_same_spectrum(method):
    arr = P.paper_8x8()
    g = P.Grid.degrees(elevation=(-90, 90), step=6.0)
    rng = np.random.default_rng(1)
    x = plane_wave_snapshot(arr, 20, -10, F)[:, None, None] * np.ones((1, 2, 3))
    x = x + 0.1 * (rng.standard_normal(x.shape) + 1j * rng.standard_normal(x.shape))
    ref = doa_spectrum(x, arr, F, g, method)
    for scale in (1e-160, 1e160):
        got = doa_spectrum(x * scale, arr, F, g, method)
        assert np.all(np.isfinite(got))
        np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12 * ref.max())


def test_an_empty_recording_images_to_no_range_bins_not_an_error():
    rec = echo_recording(P.paper_8x8(), [], n_samples=2048)
    img = P.acoustic_image(
        rec, "das", P.ProcessingSettings(grid=P.Grid.degrees(elevation=(-90, 90), step=10))
    )
    assert img.power.shape[0] == 0


@pytest.mark.parametrize("base", ["music", "capon"])
@pytest.mark.parametrize("n_snap", [1, 3, 20])
def test_eigen_shortcuts_equal_the_plain_eigendecomposition(base, n_snap):
    """Gram-matrix (S < L) and real unitary (FBSS) shortcuts against numpy's eigh."""
    from processing.imaging.doa import method_matrix
    from processing.imaging.smoothing import subarray_snapshots

    rng = np.random.default_rng(n_snap)
    Y = rng.standard_normal((4, 16, n_snap)) + 1j * rng.standard_normal((4, 16, n_snap))
    Y[:, :, 0] *= 10  # one strong direction
    C = Y @ Y.conj().transpose(0, 2, 1) / n_snap
    plain, _ = method_matrix(C, base)
    fast, _ = method_matrix(C, base, data=Y)
    np.testing.assert_allclose(fast, plain, rtol=1e-8, atol=1e-8 * np.abs(plain).max())
    xg = rng.standard_normal((6, 6, 3, n_snap)) + 1j * rng.standard_normal((6, 6, 3, n_snap))
    Yf = subarray_snapshots(xg, (4, 4), forward_backward=True)
    Cf = Yf @ Yf.conj().transpose(0, 2, 1) / Yf.shape[-1]
    Cf = 0.5 * (Cf + Cf[:, ::-1, ::-1].conj())
    plain, _ = method_matrix(Cf, base)
    fast, _ = method_matrix(Cf, base, centro=True)
    np.testing.assert_allclose(fast, plain, rtol=1e-8, atol=1e-8 * np.abs(plain).max())
