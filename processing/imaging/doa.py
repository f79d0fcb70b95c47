"""Direction-of-arrival spectra: Delay-And-Sum, MUSIC (plain, FSS, FBSS), Capon/MPDR.

One face for every method: :func:`doa_spectrum` takes the snapshots of the kept
range bins and returns a spectrum over an azimuth-elevation grid for each bin
(:func:`doa_spectra`: several methods of the same snapshots, sharing their
arrangement and eigendecompositions).  All
methods are quadratic forms ``a^H Q a`` of a per-bin Hermitian matrix Q:

=============  =========================================  =====================
method         Q                                          spectrum
=============  =========================================  =====================
das            R (sample covariance)                      a^H R a
music*         E_n E_n^H (noise subspace projector)       1 / a^H Q a
capon*         R_b^-1 (loaded covariance, eq. 9)          1 / a^H Q a (MPDR)
=============  =========================================  =====================

``-fss``/``-fbss`` use the spatially smoothed covariance of subarrays (URA only).

Speed (URA fast path): with fewer snapshots S than (sub)array elements L, Q is
``c0 I + U diag(d) U^H`` with S columns from the S x S Gram matrix (no L x L
eigendecomposition, no covariance), and the co-array coefficients come straight from
those factors (:meth:`processing.imaging.steering.CoarrayKernel.coefficients_low_rank`);
the floor and reciprocal below are applied per elevation block inside the kernel.
FBSS (S >= L) stays real throughout: the real covariance ``T^H C T`` comes from the
forward snapshots alone, the eigendecomposition and Q are real, and the co-array
coefficients of ``T Qr T^H`` are two real matrix products
(:meth:`processing.imaging.steering.CoarrayKernel.coefficients_unitary`).

Definitions that the paper leaves open, fixed here (docs/processing.md states them
for users, with the pipeline and the conventions):

* Noise subspace: eigenvectors whose eigenvalue is not above the mean eigenvalue
  (the paper's rule), or all but the `n_sources` largest when that is given.
* Diagonal loading is scale-free.  Eigenvalues of R are first floored at
  ``1e-3 * trace(R) / L``, a white-noise floor 30 dB under the mean element power
  (``EIG_FLOOR``, the default of the ``eig_floor`` option): a wideband echo seen
  through a finite STFT window is never an exact steering vector (the window
  weights the microphones differently), and without such a floor MPDR cancels a
  noise-free echo into two false peaks 2 degrees either side
  (``tests/processing/imaging/test_doa.py`` pins this).  Then every eigenvalue is
  loaded by
  ``loading * sigma2`` where sigma2 is the smallest floored eigenvalue (the noise
  floor).  The loaded matrix is positive definite for any ``loading > -1``, so the
  paper's small negative load b = -0.5 ("remove half of the noise floor") stays
  well defined at every signal scale; an absolute b = -0.5 added to an unnormalised
  R would depend on the units of the recording and can make R_b indefinite.
* A range bin whose covariance is zero (no energy) gets a spectrum of zeros for
  every method.
* MUSIC denominators ``a^H E_n E_n^H a`` are floored at ``MUSIC_FLOOR * L``
  (``1e-12 * L``, L the (sub)array size), so spectra are finite, real and
  non-negative.  The floor caps a noise-free MUSIC peak at about 120 dB over the
  spectrum's median (whose denominators are of order L); with any noise the true
  denominators are far above it.
* Scale: the snapshots are divided by their largest magnitude before anything is
  squared, so inputs of any magnitude (1e-160 or 1e+160) give the same spectrum,
  and DAS and Capon powers are relative to that largest snapshot (squared).
* Non-finite snapshots are an error naming the microphone and range bin.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from processing.base.api import folded_keywords
from processing.base.errors import InputError
from processing.base.settings import check, setting, settings_of, validate
from processing.imaging.methods import NARROWBAND_METHODS, NarrowbandMethod, parse_method
from processing.imaging.smoothing import default_subarray, subarray_snapshots
from processing.imaging.steering import (
    Grid,
    check_frequency,
    coarray_kernel,
    quadratic_form_direct,
    steering_matrix,
    warn_grating_lobes,
)
from processing.sensor.arrays import Array

__all__ = [
    "NarrowbandMethod",
    "NARROWBAND_METHODS",
    "METHODS",
    "SubspaceOptions",
    "doa_spectrum",
    "doa_spectra",
    "method_matrix",
]

METHODS = NARROWBAND_METHODS


#: Capon's white-noise floor under the eigenvalues, a fraction of the mean eigenvalue
#: (module docstring); the default of :attr:`SubspaceOptions.eig_floor`
EIG_FLOOR = 1e-3


@dataclass(frozen=True)
class SubspaceOptions:
    """How the covariance methods use the snapshots: the smoothing `subarray`
    (Lz, Ly) (None: 5/8 of each dimension), the Capon `loading` (in units of the
    noise floor, see :func:`method_matrix`), the MUSIC signal subspace size
    `n_sources` (None: the mean-eigenvalue rule) and Capon's `eig_floor` (the
    eigenvalues are first floored at ``eig_floor * trace(R) / L``, in [0, 1]: an
    InputError otherwise; :class:`processing.ProcessingSettings` takes this
    declaration)."""

    subarray: tuple[int, int] | None = None
    loading: float = -0.5
    n_sources: int | None = None
    eig_floor: float = setting(
        EIG_FLOOR, "", 0, 1, "Capon eigenvalue floor (fraction of the mean eigenvalue)"
    )

    def __post_init__(self) -> None:
        validate(self)


#: the defaults (:class:`processing.ProcessingSettings` declares the same)
SUBSPACE_DEFAULTS = SubspaceOptions()
MUSIC_FLOOR = 1e-12


class _Shared:
    """What the methods of one set of snapshots share (:func:`doa_spectra`): the
    arranged snapshots of each smoothing and the eigendecompositions made of them,
    by key.  Capon and MUSIC of one smoothing decompose the same matrix."""

    def __init__(self) -> None:
        self._made: dict = {}

    def get(self, key, make: Callable):
        """``make()``, made once for `key`."""
        if key not in self._made:
            self._made[key] = make()
        return self._made[key]


def _made(shared: _Shared | None, key, make: Callable):
    """``make()``, shared under `key` when `shared` is given."""
    return make() if shared is None else shared.get(key, make)


def _parse(method: str) -> tuple[str, str]:
    """(base, smoothing) of a narrowband method, or an InputError naming it."""
    spec = parse_method(method) if method in NARROWBAND_METHODS else None
    if spec is None:
        raise InputError(
            f"unknown DOA method; choose one of {', '.join(NARROWBAND_METHODS)}",
            key="method",
            value=method,
        )
    return spec.base, spec.smoothing


def _normalised(snapshots, array: Array) -> np.ndarray:
    """The snapshots (M, R, K) checked (shape, finite) and divided by their largest
    magnitude (before squaring: no overflow or underflow at any scale)."""
    x = np.asarray(snapshots)
    if x.ndim == 2:
        x = x[:, :, None]
    if x.ndim != 3 or x.shape[0] != array.n_mics:
        raise InputError(
            f"snapshots must have shape (M={array.n_mics}, R[, K]), got {np.shape(snapshots)}"
        )
    x = x.astype(np.complex128, copy=False)
    bad = ~np.isfinite(x)
    if bad.any():
        m, r = np.argwhere(bad)[0][:2]
        raise InputError(
            f"non-finite snapshot at microphone {m}, range bin {r}",
            key="snapshots",
            value=complex(x[m, r, 0]),
        )
    peak = np.abs(x).max() if x.size else 0.0
    return x / peak if peak > 0 else x


def _arranged(x: np.ndarray, array: Array, smooth: str, use_grid: bool, subarray):
    """The snapshots as rows per range bin, Y (R, L, K): in grid order on a URA
    (spatially smoothed with `smooth`), and the grid `shape` of the L elements (None
    off the grid) and their positions (L, 3)."""
    if not (array.is_ura and (smooth or use_grid)):
        return np.moveaxis(x, 0, 1), None, array.positions_m
    order = array.grid_order()
    nz, ny = array.grid_shape
    if smooth:
        shape = default_subarray((nz, ny)) if subarray is None else tuple(subarray)
        xg = x[order].reshape(nz, ny, *x.shape[1:])
        Y = subarray_snapshots(xg, shape, forward_backward=smooth == "fbss")
    else:
        Y = np.moveaxis(x[order], 0, 1)
        shape = (nz, ny)
    assert array.pitch_m is not None  # a URA's
    dz, dy = array.pitch_m
    rows, cols = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    positions = np.column_stack([np.zeros(rows.size), cols.ravel() * dy, rows.ravel() * dz])
    return Y, shape, positions


def method_matrix(
    C: np.ndarray,
    base: str,
    *,
    loading: float = -0.5,
    n_sources: int | None = None,
    data: np.ndarray | None = None,
    centro: bool = False,
    eig_floor: float = EIG_FLOOR,
) -> tuple[np.ndarray, bool]:
    """The Hermitian matrix Q of a method from covariances C (R, L, L).

    Returns (Q, inverse): the spectrum is ``a^H Q a`` (DAS) or its inverse.

    Shortcuts, same result (tests compare them with the plain eigendecomposition):
    `data` (R, L, S) with ``C = Y Y^H / S`` and S < L: the nonzero eigenpairs come
    from the S x S Gram matrix (the signal-subspace shortcut; every other eigenvalue
    is 0).  `centro`: C is centro-Hermitian (FBSS), so a unitary change of basis
    makes it real symmetric and a real eigendecomposition suffices.  `eig_floor`:
    Capon's eigenvalue floor, a fraction of the mean eigenvalue (module docstring).
    """
    eig_floor = check(settings_of(SubspaceOptions)["eig_floor"], eig_floor, "eig_floor")
    options = SubspaceOptions(loading=loading, n_sources=n_sources, eig_floor=eig_floor)
    return _method_matrix(C, base, options, data=data, centro=centro)


def _method_matrix(
    C, base, options: SubspaceOptions, *, data=None, centro=False, shared=None, key=None
):
    """:func:`method_matrix` with the `options` (loading, n_sources, eig_floor), its
    decompositions shared under `key` (the smoothing: the same C for every method)
    when `shared` is given."""
    loading, n_sources, eig_floor = options.loading, options.n_sources, options.eig_floor
    L = C.shape[-1]
    if base == "das":
        return C, False
    _check(base, L, loading, n_sources)
    if data is not None and data.shape[-1] < L and (n_sources or 0) <= data.shape[-1]:
        return _low_rank(data, base, loading, n_sources, shared, key, eig_floor), True
    w, U = _made(shared, ("eigh", key, centro), lambda: _eigh(C, centro))
    w = np.maximum(w, 0.0)
    if base == "music":
        if n_sources is None:
            noise = w <= w.mean(axis=-1, keepdims=True) * (1 + 1e-12)
        else:
            noise = np.zeros(w.shape, bool)
            noise[:, : L - n_sources] = True
        return (U * noise[:, None, :]) @ U.conj().transpose(0, 2, 1), True
    trace = w.sum(axis=-1, keepdims=True)
    floor = eig_floor * trace / L
    wf = np.maximum(w, floor)
    mu = wf + loading * wf.min(axis=-1, keepdims=True)
    inv = np.divide(1.0, mu, out=np.zeros_like(mu), where=mu > 0)
    return (U * inv[:, None, :]) @ U.conj().transpose(0, 2, 1), True


def _eigh(C: np.ndarray, centro: bool) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (R, L) ascending and eigenvectors (R, L, L) of the Hermitian C;
    `centro`: C centro-Hermitian, decomposed in the real basis of :func:`_unitary`."""
    if not centro:
        return np.linalg.eigh(C)
    T = _unitary(C.shape[-1])
    Cr = (T.conj().T @ C @ T).real
    w, V = np.linalg.eigh(0.5 * (Cr + Cr.transpose(0, 2, 1)))
    return w, T @ V


def _check(base: str, L: int, loading: float, n_sources: int | None) -> None:
    if base == "capon" and not loading > -1:
        raise InputError(f"loading must be > -1 (in units of the noise floor), got {loading}")
    if base == "music" and n_sources is not None and not 0 <= n_sources < L:
        raise InputError(f"n_sources must be in [0, {L - 1}], got {n_sources}")
    if base not in ("music", "capon"):
        raise InputError(f"unknown method base {base!r}")


def _unitary(L: int) -> np.ndarray:
    """Unitary T (L, L) with ``T^H C T`` real for every centro-Hermitian C."""
    k = L // 2
    I, J = np.eye(k), np.eye(k)[::-1]
    T = np.zeros((L, L), complex)
    T[:k, :k], T[:k, L - k :] = I, 1j * I
    T[L - k :, :k], T[L - k :, L - k :] = J, -1j * J
    if L % 2:
        T[k, k] = np.sqrt(2)
    return T / np.sqrt(2)


def _centro_matrix(
    Y: np.ndarray,
    T: np.ndarray,
    base: str,
    options: SubspaceOptions,
    shared: _Shared | None = None,
    key=None,
) -> tuple[np.ndarray, bool, np.ndarray]:
    """Real Qr (R, L, L) with ``Q = T Qr T^H`` from FBSS snapshots Y = [Yf, J Yf*]
    (R, L, 2S), plus (inverse, empty bins).  With Z = T^H Yf and ``J T* = T``, the
    real form of the FBSS covariance is ``T^H C T = Re(Z Z^H) / S = W W^T / S`` for
    the real W = [Re Z, Im Z] (L, 2S): no complex covariance, no complex basis change."""

    def real_covariance() -> np.ndarray:
        S = Y.shape[-1] // 2
        Z = T.conj().T @ Y[:, :, :S]
        W = np.concatenate([Z.real, Z.imag], axis=-1)
        return (W @ W.transpose(0, 2, 1)) / S

    Cr = _made(shared, ("real covariance", key), real_covariance)
    Qr, inverse = _method_matrix(Cr, base, options, shared=shared, key=("real", key))
    return Qr, inverse, np.flatnonzero(np.einsum("rii->r", Cr) <= 0)


def _low_rank(
    Y: np.ndarray,
    base: str,
    loading: float,
    n_sources: int | None,
    shared=None,
    key=None,
    eig_floor: float = EIG_FLOOR,
) -> np.ndarray:
    """Q of MUSIC or Capon from snapshots Y (R, L, S), S < L, without an L x L
    eigendecomposition (see :func:`_low_rank_factors`)."""
    c0, U, d = _low_rank_factors(Y, base, loading, n_sources, shared, key, eig_floor)
    L = Y.shape[1]
    return c0[:, None, None] * np.eye(L) + (U * d[:, None, :]) @ U.conj().transpose(0, 2, 1)


def _low_rank_factors(
    Y: np.ndarray,
    base: str,
    loading: float,
    n_sources: int | None,
    shared: _Shared | None = None,
    key=None,
    eig_floor: float = EIG_FLOOR,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Q = c0 I + U diag(d) U^H`` of MUSIC or Capon from snapshots Y (R, L, S), S < L:
    returns c0 (R,), U (R, L, S), d (R, S).  C = Y Y^H / S has S eigenpairs from the
    Gram matrix ``Y^H Y / S = V diag(lam) V^H`` (``u = Y v / sqrt(S lam)``) and L - S
    zeros."""
    R, L, S = Y.shape
    lam, U, ok = _made(shared, ("gram", key), lambda: _gram_factors(Y))
    if base == "music":
        if n_sources is None:  # signal: above the mean of all L eigenvalues
            signal = lam > lam.sum(axis=-1, keepdims=True) / L * (1 + 1e-12)
        else:
            signal = np.zeros(lam.shape, bool)
            signal[:, S - n_sources :] = True
        return np.ones(R), U, -signal.astype(float)
    floor = eig_floor * lam.sum(axis=-1, keepdims=True) / L  # the zeros floor to this
    mu = np.maximum(lam, floor) + loading * floor
    mu0 = floor * (1 + loading)
    inv0 = np.divide(1.0, mu0, out=np.zeros_like(mu0), where=mu0 > 0)
    d = 1.0 / np.where(mu > 0, mu, np.inf) - inv0
    d = np.where(ok, d, 0.0)
    return inv0[:, 0], U, d


def _gram_factors(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The S eigenpairs of ``C = Y Y^H / S`` from the Gram matrix of Y (R, L, S):
    eigenvalues lam (R, S) ascending (zero where negligible), orthonormal U (R, L, S)
    (zero columns there) and which are kept, ok (R, S)."""
    S = Y.shape[-1]
    lam, V = np.linalg.eigh(Y.conj().transpose(0, 2, 1) @ Y / S)  # (R, S), ascending
    lam = np.maximum(lam, 0.0)
    tiny = 1e-13 * lam.max(axis=-1, keepdims=True)
    ok = lam > tiny
    scale = np.divide(1.0, np.sqrt(S * lam), out=np.zeros_like(lam), where=ok)
    U = (Y @ V) * scale[:, None, :]  # (R, L, S) orthonormal columns where ok
    return np.where(ok, lam, 0.0), U, ok


@folded_keywords("options", SubspaceOptions, ("subarray", "loading", "n_sources"), since="0.1.0")
def doa_spectrum(
    snapshots: np.ndarray,
    array: Array,
    frequency_hz: float,
    grid: Grid,
    method: str = "das",
    *,
    speed_of_sound_m_s: float = 343.0,
    options: SubspaceOptions = SUBSPACE_DEFAULTS,
    backend: str = "auto",
) -> np.ndarray:
    """Spatial spectrum (R, E, A), float64, of every range bin: real, non-negative
    (linear power or pseudo-power).

    `snapshots` (M, R) or (M, R, K), complex: narrow-band snapshots
    (:func:`processing.imaging.snapshot.stft_snapshot`) at `frequency_hz` (the steering
    frequency), steered over `grid`; `method`: one of :data:`METHODS`; `options`:
    the smoothing subarray (Lz, Ly) (default: 5/8 of each dimension, 5x5 for 8x8 but a
    poor 2x2 for 4x4: docs/processing.md),
    the Capon diagonal load in units of the noise floor (module docstring) and the
    MUSIC signal-subspace dimension (default: the paper's mean-eigenvalue rule);
    `backend`: 'coarray' is the fast URA path, 'direct' evaluates the plain formula
    with explicit steering vectors (any array, slow), 'auto' picks 'coarray' for URAs.
    """
    return doa_spectra(
        snapshots,
        array,
        frequency_hz,
        grid,
        (method,),
        speed_of_sound_m_s=speed_of_sound_m_s,
        options=options,
        backend=backend,
    )[method]


def doa_spectra(
    snapshots: np.ndarray,
    array: Array,
    frequency_hz: float,
    grid: Grid,
    methods: Sequence[str],
    *,
    speed_of_sound_m_s: float = 343.0,
    options: SubspaceOptions = SUBSPACE_DEFAULTS,
    backend: str = "auto",
) -> dict[str, np.ndarray]:
    """:func:`doa_spectrum` of each of `methods` (arguments as there): {method:
    spectrum (R, E, A)}, the same arrays.  The methods share what they have in common:
    the snapshots checked and scaled once, arranged once per smoothing, and one
    eigendecomposition per smoothing for Capon and MUSIC (the default
    ``capon-fbss,music-fbss`` pair decomposes one matrix).  An InputError for a
    `frequency_hz` that is not a positive number
    (:data:`processing.imaging.steering.FREQUENCY_HZ`) or an array of fewer than 2
    microphones; a :class:`processing.GratingLobeWarning` for a URA steered above its
    alias-free frequency."""
    for m in methods:
        _parse(m)
    if backend not in ("auto", "coarray", "direct"):
        raise InputError(f"backend must be 'auto', 'coarray' or 'direct', got {backend!r}")
    array.require_mics("imaging")
    frequency_hz = check_frequency(frequency_hz)
    warn_grating_lobes(array, frequency_hz, float(speed_of_sound_m_s))
    x = _normalised(snapshots, array)
    shared = _Shared()
    steer = (frequency_hz, grid, float(speed_of_sound_m_s))
    return {m: _spectrum(x, array, steer, m, options, backend, shared) for m in methods}


def _spectrum(x, array, steer, method, options, backend, shared):
    """One method's spectrum of the scaled snapshots x (M, R, K), steered by `steer`
    (frequency_hz, grid, speed_of_sound_m_s) (:func:`doa_spectra`)."""
    frequency_hz, grid, c = steer
    base, smooth = _parse(method)
    if smooth:
        array.require_ura(f"method {method!r}")
    use_grid = array.is_ura and backend != "direct"
    if backend == "coarray" and not array.is_ura:
        array.require_ura("the 'coarray' backend")

    Y, shape, positions = shared.get(
        ("arranged", smooth, use_grid),
        lambda: _arranged(x, array, smooth, use_grid, options.subarray),
    )
    form, parts, inverse, empty = _method_form(
        Y, base, smooth, use_grid, options, shared, (smooth, use_grid)
    )
    if inverse:
        floor = MUSIC_FLOOR * Y.shape[1] if base == "music" else np.finfo(float).tiny
    else:
        floor = 0.0
    if use_grid:
        kernel = coarray_kernel(tuple(shape), array.pitch_m, grid, float(frequency_hz), c)
        forms: dict[str, Callable[..., np.ndarray]] = {
            "low_rank": kernel.coefficients_low_rank,
            "unitary": kernel.coefficients_unitary,
            "full": kernel.coefficients,
        }
        coefficients = forms[form]
        P = kernel.evaluate(coefficients(*parts), floor=floor, invert=inverse)
    else:
        steering = steering_matrix(positions, grid, frequency_hz, c)
        quadratic = quadratic_form_direct(parts[0], steering)
        P = np.maximum(quadratic, floor, out=quadratic)
        if inverse:
            np.reciprocal(P, out=P)
    if empty.size:
        P[empty] = 0.0
    return P


def _method_form(
    Y: np.ndarray, base: str, smooth: str, use_grid: bool, options, shared=None, key=None
):
    """The method's matrix of the arranged snapshots Y (R, L, K), in the form its
    evaluation takes: 'low_rank' (co-array coefficients straight from the factors,
    no L x L matrix), 'unitary' (forward-backward on the grid: real from the start,
    Q never formed complex) or 'full' (Q (R, L, L)); its parts, whether the spectrum
    is its inverse, and the range bins without energy.  What does not depend on the
    method is made once per `key` (the arrangement of Y) when `shared` is given."""
    loading, n_sources, eig_floor = options.loading, options.n_sources, options.eig_floor
    L = Y.shape[1]
    if use_grid and Y.shape[-1] < L and (n_sources or 0) <= Y.shape[-1]:
        if base == "das":
            S = Y.shape[-1]
            factors = (np.zeros(Y.shape[0]), Y, np.full(Y.shape[::2], 1.0 / S))
        else:
            _check(base, L, loading, n_sources)
            factors = _low_rank_factors(Y, base, loading, n_sources, shared, key, eig_floor)
        power = np.einsum("rls,rls->r", Y.real, Y.real) + np.einsum("rls,rls->r", Y.imag, Y.imag)
        return "low_rank", factors, base != "das", np.flatnonzero(power <= 0)
    if smooth == "fbss" and use_grid:
        T = _unitary(L)
        Qr, inverse, empty = _centro_matrix(Y, T, base, options, shared, key)
        return "unitary", (Qr, T), inverse, empty

    def covariance() -> np.ndarray:
        C = (Y @ Y.conj().transpose(0, 2, 1)) / Y.shape[-1]
        if smooth == "fbss":  # exactly centro-Hermitian despite rounding
            C = 0.5 * (C + C[:, ::-1, ::-1].conj())
        return C

    C = _made(shared, ("covariance", key), covariance)
    Q, inverse = _method_matrix(
        C, base, options, data=Y, centro=smooth == "fbss", shared=shared, key=key
    )
    return "full", (Q,), inverse, np.flatnonzero(np.einsum("rii->r", C).real <= 0)
