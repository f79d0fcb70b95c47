import numpy as np
import pytest

import processing as P
from processing.imaging.doa import SubspaceOptions, doa_spectrum
from tests.oracles.analytic import direction, echo_recording, plane_wave_snapshot

F, C = 31250.0, 343.0
SMOOTHED = ["music-fss", "music-fbss", "capon-fss", "capon-fbss"]


def peak_deg(power, grid):
    r, e, a = np.unravel_index(np.argmax(power), power.shape)
    return np.rad2deg(grid.azimuth_rad[a]), np.rad2deg(grid.elevation_rad[e])


@pytest.mark.parametrize("method", P.NARROWBAND_METHODS)
@pytest.mark.parametrize("az,el", [(0, 0), (23, -11), (-47, 31), (60, 60)])
def test_plane_wave_peaks_at_its_direction(method, az, el):
    arr = P.paper_8x8()
    grid = P.Grid.degrees(elevation=(-90, 90), step=1.0)
    rng = np.random.default_rng(0)
    x = plane_wave_snapshot(arr, az, el, F)[:, None]
    x = x + 0.01 * (rng.standard_normal(x.shape) + 1j * rng.standard_normal(x.shape))
    got = peak_deg(doa_spectrum(x, arr, F, grid, method), grid)
    assert got == pytest.approx((az, el), abs=1.0)


def test_time_domain_plane_wave_pins_the_sign_convention():
    """A far reflector at (+35, +20) must image at (+35, +20), not the mirror."""
    arr = P.paper_8x8()
    rec = echo_recording(arr, [(35, 20, 3.0, 1.0)], n_samples=12000)
    settings = P.ProcessingSettings(
        frequency_hz=F,
        grid=P.Grid.degrees(elevation=(-90, 90), step=1.0),
        energy_fraction=0.5,  # the paper's gate
    )
    for method in ["das", "music-fbss", "capon-fbss"]:
        img = P.acoustic_image(rec, method, settings)
        pk = img.peaks(-1, max_peaks=1)
        assert np.rad2deg(pk.azimuth_rad[0]) == pytest.approx(35, abs=1)
        assert np.rad2deg(pk.elevation_rad[0]) == pytest.approx(20, abs=1)
        assert pk.range_m[0] == pytest.approx(3.0, abs=0.02)


def test_das_beamwidth_matches_array_theory():
    # 8 elements at 5 mm, broadside: half-power points where |sin(N psi/2)/(N sin(psi/2))|^2
    # = 1/2 with psi = k d sin(az)
    arr = P.paper_8x8()
    grid = P.Grid(np.deg2rad(np.arange(-30, 30.001, 0.05)), np.array([0.0]))
    x = plane_wave_snapshot(arr, 0, 0, F)[:, None]
    cut = doa_spectrum(x, arr, F, grid, "das")[0, 0]
    cut = cut / cut.max()
    above = np.rad2deg(grid.azimuth_rad[cut >= 0.5])
    k, d, N = 2 * np.pi * F / C, 5e-3, 8
    psi = np.linspace(1e-6, np.pi / 2, 200001)
    af = (np.sin(N * psi / 2) / (N * np.sin(psi / 2))) ** 2
    psi3 = psi[np.argmin(np.abs(af - 0.5))]
    theory = 2 * np.rad2deg(np.arcsin(psi3 / (k * d)))
    assert above[-1] - above[0] == pytest.approx(theory, abs=0.1)


@pytest.mark.parametrize("K", [1, 2])  # 1: every method on the low-rank co-array path
@pytest.mark.parametrize("method", P.NARROWBAND_METHODS)
def test_coarray_fast_path_equals_plain_formula(method, K):
    arr = P.paper_8x8()
    grid = P.Grid.degrees(elevation=(-90, 90), step=7.0)
    rng = np.random.default_rng(5)
    x = (
        plane_wave_snapshot(arr, 20, 10, F)[:, None, None] * rng.standard_normal((1, 3, K))
        + plane_wave_snapshot(arr, -40, 0, F)[:, None, None]
        + 0.1 * (rng.standard_normal((64, 3, K)) + 1j * rng.standard_normal((64, 3, K)))
    )
    fast = doa_spectrum(x, arr, F, grid, method, backend="coarray")
    plain = doa_spectrum(x, arr, F, grid, method, backend="direct") if "-" not in method else None
    if plain is None:  # smoothed: compare with explicit steering of the subarray
        plain = _direct_smoothed(x, arr, grid, method)
    np.testing.assert_allclose(fast, plain, rtol=1e-7, atol=1e-12 * plain.max())


@pytest.mark.parametrize("K", [1, 3])  # 1: the low-rank paths; 3: the eigendecompositions
@pytest.mark.parametrize("array", ["ura", "ertis"])
@pytest.mark.parametrize("backend", ["auto", "direct"])
def test_spectra_together_are_each_methods_own(K, array, backend):
    """doa_spectra shares the arrangement and the eigendecompositions between the
    methods: every spectrum is the one doa_spectrum gives alone, to the bit, in any
    order of the methods."""
    arr = P.paper_8x8() if array == "ura" else P.ertis_v3d1()
    methods = [m for m in P.NARROWBAND_METHODS if array == "ura" or "-" not in m]
    if backend == "direct":
        methods = [m for m in methods if "-" not in m]
    grid = P.Grid.degrees(elevation=(-60, 60), step=9.0)
    rng = np.random.default_rng(11)
    M = arr.n_mics
    x = plane_wave_snapshot(arr, 20, 10, F)[:, None, None] * rng.standard_normal(
        (1, 4, K)
    ) + 0.1 * (rng.standard_normal((M, 4, K)) + 1j * rng.standard_normal((M, 4, K)))
    for order in (methods, methods[::-1]):
        together = P.doa_spectra(x, arr, F, grid, order, backend=backend)
        assert list(together) == order
        for m in order:
            alone = doa_spectrum(x, arr, F, grid, m, backend=backend)
            np.testing.assert_array_equal(together[m], alone, err_msg=m)


def _direct_smoothed(x, arr, grid, method):
    from processing.imaging.doa import method_matrix
    from processing.imaging.smoothing import smoothed_covariance
    from processing.imaging.steering import quadratic_form_direct, steering_matrix

    base, smooth = method.split("-")
    x = x / np.abs(x).max()  # the documented scale: relative to the largest snapshot
    xg = x[arr.grid_order()].reshape(8, 8, *x.shape[1:])
    Cs = smoothed_covariance(xg, (5, 5), forward_backward=smooth == "fbss")
    Q, inverse = method_matrix(Cs, base)
    sub = P.ura(5, 5, 5e-3)
    form = quadratic_form_direct(Q, steering_matrix(sub.positions_m, grid, F, C))
    if not inverse:
        return form
    if base == "music":
        return 1 / np.maximum(form, 25e-12)
    return 1 / form


def test_urtis_smoothing_and_irregular_array_refusal():
    arr = P.urtis_v1()
    grid = P.Grid.degrees(elevation=(-90, 90), step=1.0)
    x = plane_wave_snapshot(arr, -25, 15, 27000.0)[:, None]
    for method in ["music-fbss", "capon-fbss"]:
        got = peak_deg(doa_spectrum(x, arr, 27000.0, grid, method), grid)
        assert got == pytest.approx((-25, 15), abs=1.0)
    irregular = P.from_coordinates(np.random.default_rng(0).uniform(-0.02, 0.02, (12, 2)))
    xi = plane_wave_snapshot(irregular, 10, 5, 27000.0)[:, None]
    with pytest.raises(ValueError, match="uniform rectangular array.*irregular"):
        doa_spectrum(xi, irregular, 27000.0, grid, "music-fbss")
    for method in ["das", "music", "capon"]:
        got = peak_deg(
            doa_spectrum(
                xi, irregular, 27000.0, P.Grid.degrees(elevation=(-90, 90), step=2.0), method
            ),
            P.Grid.degrees(elevation=(-90, 90), step=2.0),
        )
        assert got == pytest.approx((10, 5), abs=2.0)


def test_two_coherent_sources_need_smoothing():
    """Coherent echoes at one range: FBSS methods resolve them."""
    arr = P.paper_8x8()
    grid = P.Grid(np.deg2rad(np.arange(-60, 60.1, 0.5)), np.array([0.0]))
    x = (plane_wave_snapshot(arr, -20, 0, F) + plane_wave_snapshot(arr, 20, 0, F))[:, None]
    for method in ["music-fbss", "capon-fbss"]:
        cut = doa_spectrum(x, arr, F, grid, method)[0, 0]
        att = P.max_attenuation(cut, grid.azimuth_rad, np.deg2rad(-20), np.deg2rad(20))
        assert att > 10


def test_unknown_method_and_bad_shapes():
    arr = P.paper_8x8()
    with pytest.raises(ValueError, match="method = 'bogus': unknown DOA method.*das"):
        doa_spectrum(
            np.ones((64, 1)), arr, F, P.Grid.degrees(elevation=(-90, 90), step=10), "bogus"
        )
    for loose in ("DAS", "capon_fbss", " das"):  # one spelling, checked in one place
        with pytest.raises(P.InputError if hasattr(P, "InputError") else ValueError):
            doa_spectrum(
                np.ones((64, 1)), arr, F, P.Grid.degrees(elevation=(-90, 90), step=10), loose
            )
        with pytest.raises(ValueError, match="unknown method"):
            P.check_method(loose)
    with pytest.raises(ValueError, match="M=64"):
        doa_spectrum(np.ones((10, 1)), arr, F, P.Grid.degrees(elevation=(-90, 90), step=10), "das")
    with pytest.raises(ValueError, match="loading"):
        doa_spectrum(
            np.ones((64, 1)),
            arr,
            F,
            P.Grid.degrees(elevation=(-90, 90), step=10),
            "capon",
            options=SubspaceOptions(loading=-1),
        )


def test_direction_convention_helper():
    np.testing.assert_allclose(direction(90, 0), [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(direction(0, 90), [0, 0, 1], atol=1e-15)


@pytest.mark.parametrize("S", [2, 3, 5])  # by FFT (L > 4 S) and by the formed matrix
def test_coarray_coefficients_of_low_rank_factors_equal_the_lag_sums(S):
    """c0 I + U diag(d) U^H summed along each co-array lag, written out in the test."""
    from processing.imaging.steering import coarray_kernel

    nz, ny, R = 4, 3, 2
    rng = np.random.default_rng(3)
    U = rng.standard_normal((R, nz * ny, S)) + 1j * rng.standard_normal((R, nz * ny, S))
    d, c0 = rng.standard_normal((R, S)), rng.standard_normal(R)
    kern = coarray_kernel(
        (nz, ny), (5e-3, 5e-3), P.Grid.degrees(elevation=(-90, 90), step=30.0), F, C
    )
    got = kern.coefficients_low_rank(c0, U, d)
    want = np.zeros((R, 2 * nz - 1, 2 * ny - 1), complex)
    for r in range(R):
        Q = c0[r] * np.eye(nz * ny) + (U[r] * d[r]) @ U[r].conj().T
        for m in range(nz * ny):
            for n in range(nz * ny):  # Q[m, n] belongs to the lag of n - m
                lz = n // ny - m // ny + nz - 1
                ly = n % ny - m % ny + ny - 1
                want[r, lz, ly] += Q[m, n]
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_coarray_coefficients_of_unitary_transform_equal_the_lag_sums():
    """Q = T Qr T^H (real symmetric Qr, any unitary T) summed along each co-array lag."""
    from processing.imaging.steering import coarray_kernel

    nz, ny, R = 3, 4, 2
    L = nz * ny
    rng = np.random.default_rng(5)
    A = rng.standard_normal((R, L, L))
    Qr = A + A.transpose(0, 2, 1)
    T, _ = np.linalg.qr(rng.standard_normal((L, L)) + 1j * rng.standard_normal((L, L)))
    kern = coarray_kernel(
        (nz, ny), (5e-3, 5e-3), P.Grid.degrees(elevation=(-90, 90), step=30.0), F, C
    )
    got = kern.coefficients_unitary(Qr, T)
    want = np.zeros((R, 2 * nz - 1, 2 * ny - 1), complex)
    for r in range(R):
        Q = T @ Qr[r] @ T.conj().T
        for m in range(L):
            for n in range(L):  # Q[m, n] belongs to the lag of n - m
                want[r, n // ny - m // ny + nz - 1, n % ny - m % ny + ny - 1] += Q[m, n]
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_compiled_floor_and_reciprocal_equal_numpy():
    pytest.importorskip("numba")
    from processing.imaging.doa_kernel import floor_invert

    x = np.random.default_rng(0).standard_normal((7, 9))
    for floor, invert in ((1e-3, True), (0.0, False)):
        got = x.copy()
        floor_invert(got, floor, invert)
        want = np.maximum(x, floor)
        np.testing.assert_array_equal(got, 1 / want if invert else want)


@pytest.mark.parametrize("sub", [(4, 4), (5, 6), (3, 7)])
@pytest.mark.parametrize("method", ["capon-fbss", "music-fbss"])
def test_real_fbss_coarray_path_equals_the_complex_direct_formula(method, sub):
    """The co-array FBSS path (real covariance, real Q, folded lag map) against the
    direct route: complex covariance, complex eigh, explicit steering vectors."""
    arr = P.paper_8x8()
    grid = P.Grid.degrees(elevation=(-90, 90), step=6.0)
    rng = np.random.default_rng(11)
    x = rng.standard_normal((64, 3)) + 1j * rng.standard_normal((64, 3))
    x += np.exp(1j * 2 * np.pi * F / C * arr.positions_m @ direction(25, -10))[:, None]
    opts = SubspaceOptions(subarray=sub)
    fast = doa_spectrum(x, arr, F, grid, method, options=opts)
    plain = doa_spectrum(x, arr, F, grid, method, options=opts, backend="direct")
    np.testing.assert_allclose(fast, plain, rtol=1e-9)


@pytest.mark.parametrize("bad", [-1e-3, 1.5, float("nan")])
def test_an_eig_floor_outside_0_1_is_refused_by_every_entry(bad):
    """The declared range [0, 1] holds for the options, the settings and the public
    method_matrix, each naming its key and the value."""
    from processing.imaging.doa import method_matrix

    C = np.eye(4, dtype=complex)[None]
    entries = {
        "SubspaceOptions.eig_floor": lambda: SubspaceOptions(eig_floor=bad),
        "ProcessingSettings.eig_floor": lambda: P.ProcessingSettings(eig_floor=bad),
        "eig_floor": lambda: method_matrix(C, "capon", eig_floor=bad),
    }
    for key, make in entries.items():
        with pytest.raises(P.InputError) as err:
            make()
        assert err.value.key == key and str(bad) in str(err.value)
    assert method_matrix(C, "capon", eig_floor=1.0)[1]  # the ends are allowed
    assert SubspaceOptions(eig_floor=0.0).eig_floor == 0.0


@pytest.mark.parametrize("K", [1, 3])  # 1: the low-rank paths; 3: the eigendecompositions
@pytest.mark.parametrize("method", ["capon", "capon-fbss"])
def test_capon_eig_floor_option_reaches_every_path(method, K):
    """``eig_floor`` (default 1e-3, the former fixed EIG_FLOOR): the eigenvalues are
    floored at eig_floor * trace / L, loaded by -0.5 times the smallest, inverted;
    against that formula written here with numpy's eigh."""
    from processing.imaging.smoothing import smoothed_covariance
    from processing.imaging.steering import quadratic_form_direct, steering_matrix

    assert P.ProcessingSettings().eig_floor == SubspaceOptions().eig_floor == 1e-3
    arr = P.paper_8x8()
    grid = P.Grid.degrees(elevation=(-60, 60), step=9.0)
    rng = np.random.default_rng(7)
    x = plane_wave_snapshot(arr, 20, 10, F)[:, None, None] * rng.standard_normal(
        (1, 2, K)
    ) + 0.01 * (rng.standard_normal((64, 2, K)) + 1j * rng.standard_normal((64, 2, K)))
    default = doa_spectrum(x, arr, F, grid, method)
    same = doa_spectrum(x, arr, F, grid, method, options=SubspaceOptions(eig_floor=1e-3))
    np.testing.assert_array_equal(default, same)
    got = doa_spectrum(x, arr, F, grid, method, options=SubspaceOptions(eig_floor=0.05))
    assert not np.allclose(got, default, rtol=1e-3)

    xs = x / np.abs(x).max()
    if method == "capon":
        R = np.einsum("mrk,nrk->rmn", xs, xs.conj()) / K
        positions = arr.positions_m
    else:
        xg = xs[arr.grid_order()].reshape(8, 8, *xs.shape[1:])
        R = smoothed_covariance(xg, (5, 5), forward_backward=True)
        positions = P.ura(5, 5, 5e-3).positions_m
    w, U = np.linalg.eigh(R)
    w = np.maximum(w, 0.05 * w.sum(-1, keepdims=True) / R.shape[-1])
    mu = w - 0.5 * w.min(-1, keepdims=True)
    Q = (U / mu[:, None, :]) @ U.conj().transpose(0, 2, 1)
    ref = 1 / quadratic_form_direct(Q, steering_matrix(positions, grid, F, C))
    np.testing.assert_allclose(got, ref, rtol=1e-6)
