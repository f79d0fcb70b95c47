"""Frequency-dependent factors of each path: air absorption and emitter directivity.

A path n has the response ``H(f, n) = 10^(-alpha(f) L_n / 20) * D(f, theta_n)``
(alpha from ISO 9613-1, L_n its length, D the far-field directivity of a baffled
circular piston of radius a at the departure angle theta_n).  Filtering every path
separately would cost one FFT per path; instead H, sampled over the band where the
call has energy, is factored by an SVD into a few separable terms
``H(f, n) ~ sum_q u_q(f) v_q(n)``, factorised on 64 frequencies across the band and
interpolated (rank: singular values down to 1e-3 of the largest; -67 dB against exact
per-path filtering in `tests/acousim/synth/test_synth.py`), so rendering costs Q impulse
accumulations and Q x M FFTs.  Path lengths
differ between microphones by millimetres: the per-microphone part is applied as a
gain at the centre of the band.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import j1

from acousim.core.air import absorption_db_per_m
from acousim.core.echoes import Echoes
from acousim.core.materials import MaterialSpectra

__all__ = ["PathResponse", "piston_directivity", "mic_directivity", "factorise"]

RANK_TOLERANCE = 1e-3


def piston_directivity(frequency_hz, theta_rad, radius_m: float, speed_of_sound_m_s: float):
    """Pressure directivity of a baffled circular piston, 1 on axis.

    ``D = 2 J1(k a sin(theta)) / (k a sin(theta))`` in front of the baffle; behind its
    plane (theta > 90°) the pattern fades linearly from its 90° value to zero at 180°
    (a finite baffle: continuous, so a path grazing the baffle plane does not flip
    between full level and silence).  Broadcasts f against theta.
    """
    f = np.asarray(frequency_hz, float)
    th = np.abs(np.asarray(theta_rad, float))
    x = 2 * np.pi * f / speed_of_sound_m_s * radius_m * np.sin(np.minimum(th, np.pi / 2))
    small = np.abs(x) < 1e-8
    x = np.where(small, 1.0, x) if small.any() else np.asarray(x, float)
    d = j1(x)
    d *= 2
    d /= x
    if small.any():
        d[small] = 1.0
    fade = np.clip(2 - 2 * th / np.pi, 0.0, 1.0)  # 1 up to 90°, 0 at 180°
    d *= fade
    return d


#: the largest argument ``x = k a sin(theta)`` :func:`piston_series` sums
SERIES_MAX_X = 6.0


def piston_series(
    frequency_hz: np.ndarray,
    theta_rad: np.ndarray,
    radius_m: float,
    speed_of_sound_m_s: float,
    weight: np.ndarray,
) -> np.ndarray | None:
    """:func:`piston_directivity` (F, N) of the frequencies (F,) and angles (N,),
    times weight (N,), as the power series of ``2 J1(x) / x``: ``sum_k (-z)^k / (k!
    (k + 1)!)``, z = x^2 / 4 = a_f b_n (a_f = (k a / 2)^2, b_n = sin(theta)^2), which
    is the matrix product ``C B`` of C[f, k] = (-a_f)^k / (k! (k + 1)!) and B[k, n] =
    b_n^k (one small GEMM instead of F N Bessel functions: 10x faster), summed until
    the terms fall below 1e-18.  Exact to rounding for ``x <= SERIES_MAX_X`` (the
    largest term 6.8: errors of a few 1e-15 against scipy's J1, the tests check
    it); None beyond that."""
    kr = 2 * np.pi * np.asarray(frequency_hz, float) / speed_of_sound_m_s * radius_m
    th = np.abs(np.asarray(theta_rad, float))
    sin_theta = np.sin(np.minimum(th, np.pi / 2))
    a, b = (kr / 2) ** 2, sin_theta**2
    z_max = a.max(initial=0.0) * b.max(initial=0.0)
    if z_max > (SERIES_MAX_X / 2) ** 2:
        return None
    coef = [1.0]  # 1 / (k! (k + 1)!)
    while coef[-1] * z_max ** (len(coef) - 1) > 1e-18:
        k = len(coef)
        coef.append(coef[-1] / (k * (k + 1)))
    K = len(coef)
    C = np.cumprod(np.broadcast_to(-a[:, None], (a.size, K)), axis=1)
    C[:, 1:] = C[:, :-1] * coef[1:]
    C[:, 0] = 1.0
    B = np.empty((K, b.size))
    B[0] = np.clip(2 - 2 * th / np.pi, 0.0, 1.0) * weight  # the fade behind the baffle
    for k in range(1, K):
        np.multiply(B[k - 1], b, out=B[k])
    return C @ B


def mic_directivity(
    echoes: Echoes,
    *,
    anchor_m: np.ndarray,
    mics_m: np.ndarray,
    axis: np.ndarray,
    radius_m: float,
    frequency_hz: float,
    speed_of_sound_m_s: float,
) -> Echoes:
    """`echoes` with the microphones' directivity applied: each port a baffled piston
    of radius `radius_m` (m) facing `axis` (3,), at one frequency (the centre of the
    call's band: MEMS ports are small, the pattern barely changes across it), as a
    gain per microphone and path.  anchor_m (N, 3): where each path's last leg
    starts; mics_m (M, 3): the microphones, world frame."""
    arrival = anchor_m[None, :, :] - mics_m[:, None, :]  # towards the source
    arrival /= np.maximum(np.linalg.norm(arrival, axis=2, keepdims=True), 1e-12)
    theta = np.arccos(np.clip(arrival @ axis, -1, 1))  # (M, N)
    d = piston_directivity(frequency_hz, theta, radius_m, speed_of_sound_m_s)
    return Echoes(
        echoes.delay_s,
        echoes.gain * d,
        echoes.path_length_m,
        echoes.order,
        echoes.emitter_angle_rad,
        echoes.interactions,
    )


@dataclass(frozen=True)
class PathResponse:
    """What shapes each path's spectrum.

    absorption : bool
        ISO 9613-1 air absorption at the given atmosphere.
    emitter_radius_m : float
        Baffled-piston radius of the emitter; 0 is omnidirectional.
    materials : MaterialSpectra, optional
        Frequency-dependent materials: each path's response is multiplied by its
        interactions' gains over their references (:mod:`acousim.core.materials`).
    """

    speed_of_sound_m_s: float = 343.0
    absorption: bool = True
    temperature_c: float = 20.0
    humidity_percent: float = 50.0
    pressure_kpa: float = 101.325
    emitter_radius_m: float = 0.0
    materials: MaterialSpectra | None = None

    @property
    def active(self) -> bool:
        return self.absorption or self.emitter_radius_m > 0 or self.materials is not None

    def matrix(
        self,
        freqs: np.ndarray,
        length_m: np.ndarray,
        theta_rad: np.ndarray | None,
        interactions: np.ndarray | None = None,
    ) -> np.ndarray:
        """H(f, n): shape (F, N); `interactions` (N, K): the paths' material
        interaction counts (None: none)."""
        if self.absorption:
            alpha = absorption_db_per_m(
                freqs, self.temperature_c, self.humidity_percent, self.pressure_kpa
            )
            # 10^(-alpha L / 20), as exp (5x faster than a power)
            H = np.exp(np.multiply.outer(alpha * (-np.log(10) / 20), length_m))
        else:
            H = np.ones((freqs.size, length_m.size))
        if self.emitter_radius_m > 0 and theta_rad is not None:
            H *= piston_directivity(
                freqs[:, None], theta_rad[None, :], self.emitter_radius_m, self.speed_of_sound_m_s
            )
        if self.materials is not None and interactions is not None and interactions.size:
            H *= self.materials.factor(freqs, interactions)
        return H

    def weighted_matrix(
        self,
        freqs: np.ndarray,
        length_m: np.ndarray,
        theta_rad: np.ndarray | None,
        interactions: np.ndarray | None,
        weight: np.ndarray,
    ) -> np.ndarray:
        """``H(f, n) weight[n]`` (F, N): :meth:`matrix` with each path's column times
        its weight (N,), the emitter's directivity as a matrix product
        (:func:`piston_series`) when every argument ``k a sin(theta)`` is within its
        range."""
        if self.emitter_radius_m <= 0 or theta_rad is None:
            return self.matrix(freqs, length_m, theta_rad, interactions) * weight
        D = piston_series(freqs, theta_rad, self.emitter_radius_m, self.speed_of_sound_m_s, weight)
        if D is None:  # beyond the series' range: scipy's J1
            return self.matrix(freqs, length_m, theta_rad, interactions) * weight
        H = self.matrix(freqs, length_m, None, interactions)
        H *= D
        return H

    def alpha_db_per_m(self, f: float) -> float:
        if not self.absorption:
            return 0.0
        return float(
            absorption_db_per_m(f, self.temperature_c, self.humidity_percent, self.pressure_kpa)
        )


def factorise(H: np.ndarray, tolerance: float = RANK_TOLERANCE) -> tuple[np.ndarray, np.ndarray]:
    """Separable terms of H (F, N), F small: (U (F, Q) with singular values folded in,
    V (N, Q) orthonormal columns).

    Q keeps the singular values above `tolerance` times the largest.  Computed from
    the eigenvectors of the smaller Gram matrix: F x F, ``H H^T`` (N is the number
    of paths, often thousands: a full SVD would cost far more), or N x N, ``H^T H``,
    when there are fewer paths than frequencies (the wall's one, the shoebox's 18).
    """
    if H.size == 0:
        return np.zeros((H.shape[0], 0)), np.zeros((H.shape[1], 0))
    if H.shape[1] < H.shape[0]:
        V, U = factorise(H.T, tolerance)  # H^T = V' U'^T: U' orthonormal, H = U' V'^T
        s = np.linalg.norm(V, axis=0)  # the singular values, folded into V'
        return U * s, V / s
    w, E = np.linalg.eigh(H @ H.T)  # ascending; w = singular values squared
    w = np.maximum(w[::-1], 0.0)
    E = E[:, ::-1]
    if w[0] <= 0:
        return np.zeros((H.shape[0], 0)), np.zeros((H.shape[1], 0))
    q = max(1, int(np.sum(np.sqrt(w) > tolerance * np.sqrt(w[0]))))
    s = np.sqrt(w[:q])
    V = (H.T @ E[:, :q]) / s
    return E[:, :q] * s, V
