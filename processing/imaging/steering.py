"""Direction grids, steering vectors and fast evaluation of steered quadratic forms.

Sign convention (pinned by ``tests/processing/imaging/test_doa.py::test_time_domain_plane_wave``):
transforms here use the usual ``exp(-j w t)`` kernel (numpy/scipy FFT and STFT), so a
wave from direction u reaches microphone m *earlier* by ``u . p_m / c`` and its
narrow-band snapshot is proportional to ``exp(+j k u . p_m)``.  The steering vector
is therefore::

    a_m(az, el) = exp(+j 2 pi f / c * (sin(az) cos(el) y_m + sin(el) z_m))

Eq. 7 of the paper prints the opposite sign; used with an ``exp(-j w t)`` transform
it steers to the mirror direction (-az, -el).

Every spectrum of :mod:`processing.imaging.doa` is a quadratic form ``a^H Q a`` over the grid.
For a URA, ``a^H Q a = sum_d c[d] exp(j k (v dy_d + w dz_d))`` where ``c`` sums Q
along the difference co-array (2Nz-1 x 2Ny-1 lags), v = sin(az) cos(el) and
w = sin(el).  Summing first over the z lags (per elevation) and then over the y lags
(a real matrix product, using ``c[-d] = conj(c[d])``) costs O(E (R Ny A)) instead of
O(E A R M^2): this is :class:`CoarrayKernel`.  When ``Q = c0 I + U diag(d) U^H`` with
few columns (fewer snapshots than microphones), the co-array coefficients are 2D
autocorrelations of U's columns (zero-padded FFTs), so Q is never formed.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
import scipy.sparse as sp
from scipy import fft as sfft

from processing.base.errors import InputError, UnitsWarning
from processing.base.kernels import optional_kernel
from processing.base.settings import Setting, check
from processing.sensor.arrays import Array

__all__ = [
    "Grid",
    "GRID_AZIMUTH_DEG",
    "GRID_ELEVATION_DEG",
    "GRID_STEP_DEG",
    "FREQUENCY_HZ",
    "GratingLobeWarning",
    "check_frequency",
    "warn_grating_lobes",
    "steering_matrix",
    "CoarrayKernel",
    "coarray_kernel",
    "quadratic_form_direct",
]

#: the default grid's azimuths (min, max) in degrees, of every entry: ``Grid.degrees()``,
#: :class:`processing.ProcessingSettings`, ``acousim image`` and its pictures
GRID_AZIMUTH_DEG = (-90.0, 90.0)
#: the default grid's elevations (min, max) in degrees (the sensors' field of view: a
#: grid to +-90 degrees adds the poles, where every azimuth is one direction)
GRID_ELEVATION_DEG = (-40.0, 40.0)
#: the default grid's step in degrees
GRID_STEP_DEG = 2.0

#: the steering frequency, declared once: every entry that takes a ``frequency_hz``
#: (:func:`steering_matrix`, :func:`processing.doa_spectrum`,
#: :class:`processing.ProcessingSettings`) checks it against this (NaN, 0 and negative
#: frequencies refused)
FREQUENCY_HZ = Setting("float", None, "Hz", 1.0, 1e9, "steering frequency")


class GratingLobeWarning(UserWarning):
    """A uniform array steered above its alias-free frequency
    (:meth:`processing.Array.alias_free_hz`): every echo also appears, as strong, at
    grating-lobe directions (docs/processing.md, "Grating lobes")."""


def check_frequency(frequency_hz: float, key: str = "frequency_hz") -> float:
    """`frequency_hz` as a float, or an InputError naming `key` and the value when it is
    not a number in :data:`FREQUENCY_HZ`'s range (NaN, 0, negative)."""
    return float(check(FREQUENCY_HZ, frequency_hz, key))


def warn_grating_lobes(array: Array, frequency_hz: float, speed_of_sound_m_s: float) -> None:
    """A :class:`GratingLobeWarning` when `array` (a URA: an irregular layout has no
    periodic grating lobes) is steered at `frequency_hz` above its alias-free limit
    ``c / (2 pitch)``."""
    limit = array.alias_free_hz(speed_of_sound_m_s)
    if frequency_hz <= limit or array.pitch_m is None:
        return
    dz, dy = array.pitch_m
    warnings.warn(
        f"steering frequency {frequency_hz:.0f} Hz is above the alias-free limit "
        f"{limit:.0f} Hz of array {array.name!r} ({dy * 1e3:g} x {dz * 1e3:g} mm pitch, "
        f"c = {speed_of_sound_m_s:g} m/s): an echo can also appear, as strong, at a grating "
        f"lobe, where cos(el) sin(az) differs by {speed_of_sound_m_s / (frequency_hz * dy):.3g} "
        f"or sin(el) by {speed_of_sound_m_s / (frequency_hz * dz):.3g}; frequency_hz=None "
        "picks the strongest frequency below the limit",
        GratingLobeWarning,
        stacklevel=3,
    )


@dataclass(frozen=True, eq=False)
class Grid:
    """A product grid of directions: every azimuth at every elevation.

    Attributes
    ----------
    azimuth_rad : ndarray, shape (A,)
    elevation_rad : ndarray, shape (E,)
    """

    azimuth_rad: np.ndarray
    elevation_rad: np.ndarray

    def __post_init__(self) -> None:
        for name in ("azimuth_rad", "elevation_rad"):
            v = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if v.ndim != 1 or v.size == 0 or not np.all(np.isfinite(v)):
                raise InputError(f"grid {name} must be a non-empty finite 1-D array")
            if v.size > 1 and np.any(np.diff(v) <= 0):
                raise InputError(f"grid {name} must be strictly increasing")
            object.__setattr__(self, name, v)
        if np.any(np.abs(self.elevation_rad) > np.pi / 2 + 1e-12):
            raise InputError("grid elevations must lie in [-90, 90] degrees")

    def __repr__(self) -> str:
        az, el = np.rad2deg(self.azimuth_rad), np.rad2deg(self.elevation_rad)
        return (
            f"Grid(azimuth {az[0]:g}..{az[-1]:g} deg x {az.size}, "
            f"elevation {el[0]:g}..{el[-1]:g} deg x {el.size})"
        )

    @classmethod
    def degrees(
        cls,
        azimuth: tuple[float, float] = GRID_AZIMUTH_DEG,
        elevation: tuple[float, float] = GRID_ELEVATION_DEG,
        step: float | tuple[float, float] = GRID_STEP_DEG,
    ) -> Grid:
        """A regular grid from (min, max) limits and a step, all in degrees (inclusive).

        The defaults are the command line's (:data:`GRID_AZIMUTH_DEG`,
        :data:`GRID_ELEVATION_DEG`, :data:`GRID_STEP_DEG`): azimuth -90..90, elevation
        -40..40, every 2 degrees."""
        s_az, s_el = (step, step) if isinstance(step, int | float | np.number) else step
        if not (s_az > 0 and s_el > 0):
            raise InputError(f"grid step must be positive, got {step}")
        for key, limits in (("azimuth", azimuth), ("elevation", elevation)):
            _warn_radians(f"Grid.degrees: {key}", limits)

        def axis(lo: float, hi: float, step: float) -> np.ndarray:
            n = int(np.floor((hi - lo) / step + 1e-9))
            return lo + step * np.arange(n + 1)

        return cls(np.deg2rad(axis(*azimuth, s_az)), np.deg2rad(axis(*elevation, s_el)))

    @property
    def shape(self) -> tuple[int, int]:
        """(E, A)."""
        return self.elevation_rad.size, self.azimuth_rad.size

    def directions(self) -> np.ndarray:
        """Unit vectors, shape (E, A, 3)."""
        el = self.elevation_rad[:, None]
        az = self.azimuth_rad[None, :]
        return np.stack(
            np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)),
            axis=-1,
        )


def _warn_radians(key: str, limits) -> None:
    """A :class:`UnitsWarning` when (min, max) limits asked in degrees look like radians:
    a span under 2 pi degrees (6.3) whose ends include +-pi/2 or +-pi (1.57, 3.14) to
    within 0.01, e.g. (-1.57, 1.57) for -90..90 degrees.  A narrow grid in degrees
    (-2..2 every 0.1, a resolution test) never ends there."""
    try:
        lo, hi = (float(v) for v in limits)
    except (TypeError, ValueError):
        return
    ends = [abs(v) for v in (lo, hi) if v != 0]
    if not ends or not hi - lo < 2 * np.pi + 0.02:
        return
    if all(min(abs(v - np.pi / 2), abs(v - np.pi)) < 0.01 for v in ends):
        meant = tuple(round(float(np.rad2deg(v)), 1) for v in (lo, hi))
        warnings.warn(
            f"{key} = {tuple(limits)!r} spans only {hi - lo:.3g} degrees and ends at +-pi/2 "
            f"or +-pi: radians given as degrees? In degrees they are {meant!r}",
            UnitsWarning,
            stacklevel=4,  # the caller of Grid.degrees (through its keyword check)
        )


def steering_matrix(
    positions_m: np.ndarray, grid: Grid, frequency_hz: float, speed_of_sound_m_s: float
) -> np.ndarray:
    """Steering vectors for every grid direction, shape (E, A, M), complex128
    (`frequency_hz` checked: :func:`check_frequency`)."""
    k = 2 * np.pi * check_frequency(frequency_hz) / speed_of_sound_m_s
    return np.exp(1j * k * (grid.directions() @ np.asarray(positions_m).T))


def quadratic_form_direct(Q: np.ndarray, steering: np.ndarray) -> np.ndarray:
    """``Re(a^H Q a)`` for explicit steering vectors: the plain formula, any array.

    Q : (R, M, M) Hermitian; steering : (E, A, M).  Returns (R, E, A).
    """
    E, A, M = steering.shape
    S = steering.reshape(E * A, M)
    out = np.empty((Q.shape[0], E * A))
    for r in range(Q.shape[0]):
        out[r] = np.einsum("gm,gm->g", S.conj(), S @ Q[r].T).real
    return out.reshape(-1, E, A)


class CoarrayKernel:
    """Fast ``a^H Q a`` over a product grid for a uniform rectangular (sub)array.

    Parameters
    ----------
    shape : (Nz, Ny)
        Rows and columns of the (sub)array; Q is indexed in row-major grid order.
    pitch_m : (dz, dy)
    grid : Grid
    frequency_hz, speed_of_sound_m_s : float
    """

    def __init__(
        self,
        shape: tuple[int, int],
        pitch_m: tuple[float, float],
        grid: Grid,
        frequency_hz: float,
        speed_of_sound_m_s: float,
    ) -> None:
        self.shape = (int(shape[0]), int(shape[1]))
        self.pitch_m = pitch_m
        self.grid = grid
        self.k = 2 * np.pi * frequency_hz / speed_of_sound_m_s

    @cached_property
    def _scatter(self) -> sp.csr_matrix:
        """Sparse (K, L*L) map from Q's entries to co-array lags, K = (2Nz-1)(2Ny-1)."""
        nz, ny = self.shape
        L = nz * ny
        row, col = np.divmod(np.arange(L), ny)
        dz = row[None, :] - row[:, None] + nz - 1  # [m, n] -> lag of n - m
        dy = col[None, :] - col[:, None] + ny - 1
        lag = (dz * (2 * ny - 1) + dy).ravel()
        return sp.csr_matrix(
            (np.ones(L * L), (lag, np.arange(L * L))), shape=((2 * nz - 1) * (2 * ny - 1), L * L)
        )

    @cached_property
    def _z_phase(self) -> np.ndarray:
        """exp(j k sin(el) dz lag), shape (2Nz-1, E)."""
        nz = self.shape[0]
        lags = np.arange(-(nz - 1), nz) * self.pitch_m[0]
        return np.exp(1j * self.k * lags[:, None] * np.sin(self.grid.elevation_rad)[None, :])

    @cached_property
    def _y_basis(self) -> np.ndarray:
        """Real basis [1, 2cos(k v dy l), -2sin(k v dy l)] for l = 1..Ny-1: (E, 2Ny-1, A)."""
        ny = self.shape[1]
        v = np.cos(self.grid.elevation_rad)[:, None] * np.sin(self.grid.azimuth_rad)[None, :]
        lags = np.arange(1, ny) * self.pitch_m[1]
        phase = self.k * lags[None, :, None] * v[:, None, :]  # (E, Ny-1, A)
        E, A = v.shape
        return np.concatenate([np.ones((E, 1, A)), 2 * np.cos(phase), -2 * np.sin(phase)], axis=1)

    def coefficients(self, Q: np.ndarray) -> np.ndarray:
        """Co-array coefficients of Hermitian Q (R, L, L): shape (R, 2Nz-1, 2Ny-1)."""
        R, L, _ = Q.shape
        nz, ny = self.shape
        if L != nz * ny:
            raise InputError(f"Q is {L}x{L}, expected {nz * ny} for a {nz}x{ny} array")
        c = self._scatter @ Q.reshape(R, L * L).T  # (K, R)
        return c.T.reshape(R, 2 * nz - 1, 2 * ny - 1)

    def coefficients_unitary(self, Qr: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Co-array coefficients of ``Q = T Qr T^H`` from real symmetric Qr (R, L, L)
        and a fixed unitary T (L, L), without forming the complex Q: the map from the
        L (L + 1) / 2 entries of Qr's upper triangle to the real and imaginary parts of
        the lag sums is one real (L (L + 1) / 2, 2K) matrix, cached per T, applied as
        one real matrix product.  Returns (R, 2Nz-1, 2Ny-1), as :meth:`coefficients`.
        """
        R, L, _ = Qr.shape
        nz, ny = self.shape
        if L != nz * ny:
            raise InputError(f"Qr is {L}x{L}, expected {nz * ny} for a {nz}x{ny} array")
        cache = self.__dict__.setdefault("_unitary_maps", {})
        key = T.tobytes()
        if key not in cache:  # vec(T Qr T^H) = kron(T, conj T) vec(Qr), row-major
            M = np.asarray((self._scatter @ np.kron(T, T.conj())).T).reshape(L, L, -1)
            iu = np.triu_indices(L)
            Ms = M + M.transpose(1, 0, 2)  # Qr[i, j] = Qr[j, i]: fold the pairs
            Ms[np.arange(L), np.arange(L)] = M[np.arange(L), np.arange(L)]
            Ms = Ms[iu]
            cache[key] = (iu, np.ascontiguousarray(np.concatenate([Ms.real, Ms.imag], axis=1)))
        iu, Mri = cache[key]
        q = Qr[:, iu[0], iu[1]]  # (R, L (L + 1) / 2)
        # products of 4 bins at a time stay under OpenBLAS's threading threshold: a
        # threaded GEMM here leaves spinning workers that slow down what follows
        pad = -R % 4
        if pad:
            q = np.concatenate([q, np.zeros((pad, q.shape[1]))])
        ri = (q.reshape(-1, 4, q.shape[1]) @ Mri).reshape(-1, Mri.shape[1])[:R]  # (R, 2K)
        K = Mri.shape[1] // 2
        c = ri[:, :K] + 1j * ri[:, K:]
        return c.reshape(R, 2 * nz - 1, 2 * ny - 1)

    def coefficients_low_rank(self, c0: np.ndarray, U: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Co-array coefficients of ``Q = c0 I + U diag(d) U^H`` without forming Q.

        c0 : (R,) real; U : (R, L, S) complex; d : (R, S) real.  The coefficient of
        lag l is ``sum_s d_s sum_m U[m, s] conj(U[m + l, s])`` (a 2D autocorrelation of
        each column on the grid, by zero-padded FFT) plus ``L c0`` at lag 0.  With many
        columns (L <= 4 S, e.g. the 16 of a smoothed 5x5 subarray) forming
        ``U diag(d) U^H`` and summing its lags is cheaper than S FFTs, and is used.
        Returns (R, 2Nz-1, 2Ny-1), as :meth:`coefficients`.
        """
        R, L, S = U.shape
        nz, ny = self.shape
        if L != nz * ny:
            raise InputError(f"U has {L} rows, expected {nz * ny} for a {nz}x{ny} array")
        if L <= 4 * S:
            c = self.coefficients((U * d[:, None, :]) @ U.conj().transpose(0, 2, 1))
            c[:, nz - 1, ny - 1] += L * np.asarray(c0, dtype=float)
            return c
        g = U.reshape(R, nz, ny, S)
        spec = sfft.fft2(g, s=(2 * nz, 2 * ny), axes=(1, 2))
        power = np.einsum("rzys,rs->rzy", spec.real**2 + spec.imag**2, d)
        corr = sfft.ifft2(power, axes=(1, 2))  # corr[l] = sum d U[m + l] conj(U[m])
        iz = np.arange(-(nz - 1), nz) % (2 * nz)
        iy = np.arange(-(ny - 1), ny) % (2 * ny)
        c = corr[:, iz][:, :, iy].conj()
        c[:, nz - 1, ny - 1] += L * np.asarray(c0, dtype=float)
        return c

    def evaluate(
        self, coeffs: np.ndarray, *, floor: float | None = None, invert: bool = False
    ) -> np.ndarray:
        """``Re(a^H Q a)`` from co-array coefficients (R, 2Nz-1, 2Ny-1): (R, E, A).

        `floor`: the form is raised to at least `floor`; `invert`: then replaced by its
        reciprocal (MUSIC and Capon spectra).  Both are applied to each elevation's
        block while it is in cache, instead of in passes over the whole image.
        The result is a transposed view of a C-contiguous (E, R, A) array.
        """
        ny = self.shape[1]
        R = coeffs.shape[0]
        # sum over z lags first, only for y lags >= 0 (the others are conjugates)
        cz = coeffs[:, :, ny - 1 :].transpose(0, 2, 1)  # (R, Ny, 2Nz-1)
        h = (cz @ self._z_phase).transpose(2, 0, 1)  # (E, R, Ny)
        H = np.concatenate([h.real, h[:, :, 1:].imag], axis=2)  # (E, R, 2Ny-1)
        basis = self._y_basis
        E, A = basis.shape[0], basis.shape[2]
        out = np.empty((E, R, A))
        post = _floor_invert() if floor is not None else None
        for e in range(E):  # a loop of GEMMs beats numpy's batched matmul here (5x)
            block = out[e]
            np.dot(H[e], basis[e], out=block)
            if post is not None:
                post(block, floor, invert)
            else:
                if floor is not None:
                    np.maximum(block, floor, out=block)
                if invert:
                    np.divide(1.0, block, out=block)  # twice as fast as np.reciprocal
        return out.transpose(1, 0, 2)

    def __call__(self, Q: np.ndarray) -> np.ndarray:
        """``Re(a^H Q a)`` for Hermitian Q (R, L, L) in row-major grid order: (R, E, A)."""
        return self.evaluate(self.coefficients(Q))


def _floor_invert():
    """The compiled floor-and-invert pass, or None when numba is not installed."""
    return optional_kernel("processing.imaging.doa_kernel", "floor_invert")


#: ``coarray_kernel(shape, pitch_m, grid, frequency_hz, speed_of_sound_m_s)``: a cached
#: :class:`CoarrayKernel` (grids hash by identity): its precomputed phases are reused
#: by every method and recording that shares the grid (at most 32 kept)
coarray_kernel = lru_cache(maxsize=32)(CoarrayKernel)
