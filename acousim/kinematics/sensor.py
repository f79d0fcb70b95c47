"""Where the sensor's emitter and microphones are during a measurement
(:class:`SensorKinematics`), times from the start of the emission."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from processing import Array

__all__ = ["SensorKinematics", "Pieces", "TABLE_STEP_S"]

#: the trajectory is tabulated at this step for the fast method (linear interpolation
#: between: error a h^2 / 8, below 1e-8 m for a robot)
TABLE_STEP_S = 2.5e-4
#: the table is replaced by a polynomial in time of the lowest degree up to this one
#: that fits it within POLY_FIT_M
POLY_DEGREE = 6
POLY_FIT_M = 1e-10
#: over a knot, each piece between knots is fitted at this many Chebyshev nodes (and
#: checked at the midpoints between them)
PIECE_NODES = 25


def _spans_a_knot(trajectory, t0: float, span_s: float) -> bool:
    """Whether a knot of `trajectory` (its ``times_s``, if it has some) lies within
    ``(t0, t0 + span_s)`` (s): its motion's derivatives may jump there."""
    knots = getattr(trajectory, "times_s", None)
    if knots is None or np.size(knots) < 2:
        return False
    return bool(np.any((knots > t0) & (knots < t0 + span_s)))


def _none_fits(x: np.ndarray, flat: np.ndarray) -> bool:
    """Whether no polynomial of degree up to POLY_DEGREE fits the table `flat` (G, C)
    at the normalised times `x` (G,) within POLY_FIT_M: the least-squares fit of that
    degree leaves in some column a root mean square residual above twice it (every
    polynomial of that degree or lower leaves at least that root mean square, so a
    largest residual at least that, in the column: the rounding of the fit, about
    1e-13 m for tables of metres, is far within the factor 2)."""
    coef = np.polynomial.polynomial.polyfit(x, flat, POLY_DEGREE)
    fit = np.polynomial.polynomial.polyval(x, coef).T
    rms = np.sqrt(np.mean((fit - flat) ** 2, axis=0))
    return bool(rms.max() > 2 * POLY_FIT_M)


def _ruled_out(x: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """Which degrees 1..POLY_DEGREE (bool (POLY_DEGREE,), degree d at d - 1) no
    polynomial can fit within POLY_FIT_M at the times `x` (G,) of the table `flat`
    (G, C) (so their fits need not be tried): with g a unit vector over the G times
    orthogonal to every polynomial of degree d (the Q of the Vandermonde's QR,
    columns d + 1 and up), ``g . (f - p) = g . f`` for such a p, so ``max |f - p|``
    is at least ``|g . f| / sum |g|`` (the rounding of metres in the products: far
    below 1e-12 m)."""
    if x.size < POLY_DEGREE + 2:
        return np.zeros(POLY_DEGREE, bool)
    q, bound = _orthogonal(x.tobytes())
    proj = np.abs(q.T @ flat).max(axis=1)
    beyond = proj > bound  # column k + 2: degree k + 1
    return np.logical_or.accumulate(beyond[::-1])[::-1]


@functools.lru_cache(maxsize=8)
def _orthogonal(key: bytes) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_ruled_out`'s Q columns (G, POLY_DEGREE) and the bounds of their
    projections, for the times whose bytes are `key` (every pose of a scene has the
    same grid: made once)."""
    x = np.frombuffer(key)
    q = np.linalg.qr(np.vander(x, POLY_DEGREE + 2, increasing=True))[0][:, 2:]
    return q, POLY_FIT_M * np.abs(q).sum(axis=0) + 1e-12


@functools.lru_cache(maxsize=32)
def _fitter(key: bytes, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """The Vandermonde matrix V (G, degree + 1) of the times whose bytes are `key`
    and its pseudo-inverse (degree + 1, G): the least-squares polynomial of a table
    (G, C) is ``pinv @ table`` (coefficients of x^0 first), its values ``V @ coef``
    (as numpy's polyfit, made once per grid and degree)."""
    V = np.vander(np.frombuffer(key), degree + 1, increasing=True)
    return V, np.linalg.pinv(V)


def _fit(x: np.ndarray, flat: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """The least-squares polynomial of `degree` through the table `flat` (G, C) at the
    times `x` (G,): its coefficients (degree + 1, C) and values (G, C)."""
    V, pinv = _fitter(x.tobytes(), degree)
    coef = pinv @ flat
    return coef, V @ coef


@dataclass(frozen=True, eq=False)
class Pieces:
    """The microphones' motion over a measurement that spans knots of its trajectory
    (where the turn rate, or the acceleration, may jump): a polynomial in time per
    piece between knots.  P pieces, M microphones, degree D (the highest any piece
    needs; the others' higher coefficients zero)."""

    bounds: np.ndarray
    """(P - 1,) the knots, s from the start of the emission: piece j holds the times
    from ``bounds[j - 1]`` up to ``bounds[j]``."""
    mid: np.ndarray
    """(P,) each piece's middle, s from the start of the emission."""
    half: np.ndarray
    """(P,) each piece's half length (s): its polynomials take ``(t - mid) / half``."""
    mic_poly: np.ndarray
    """(P, M, D + 1, 3) positions (m), coefficients of x^0 first."""
    mic_poly_v: np.ndarray
    """(P, M, D, 3) velocities (m/s), the positions' derivatives in t."""


def fit_pieces(trajectory, t0: float, points: np.ndarray, end_s: float) -> Pieces | None:
    """The motion of sensor-frame `points` (M, 3) on `trajectory` from `t0` (s) for
    `end_s` (s) as :class:`Pieces` (None: a piece no polynomial of degree up to
    POLY_DEGREE fits within POLY_FIT_M):

    1. cut ``[0, end_s]`` at the trajectory's knots inside it;
    2. per piece, evaluate the trajectory at PIECE_NODES Chebyshev nodes and at the
       midpoints between them;
    3. fit the nodes with the lowest degree whose polynomial is within POLY_FIT_M of
       the trajectory at every node and midpoint;
    4. pad every piece to the highest degree, and differentiate."""
    knots = np.asarray(getattr(trajectory, "times_s", ()), float).reshape(-1) - t0
    inner = np.sort(knots[(knots > 0) & (knots < end_s)])
    edges = np.concatenate([[0.0], inner, [end_s]])
    nodes = -np.cos(np.pi * np.arange(PIECE_NODES) / (PIECE_NODES - 1))
    x = np.concatenate([nodes, 0.5 * (nodes[1:] + nodes[:-1])])
    fits = []
    for a, b in zip(edges[:-1], edges[1:]):
        mid, half = 0.5 * (a + b), 0.5 * (b - a)
        flat = trajectory.to_world(points, t0 + mid + half * x).reshape(x.size, -1)
        for degree in range(1, POLY_DEGREE + 1):
            coef = np.polynomial.polynomial.polyfit(nodes, flat[: nodes.size], degree)
            if np.max(np.abs(np.polynomial.polynomial.polyval(x, coef).T - flat)) < POLY_FIT_M:
                fits.append((mid, half, coef))
                break
        else:
            return None
    D = max(coef.shape[0] for _, _, coef in fits) - 1
    M = len(points)
    poly = np.zeros((len(fits), D + 1, M * 3))
    poly_v = np.zeros((len(fits), D, M * 3))
    for j, (_, half, coef) in enumerate(fits):
        poly[j, : coef.shape[0]] = coef
        deriv = np.polynomial.polynomial.polyder(coef) / half
        poly_v[j, : deriv.shape[0]] = deriv
    return Pieces(
        bounds=inner,
        mid=np.array([f[0] for f in fits]),
        half=np.array([f[1] for f in fits]),
        mic_poly=np.ascontiguousarray(poly.reshape(len(fits), D + 1, M, 3).transpose(0, 2, 1, 3)),
        mic_poly_v=np.ascontiguousarray(poly_v.reshape(len(fits), D, M, 3).transpose(0, 2, 1, 3)),
    )


class SensorKinematics:
    """Emitter and microphone positions over a measurement, times from the start of
    the emission.

    `trajectory` None: the sensor stays at `pose`.  With `step_s`, the motion is
    tabulated over ``[0, window_s + step_s]`` and represented by a polynomial in time
    where one fits the table within POLY_FIT_M; over a knot of the trajectory, where
    none may, by a polynomial per piece between knots (:attr:`pieces`, for the
    reception times' Newton solve) and the table interpolated linearly (the rest);
    without `step_s`, every query evaluates the trajectory (the reference).
    """

    def __init__(self, trajectory, pose, array: Array, window_s: float, step_s: float | None):
        self.trajectory = trajectory
        self.t0 = pose.time_s
        self.array = array
        self.emitter0 = pose.to_world(array.emitter_m)
        self.mics0 = pose.to_world(array.positions_m)
        self.static = trajectory is None
        self.step = step_s
        #: over knots where no one polynomial fits: a polynomial per piece (the
        #: reception times' Newton solve takes them; the rest the table)
        self.pieces: Pieces | None = None
        if not self.static and step_s is not None:
            # from the start of the emission (no earlier time is ever asked for: the
            # pose may be a knot of the trajectory, where its derivatives jump)
            n = int(np.ceil((window_s + step_s) / step_s)) + 2
            self.grid = step_s * np.arange(n)
            pts = np.vstack([array.emitter_m[None], array.positions_m])
            table = trajectory.to_world(pts, self.t0 + self.grid)  # (G, 1 + M, 3)
            self.emitter_table = table[:, 0]
            self.mic_table = table[:, 1:]
            # a polynomial in time through the table where it fits (within one
            # segment of a trajectory: always), evaluated without look-ups
            self.mid = 0.5 * (self.grid[0] + self.grid[-1])
            self.half = 0.5 * (self.grid[-1] - self.grid[0])
            x = (self.grid - self.mid) / self.half
            flat = table.reshape(table.shape[0], -1)
            self.poly = None
            # the lowest degree that fits (a sensor on a trajectory: 3, the cubic
            # of its segment; every Newton step evaluates it per path and microphone);
            # over a knot of the trajectory none may (then found with one fit)
            degrees = range(1, POLY_DEGREE + 1)
            if _spans_a_knot(trajectory, self.t0, self.grid[-1]) and _none_fits(x, flat):
                degrees = range(0)
            fits = False
            ruled_out = _ruled_out(x, flat)
            for degree in degrees:
                if ruled_out[degree - 1]:
                    continue
                coef, fit = _fit(x, flat, degree)  # (D + 1, P * 3), (G, P * 3)
                fits = bool(np.max(np.abs(fit - flat)) < POLY_FIT_M)
                if fits:
                    break
            if fits:
                self.degree = degree
                self.poly = coef.reshape(degree + 1, *table.shape[1:])  # (D + 1, 1 + M, 3)
                # (numpy's polyder: k c_k, the same products, without its overhead)
                deriv = coef[1:] * np.arange(1, degree + 1.0)[:, None] / self.half
                self.poly_v = deriv.reshape(degree, *table.shape[1:])
                # per microphone (M, D + 1, 3) for batched products with the powers
                self.mic_poly = np.ascontiguousarray(self.poly[:, 1:].transpose(1, 0, 2))
                self.mic_poly_v = np.ascontiguousarray(self.poly_v[:, 1:].transpose(1, 0, 2))
            else:
                self.pieces = fit_pieces(trajectory, self.t0, array.positions_m, self.grid[-1])

    @classmethod
    def exact(cls, trajectory, pose, array: Array) -> SensorKinematics:
        """The kinematics evaluated on `trajectory` (None: static) at every query:
        the reference's."""
        return cls(trajectory, pose, array, 0.0, None)

    def _powers(self, t: np.ndarray, degree: int) -> np.ndarray:
        """Powers 0..degree of the normalised time: t (M, ...) -> (M, K, degree + 1)."""
        x = ((t - self.mid) / self.half).reshape(t.shape[0], -1)
        X = np.empty((degree + 1, *x.shape))  # each power contiguous
        X[0] = 1.0
        for k in range(1, degree + 1):
            np.multiply(X[k - 1], x, out=X[k])
        return np.moveaxis(X, 0, -1)

    @staticmethod
    def _horner(coef, x):
        p = coef[-1]
        for c in coef[-2::-1]:
            p = p * x + c
        return p

    def _lookup(self, table, t):
        x = (np.asarray(t, float) - self.grid[0]) / self.step
        i = np.clip(np.floor(x).astype(np.intp), 0, self.grid.size - 2)
        w = (x - i)[..., None]
        return i, w

    def emitter(self, tau) -> np.ndarray:
        """Emitter positions (..., 3) at times `tau` (...)."""
        tau = np.asarray(tau, float)
        if self.static:
            return np.broadcast_to(self.emitter0, (*tau.shape, 3))
        if self.step is None:
            return self.trajectory.to_world(self.array.emitter_m[None], self.t0 + tau)[..., 0, :]
        if self.poly is not None:
            return self._horner(self.poly[:, 0], ((tau - self.mid) / self.half)[..., None])
        i, w = self._lookup(self.emitter_table, tau)
        return self.emitter_table[i] * (1 - w) + self.emitter_table[i + 1] * w

    def mics(self, t, m: int | None = None) -> np.ndarray:
        """Microphone positions (..., 3): of microphone `m` at times `t` (...), or with
        m None, of microphone i at times ``t[i]`` (t of shape (M, ...))."""
        t = np.asarray(t, float)
        if m is None:
            idx = np.arange(t.shape[0]).reshape(-1, *([1] * (t.ndim - 1)))
        else:
            idx = np.full(t.shape, m)
        if self.static:
            return self.mics0[np.broadcast_to(idx, t.shape)]
        if self.step is None:
            R = self.trajectory.rotation(self.t0 + t)
            p = self.trajectory.position(self.t0 + t)
            local = self.array.positions_m[np.broadcast_to(idx, t.shape)]
            return np.einsum("...ij,...j->...i", R, local) + p
        if self.poly is not None:
            if m is None:
                X = self._powers(t, self.degree)
                return np.matmul(X, self.mic_poly).reshape(*t.shape, 3)
            return self._horner(self.poly[:, 1 + m], ((t - self.mid) / self.half)[..., None])
        i, w = self._lookup(self.mic_table, t)
        idx = np.broadcast_to(idx, t.shape)
        return self.mic_table[i, idx] * (1 - w) + self.mic_table[i + 1, idx] * w

    def mics_by_axis(self, t: np.ndarray, velocity: bool = False):
        """Polynomial kinematics only: positions (M, 3, N) of microphone i at times
        ``t[i]`` (t (M, N)), coordinates in rows (no short last axis to reduce over),
        and with `velocity` the velocities too."""
        M, N = t.shape
        X = np.empty((M, self.degree + 1, N))
        X[:, 0] = 1.0
        np.subtract(t, self.mid, out=X[:, 1])
        X[:, 1] /= self.half
        for k in range(2, self.degree + 1):
            np.multiply(X[:, k - 1], X[:, 1], out=X[:, k])
        pos = np.matmul(self.mic_poly.transpose(0, 2, 1), X)
        if not velocity:
            return pos
        return pos, np.matmul(self.mic_poly_v.transpose(0, 2, 1), X[:, :-1])

    def mics_and_velocity(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Tabulated kinematics only: positions and velocities (M, ..., 3) of
        microphone i at times ``t[i]``."""
        t = np.asarray(t, float)
        if self.poly is not None:
            X = self._powers(t, self.degree)
            pos = np.matmul(X, self.mic_poly).reshape(*t.shape, 3)
            vel = np.matmul(X[..., :-1], self.mic_poly_v).reshape(*t.shape, 3)
            return pos, vel
        idx = np.broadcast_to(np.arange(t.shape[0]).reshape(-1, *([1] * (t.ndim - 1))), t.shape)
        i, w = self._lookup(self.mic_table, t)
        a, b = self.mic_table[i, idx], self.mic_table[i + 1, idx]
        return a + (b - a) * w, (b - a) / self.step
