import warnings

import numpy as np
import pytest

import processing as P
from processing.base.errors import InputError


def test_ura_geometry_is_centred_with_pitch():
    a = P.ura(4, 3, (2e-3, 3e-3))
    assert a.n_mics == 12 and a.is_ura and a.grid_shape == (4, 3)
    np.testing.assert_allclose(a.positions_m.mean(axis=0), 0, atol=1e-15)
    np.testing.assert_allclose(np.unique(a.positions_m[:, 1]), [-3e-3, 0, 3e-3])
    np.testing.assert_allclose(np.unique(a.positions_m[:, 2]), [-3e-3, -1e-3, 1e-3, 3e-3])


def test_paper_array():
    a = P.paper_8x8()
    assert a.n_mics == 64 and a.pitch_m == (5e-3, 5e-3)
    assert a.aperture_m() == pytest.approx((35e-3, 35e-3))
    # 31.25 kHz is below the half-wavelength limit of a 5 mm pitch (34.3 kHz)
    assert a.alias_free_hz(343.0) == pytest.approx(34300.0)


def test_urtis_layout_matches_published_facts():
    a = P.urtis_v1()
    assert a.n_mics == 30 and a.grid_shape == (5, 6) and a.is_ura
    assert 15 not in a.channels and 31 not in a.channels
    # column-major channels: channel 0..4 are column 0, rows bottom to top
    assert a.positions_m[0, 1] == a.positions_m[4, 1] < a.positions_m[5, 1]
    assert a.positions_m[0, 2] < a.positions_m[4, 2]
    assert a.aperture_m() == pytest.approx((4 * 3.85e-3, 5 * 3.85e-3))
    order = a.grid_order()
    grid_y = a.positions_m[order, 1].reshape(5, 6)
    assert np.all(np.diff(grid_y, axis=1) > 0)


def test_coordinates_file_text_with_unused_channel(tmp_path):
    f = tmp_path / "layout.csv"
    f.write_text("# y, z in mm\n0,0\n10,0\nnan,nan\n0,10\n")
    a = P.from_coordinates_file(f, units="mm")
    assert a.n_mics == 3
    np.testing.assert_array_equal(a.channels, [0, 1, 3])
    np.testing.assert_allclose(a.positions_m.mean(axis=0), 0, atol=1e-15)
    assert not a.is_ura


def test_coordinates_file_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match="nope.csv"):
        P.from_coordinates_file(tmp_path / "nope.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("1,2,3\n4,5,6\n")
    with pytest.raises(ValueError, match="bad.csv.*shape"):
        P.from_coordinates_file(bad)
    with pytest.raises(ValueError, match="units"):
        P.from_coordinates_file(bad, units="inch")


def test_matlab_v73_coordinates_file(tmp_path):
    """A v7.3 .mat is HDF5 behind a 512-byte header, matrices stored column-major: an
    (M, 2) table is an HDF5 dataset of shape (2, M)."""
    import h5py

    yz_mm = np.array([[-10.0, 0.0], [10.0, 0.0], [0.0, 5.0], [np.nan, np.nan]])
    path = tmp_path / "layout.mat"
    with h5py.File(path, "w", userblock_size=512) as f:
        f["mic_pos_final_pos"] = yz_mm.T
    a = P.from_coordinates_file(path, units="mm")
    assert a.n_mics == 3 and a.channels.tolist() == [0, 1, 2]
    centroid = np.array([0.0, 5.0 / 3]) * 1e-3
    np.testing.assert_allclose(a.positions_m[:, 1:], yz_mm[:3] * 1e-3 - centroid, atol=1e-15)
    with pytest.raises(InputError, match="layout.mat.*no variable 'other'"):
        P.from_coordinates_file(path, variable="other")
    junk = tmp_path / "junk.mat"
    junk.write_bytes(b"not a matlab file at all" * 10)
    with pytest.raises(InputError, match="junk.mat"):
        P.from_coordinates_file(junk)


def test_ertis_preset_offline_is_an_input_error(monkeypatch, capsys):
    import processing.sensor.rtisdev as rtisdev
    from acousim.cli import main

    def offline(sensor):
        raise RuntimeError("could not download rtisdev with pip")

    monkeypatch.setattr(rtisdev, "layout_file", offline)
    with pytest.raises(InputError, match="ertis_v3d1.*rtisdev"):
        P.preset("ertis_v3d1")
    assert main(["scenes"]) == 0  # the other scenes are still listed
    out = capsys.readouterr().out
    assert "corridor.toml" in out and "rtisdev" in out


def test_unknown_preset_lists_choices():
    with pytest.raises(ValueError, match="paper_8x8"):
        P.preset("nope")


def test_ertis_layout_from_rtisdev_wheel():
    a = P.ertis_v3d1()
    assert a.n_mics == 32 and not a.is_ura
    # about 66 x 38 mm, centred
    assert a.aperture_m()[1] == pytest.approx(0.0665, abs=2e-3)
    assert a.aperture_m()[0] == pytest.approx(0.0376, abs=2e-3)
    np.testing.assert_allclose(a.positions_m.mean(axis=0), 0, atol=1e-12)


@pytest.mark.parametrize("pitch", [(0.0, 0.0), (np.nan, np.nan), (-1e-3, 1e-3), "ab"])
def test_ura_pitch_must_be_positive_and_finite(pitch):
    base = P.ura(2, 2, 5e-3)
    with pytest.raises(InputError, match="pitch_m"):
        P.Array("bad", base.positions_m, grid_index=base.grid_index, pitch_m=pitch)


@pytest.mark.parametrize(
    "args,want",
    [
        ((0, 4, 4e-3), r"^ura: n_rows = 0: outside the allowed range \[1, 1048576\]$"),
        ((4, 2.5, 4e-3), r"^ura: n_cols = 2.5: must be a whole number"),
        ((4, 4, 0.0), r"^ura: pitch_m = 0.0: outside the allowed range \[1e-05, 0.5\] m$"),
        ((4, 4, np.nan), r"^ura: pitch_m = nan: must be a number .* not NaN$"),
        ((4, 4, (4e-3, -1e-3)), r"^ura: pitch_m = -0.001: outside the allowed range"),
        ((4, 4, (1e-3, 2e-3, 3e-3)), r"^ura: pitch_m = \(0.001, 0.002, 0.003\): must be a number"),
        # millimetres given as metres: refused, saying what was probably meant
        (
            (4, 4, 4),
            r"^ura: pitch_m = 4: .*\[1e-05, 0.5\] m; metres expected: did you mean 4 mm, "
            r"pitch_m=0.004\?$",
        ),
    ],
)
def test_ura_arguments_are_input_errors_naming_the_argument(args, want):
    with pytest.raises(InputError, match=want):
        P.ura(*args)


def test_ura_accepts_large_and_small_plausible_pitches():
    big = P.ura(2, 3, 0.5)  # a large (audio) array
    assert big.aperture_m() == pytest.approx((0.5, 1.0))
    tiny = P.ura(2, 2, (1e-5, 2e-5))
    assert tiny.pitch_m == (1e-5, 2e-5)


def test_coordinates_in_millimetres_given_as_metres_warn():
    with pytest.warns(P.UnitsWarning, match=r"coordinates reach 4 m .* would reach 0.004 m") as got:
        P.from_coordinates(np.array([[0.0, 0.0], [4.0, 0.0]]))
    assert got[0].filename == __file__  # points at the caller's line
    with warnings.catch_warnings():
        warnings.simplefilter("error", P.UnitsWarning)
        wide = P.from_coordinates(np.array([[-0.75, 0.0], [0.75, 0.0]]))  # a 1.5 m array
    assert wide.aperture_m()[1] == pytest.approx(1.5)
