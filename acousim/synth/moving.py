"""Echoes of a measurement in motion: retarded time per path and microphone, Doppler.

The sensor moves and turns during a measurement (30-36 ms), point reflectors may move
too.  A sample of the call emitted at time tau (after the start of the emission) from
the emitter at ``e(tau)`` reaches microphone m at the time t that solves

    t = t_r + |m(t) - A(tau, t_r)| / c,      t_r = tau + F(tau, t_r) / c

with A the path's last anchor (image source, scatterer or reflector) and F its first
leg (see :class:`MovingPaths`).  The microphone records ``g w(tau(t))``: the call
delayed and time-compressed (Doppler), exactly.

Approximation of the geometry (stated, measured in ``BENCHMARKS.md``): paths are
traced once, at the pose of the start of the emission.  Then:

1. the receiving side is exact: an image source, a scatterer or a point reflector
   stays where it is while the microphones move (an image source depends only on
   the emitter), so ``|m(t) - A|`` holds for any reception time;
2. the emitting side moves only during the call (2.5 mm at 1 m/s): the image source
   of a first- or second-order reflection moves exactly with the emitter (its
   planes found from the traced path); the first leg
   of higher-order and scattered paths changes, for an emitter displacement de, by
   ``-u.de + (|de|^2 - (u.de)^2) / (2 L)`` with u the departure direction and L the
   unfolded length from the emitter (Fermat: the length is stationary in the
   reflection points, so the first-order term holds them still; the second-order
   term is that of the image source ``|m - A - J de|`` for any orthogonal J of the
   reflections; third order: below 0.1 ns at 2 m/s); point reflectors use
   ``|A - e(tau)|`` exactly;
3. which paths exist (visibility, the energy floor) is that of the emission pose;
4. gains (spreading, directivity, air absorption) are those at the start of the
   echo: the echo's level changes by v T / r during a call (0.1 % at 1 m/s, 2.5 m).

Rendering:

``render_doppler`` (fast)
    Per path and microphone the emission time is taken linear in the reception
    time, ``tau = a (t - t0)`` (a from the exact solution at the first and last
    sample of the call, t0 shifted by the mean of the parabolic deviation measured at
    the middle sample; the deviation left is what this method neglects), so the
    echo is the call time-scaled by ``a``: ``w(a s)`` is again a sweep of the same
    kind (frequencies times a, duration over a), band-limited as the static
    renderer's call.  The templates are scaled about the middle of the call (the
    pivot p = T/2): ``w(p + a (s - p))``, the echo placed at ``t0 + p / a - p``
    (half the phase excursion over the Doppler factors of scaling about the start:
    fewer nodes and sets).  The scale factors of all paths lie in a small interval
    (widened to multiples of NODE_QUANTUM, so that a drive reuses its templates);
    the call is tabulated at K Chebyshev nodes of it and its interpolant in the
    factor written as a Chebyshev series: every path gets ``T_k(s)`` of its own
    factor (s mapped onto [-1, 1]; a three-term recurrence), the templates their
    Chebyshev coefficients; K chosen so the interpolation error stays below
    ``DOPPLER_TOLERANCE`` (K = 1 when all factors are equal, 6 for the corridor
    drive at 1 m/s).  With the Q separable terms of the path responses
    (absorption, directivity: :mod:`acousim.synth.response`) that makes K Q sets of
    gains, each with its filter; their sum is compressed to the few sets it needs
    (a real SVD from Gram matrices, per group: direct path, echoes, to
    ``COMPRESS_TOLERANCE``; 30 -> 6 on the corridor) and rendered as the static
    renderer does: fractional-delay impulses per set, FFT, products with the
    filters, summed.
``render_doppler_reference`` (exact)
    Per output sample at 64 times the sample rate, the emission time solved exactly
    (Newton on the retarded-time equation with the continuous trajectory), the
    analytic call evaluated there, low-passed at 0.8 Nyquist and decimated, as the
    static renderer's reference.  Cost grows as M N L 64; for tests and benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np
from scipy import fft as sfft

from processing import Array, Waveform
from processing.waveforms import ANTI_ALIAS_CUTOFF

from .echoes import Echoes
from .render import (
    DEFAULT_TAPS,
    FFT_WORKERS,
    FractionalDelay,
    _impulses,
    check_interpolator,
    response_factors,
)
from .response import PathResponse

__all__ = [
    "MovingPaths",
    "SensorKinematics",
    "Arrivals",
    "arrivals",
    "doppler_nodes",
    "DopplerPlan",
    "plan_doppler",
    "render_planned",
    "render_doppler",
    "render_doppler_reference",
    "DOPPLER_TOLERANCE",
    "COMPRESS_TOLERANCE",
]

#: relative error of interpolating the time-scaled call between Doppler nodes (a
#: bound at the call's top frequency: the renderer's error stays far below it)
DOPPLER_TOLERANCE = 1e-3
#: Doppler ranges are widened to multiples of this, so consecutive poses of a drive
#: share their nodes and templates
NODE_QUANTUM = 2e-3
#: the gain sets are compressed to this relative amplitude of what is left out
#: (-63 dB): the renderer's error against the exact reference stays below -65 dB at
#: 2 m/s and 180 deg/s (BENCHMARKS.md, motion: its time against error, 3e-4 -> -71 dB
#: with 8 sets instead of 6 on the corridor)
COMPRESS_TOLERANCE = 7e-4
#: the trajectory is tabulated at this step for the fast method (linear interpolation
#: between: error a h^2 / 8, below 1e-8 m for a robot)
TABLE_STEP_S = 2.5e-4
#: the table is replaced by a polynomial in time of the lowest degree up to this one
#: that fits it within POLY_FIT_M
POLY_DEGREE = 6
POLY_FIT_M = 1e-10
FIRST_LEG = {"fixed": 0, "fermat": 1, "exact": 2}
#: microphones rendered together: the corridor's 30 in two blocks renders in 0.95 of
#: the time of one block (paired runs; its buffers are smaller), in 1.01 with three
#: blocks and 1.08 with six (more, smaller FFT calls)
MICS_PER_BLOCK = 15
#: Newton on the reception time stops after a step below this (error: about the
#: step squared times 0.1 / s, see :func:`_newton_by_axis`)
NEWTON_STOP_S = 2e-5


@dataclass(frozen=True, eq=False)
class MovingPaths:
    """Paths of one measurement and how they follow the motion.  N paths, world frame,
    at the start of the emission (tau = 0).

    anchor_m (N, 3), first_leg_m (N,), strength (N,): as
    :class:`acousim.trace.tracer.TracedPaths` (path length to a microphone p
    ``first_leg + |anchor - p|``, gain ``strength / |anchor - p|``).
    departure (N, 3): unit direction leaving the emitter.  order (N,).
    mirror (N, 3, 3): the anchor moves by ``mirror @ (e(tau) - e(0))`` (identity
    for the direct path, the reflections' linear part for a first- or second-order
    image source, zero else).
    first_leg (N,): :data:`FIRST_LEG` codes: fixed, Fermat (``-departure . de``) or
    exact (``|A - e(tau)|``, point reflectors).
    velocity_m_s (N, 3): of the anchor (moving point reflectors), from tau = 0.
    fermat_length_m (N,): L of the second-order term of a Fermat first leg (the
    first leg of a scattered path, the image distance of a specular one).
    acceleration_m_s2 (N, 3): of the anchor (the image in a turning plane), from
    tau = 0: it is at ``anchor + velocity t + acceleration t^2 / 2`` (None: zero).
    """

    anchor_m: np.ndarray
    first_leg_m: np.ndarray
    strength: np.ndarray
    departure: np.ndarray
    order: np.ndarray
    mirror: np.ndarray
    first_leg: np.ndarray
    velocity_m_s: np.ndarray
    fermat_length_m: np.ndarray
    acceleration_m_s2: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.acceleration_m_s2 is None:
            object.__setattr__(self, "acceleration_m_s2", np.zeros_like(self.anchor_m))

    def __len__(self) -> int:
        return self.strength.size

    @classmethod
    def from_traced(cls, paths, emitter_m: np.ndarray) -> MovingPaths:
        """From :class:`~acousim.trace.tracer.TracedPaths` traced with the emitter at
        `emitter_m` (all static)."""
        from acousim.trace.tracer import KIND

        n = len(paths)
        mirror = np.zeros((n, 3, 3))
        first = np.full(n, FIRST_LEG["fermat"])
        direct = paths.kind == KIND["direct"]
        mirror[direct] = np.eye(3)
        first[direct] = FIRST_LEG["fixed"]
        one = (paths.kind == KIND["specular"]) & (paths.order == 1)
        if one.any():
            normal = emitter_m - paths.anchor_m[one]
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
            mirror[one] = np.eye(3) - 2 * normal[:, :, None] * normal[:, None, :]
            first[one] = FIRST_LEG["fixed"]
        two = np.flatnonzero((paths.kind == KIND["specular"]) & (paths.order == 2))
        if two.size:
            J, ok = _second_order_mirror(
                emitter_m, paths.departure[two], paths.position_m[two], paths.anchor_m[two]
            )
            mirror[two[ok]] = J[ok]
            first[two[ok]] = FIRST_LEG["fixed"]
        first[paths.kind == KIND["point"]] = FIRST_LEG["exact"]
        unfolded = np.where(
            paths.first_leg_m > 0,
            paths.first_leg_m,
            np.linalg.norm(paths.anchor_m - emitter_m, axis=1),
        )
        return cls(
            paths.anchor_m,
            paths.first_leg_m,
            paths.strength,
            paths.departure,
            paths.order,
            mirror,
            first,
            np.zeros((n, 3)),
            np.maximum(unfolded, 1e-6),
        )

    @classmethod
    def points(cls, positions_m, strength, velocity_m_s, emitter_m: np.ndarray) -> MovingPaths:
        """Point reflectors at `positions_m` (P, 3) at tau = 0, moving at
        `velocity_m_s` (P, 3): a_k / r_e at the emitter as the tracer's points."""
        pos = np.asarray(positions_m, float).reshape(-1, 3)
        r_e = np.linalg.norm(pos - emitter_m, axis=1)
        n = pos.shape[0]
        return cls(
            pos,
            r_e,
            np.asarray(strength, float) / r_e,
            (pos - emitter_m) / r_e[:, None],
            np.ones(n, int),
            np.zeros((n, 3, 3)),
            np.full(n, FIRST_LEG["exact"]),
            np.asarray(velocity_m_s, float).reshape(-1, 3),
            r_e,
        )

    @staticmethod
    def concatenate(parts: list[MovingPaths]) -> MovingPaths:
        return MovingPaths(
            *(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(MovingPaths))
        )

    def select(self, keep) -> MovingPaths:
        """The paths where `keep` (a mask, indices or a slice) selects."""
        return MovingPaths(*(getattr(self, f.name)[keep] for f in fields(MovingPaths)))

    def moved(self, emitter0: np.ndarray, emitter1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Static paths after the emitter moved from `emitter0` to `emitter1` (3,):
        anchors (N, 3) and first legs (N,) (the law of the module docstring)."""
        de = emitter1 - emitter0
        anchor = self.anchor_m + self.mirror @ de
        along = self.departure @ de
        fermat = self.first_leg_m - along + (de @ de - along**2) / (2 * self.fermat_length_m)
        first = np.where(self.first_leg == FIRST_LEG["fermat"], fermat, self.first_leg_m)
        exact = np.linalg.norm(anchor - emitter1, axis=1)
        first = np.where(self.first_leg == FIRST_LEG["exact"], exact, first)
        return anchor, first


def _second_order_mirror(e, dep, x2, image):
    """The linear part J (S, 3, 3) of a second-order image source ``A = J e + b`` from
    the emitter e (3,), the departure (S, 3), the last reflection point x2 (S, 3) and
    the image (S, 3); and where it is valid (S,).

    The first reflection point is ``x1 = e + s dep`` with ``s + |x2 - x1| = |x2 - A|``
    (unfolded, the first image lies on the line x2 -> x1 at the distance of A from
    x2): ``s = (R^2 - |w|^2) / (2 (R - w.dep))``, w = x2 - e, R = |x2 - A|; the
    normals follow from the law of reflection at x1 and x2.
    """
    w = x2 - e
    R = np.linalg.norm(x2 - image, axis=1)
    den = 2 * (R - np.einsum("si,si->s", w, dep))
    s = (R**2 - np.einsum("si,si->s", w, w)) / np.where(np.abs(den) > 1e-12, den, 1.0)
    x1 = e + s[:, None] * dep
    u = x2 - x1
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    out = x2 - image
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
    n1, n2 = u - dep, out - u
    n1 /= np.maximum(np.linalg.norm(n1, axis=1, keepdims=True), 1e-12)
    n2 /= np.maximum(np.linalg.norm(n2, axis=1, keepdims=True), 1e-12)
    eye = np.eye(3)
    M1 = eye - 2 * n1[:, :, None] * n1[:, None, :]
    M2 = eye - 2 * n2[:, :, None] * n2[:, None, :]
    J = M2 @ M1
    # valid: a proper solution that maps the departure onto the last leg
    ok = (np.abs(den) > 1e-12) & (s > 0)
    ok &= np.linalg.norm(np.einsum("sij,sj->si", J, dep) - out, axis=1) < 1e-6
    return J, ok


class SensorKinematics:
    """Emitter and microphone positions over a measurement, times from the start of
    the emission.

    `trajectory` None: the sensor stays at `pose`.  With `step_s`, the motion is
    tabulated over ``[0, window_s + step_s]`` and represented by a polynomial in time
    where one fits the table within POLY_FIT_M, else interpolated linearly (the fast
    method); without, every query evaluates the trajectory (the reference).
    """

    def __init__(self, trajectory, pose, array: Array, window_s: float, step_s: float | None):
        self.trajectory = trajectory
        self.t0 = pose.time_s
        self.array = array
        self.emitter0 = pose.to_world(array.emitter_m)
        self.mics0 = pose.to_world(array.positions_m)
        self.static = trajectory is None
        self.step = step_s
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
            # of its segment; every Newton step evaluates it per path and microphone)
            for degree in range(1, POLY_DEGREE + 1):
                coef = np.polynomial.polynomial.polyfit(x, flat, degree)  # (D + 1, P * 3)
                fit = np.polynomial.polynomial.polyval(x, coef).T
                if np.max(np.abs(fit - flat)) < POLY_FIT_M:
                    break
            if np.max(np.abs(fit - flat)) < POLY_FIT_M:
                self.degree = degree
                self.poly = coef.reshape(degree + 1, *table.shape[1:])  # (D + 1, 1 + M, 3)
                deriv = np.polynomial.polynomial.polyder(coef) / self.half
                self.poly_v = deriv.reshape(degree, *table.shape[1:])
                # per microphone (M, D + 1, 3) for batched products with the powers
                self.mic_poly = np.ascontiguousarray(self.poly[:, 1:].transpose(1, 0, 2))
                self.mic_poly_v = np.ascontiguousarray(self.poly_v[:, 1:].transpose(1, 0, 2))

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


def _arrival_times(paths: MovingPaths, kin: SensorKinematics, tau, c: float, mic=None, guess=None):
    """Reception times of the samples emitted at `tau`: a number (one emission time
    for every path and microphone), (M, N) with mic None (row i: microphone i), or
    (N, S) for microphone `mic` (path n in row n).

    Returns (t, anchor, first_leg): t (M, N) (a number or mic None) or (N, S), the
    others broadcast against it (anchor with a last axis 3).
    """
    tau = np.asarray(tau, float)
    e = kin.emitter(tau)
    de = e - kin.emitter0
    scalar = tau.ndim == 0
    if scalar:
        sel = (slice(None),)  # paths only: (N, ...)
    elif mic is None:
        sel = (None, slice(None))  # paths along the last axis: (1, N, ...)
    else:
        sel = (slice(None), None)  # paths along the first axis: (N, 1, ...)
    a0 = paths.anchor_m[sel]
    J = paths.mirror[sel]
    u = paths.velocity_m_s[sel]
    acc = paths.acceleration_m_s2[sel]
    accelerating = bool(np.any(paths.acceleration_m_s2))
    f0 = paths.first_leg_m[sel]
    mode = paths.first_leg[sel]
    dep = paths.departure[sel]
    lf = paths.fermat_length_m[sel]
    moving = bool(np.any(paths.velocity_m_s))
    t_r = tau + f0 / c
    first = f0
    # the anchors moved with the emitter: one matrix-vector product for a single
    # emission time (batched 3 x 3 products cost 50 times more)
    if scalar:
        shift = (paths.mirror.reshape(-1, 3) @ de).reshape(-1, 3)
    else:
        shift = np.matmul(J, de[..., None])[..., 0]

    def at(t):  # the anchors where they are at t (s)
        out = a0 + shift + u * t[..., None]
        return out + 0.5 * acc * t[..., None] ** 2 if accelerating else out

    for _ in range(8 if moving else 1):
        anchor = at(t_r)
        exact = np.linalg.norm(anchor - e, axis=-1)
        along = np.sum(dep * de, axis=-1)
        fermat = f0 - along + (np.sum(de * de, axis=-1) - along**2) / (2 * lf)
        first = np.where(mode == FIRST_LEG["fermat"], fermat, f0)
        first = np.where(mode == FIRST_LEG["exact"], exact, first)
        new = tau + first / c
        done = np.max(np.abs(new - t_r)) < 1e-15
        t_r = new
        if done:
            break
    anchor = at(t_r)
    if scalar:
        shape = (kin.mics0.shape[0], len(paths))
        t_r, anchor = np.broadcast_to(t_r, shape), anchor[None]
        first = np.broadcast_to(first, shape)
    if mic is None and getattr(kin, "poly", None) is not None and t_r.ndim == 2:
        return _newton_by_axis(kin, t_r, anchor, c, guess), anchor, first
    if mic is None and not kin.static and kin.step is not None:
        t = (
            t_r + np.linalg.norm(kin.mics(t_r, mic) - anchor, axis=-1) / c
            if guess is None
            else guess
        )
        # Newton on f(t) = t - t_r - |m(t) - A| / c (the table's slope as m')
        for _ in range(20):
            pos, vel = kin.mics_and_velocity(t)
            diff = pos - anchor
            dist = np.sqrt(np.einsum("...i,...i->...", diff, diff))
            slope = 1 - np.einsum("...i,...i->...", vel, diff) / (np.maximum(dist, 1e-12) * c)
            step = (t - t_r - dist / c) / slope
            t = t - step
            # quadratic convergence: after a step s the error is about s^2 |f''| / 2
            # with |f''| below 1e-2 / s for a robot: s < 1e-7 s leaves < 1e-16 s
            if np.max(np.abs(step)) < 1e-7:
                break
        return t, anchor, first
    t = t_r + np.linalg.norm(kin.mics(t_r, mic) - anchor, axis=-1) / c
    for _ in range(20):
        new = t_r + np.linalg.norm(kin.mics(t, mic) - anchor, axis=-1) / c
        change = np.max(np.abs(new - t)) if new.size else 0.0
        t = new
        if change < 1e-14:
            break
    return t, anchor, first


def _newton_by_axis(kin: SensorKinematics, t_r, anchor, c: float, guess) -> np.ndarray:
    """Reception times (M, N) for the polynomial kinematics: Newton on
    ``f(t) = t - t_r - |m(t) - A| / c`` as in :func:`_arrival_times`, with the
    coordinates in rows (t_r (M, N), anchor (M or 1, N, 3))."""
    A = np.ascontiguousarray(np.moveaxis(anchor, -1, -2))  # (M or 1, 3, N)
    # without a guess, the first Newton step starts at t_r, where f = -|m - A| / c:
    # exact for a microphone at constant velocity
    t = np.broadcast_to(t_r, t_r.shape) if guess is None else np.array(guess, float)
    compiled = _arrival_kernel()
    if compiled is not None:  # the same iteration, compiled (numba)
        return compiled(
            np.broadcast_to(t_r, t.shape),
            A,
            t,
            kin.mic_poly,
            kin.mic_poly_v,
            kin.mid,
            kin.half,
            c,
            NEWTON_STOP_S,
        )
    for _ in range(20):
        pos, vel = kin.mics_by_axis(t, velocity=True)
        diff = pos - A
        dist = np.sqrt(np.sum(diff * diff, axis=1))
        slope = 1 - np.sum(vel * diff, axis=1) / (np.maximum(dist, 1e-12) * c)
        step = (t - t_r - dist / c) / slope
        t = t - step
        # quadratic convergence: after a step s the error is about s^2 |f''| / 2
        # with |f''| <= (|m''| + |m'|^2 / |m - A|) / c: below 0.2 / s at 1 m/s for
        # the direct path (2 cm), 1.5 / s at 3 m/s; s < NEWTON_STOP_S leaves
        # 4e-11 s (-95 dB at 80 kHz), 3e-10 s (-78 dB)
        if np.max(np.abs(step)) < NEWTON_STOP_S:
            break
    return t


@lru_cache(maxsize=1)
def _arrival_kernel():
    """The compiled Newton solve, or None when numba is not installed."""
    try:
        from ._arrival_kernel import solve
    except ImportError:  # numba is optional (the 'fast' extra)
        return None
    return solve


@dataclass(frozen=True, eq=False)
class Arrivals:
    """Echoes in motion: `echoes` (delay_s: reception time of the start of the call,
    gains and lengths there) and `rate` (M, N), the time compression ``d tau / d t``
    of each path at each microphone (1 static, (c + v) / (c - v) closing at v), and
    `curvature_s` (M, N), how far the reception time of the call's middle sample is
    from the linear law (what the fast renderer neglects)."""

    echoes: Echoes
    rate: np.ndarray
    curvature_s: np.ndarray


def arrivals(
    paths: MovingPaths,
    kin: SensorKinematics,
    duration_s: float,
    speed_of_sound_m_s: float,
    emitter_axis: np.ndarray,
) -> Arrivals:
    """Reception times of the first, middle and last sample of the call for every
    path and microphone; the delays and time-compression factors of the fast method."""
    c = speed_of_sound_m_s
    t0, anchor, first = _arrival_times(paths, kin, 0.0, c)
    # started from a line, then from the chord: one or two Newton steps each
    t1, _, _ = _arrival_times(paths, kin, duration_s, c, guess=t0 + duration_s)
    tm, _, _ = _arrival_times(paths, kin, duration_s / 2, c, guess=0.5 * (t0 + t1))
    # the last leg from the solved retarded-time equation, t0 = first / c + last / c
    # (within c times its error, below 1e-10 m)
    last = np.maximum(c * t0 - first, 1e-6)
    length = first + last
    # spreading: strength is a_k / r_e at tau = 0; a moving point's first leg is
    # the one at its reflection
    exact = paths.first_leg == FIRST_LEG["exact"]
    spread = np.where(exact[None, :], paths.first_leg_m[None, :] / np.maximum(first, 1e-9), 1.0)
    gain = paths.strength[None, :] * spread / last
    cos = np.clip(paths.departure @ emitter_axis, -1, 1)
    # the linear law through the first and last sample, shifted by the mean of the
    # (parabolic) deviation: two thirds of the deviation at the middle
    curvature = tm - 0.5 * (t0 + t1)
    echoes = Echoes(t0 + curvature * (2 / 3), gain, length, paths.order.copy(), np.arccos(cos))
    return Arrivals(echoes, duration_s / (t1 - t0), curvature)


def scaled_call(waveform: Waveform, rate: float) -> Waveform:
    """The call time-scaled: ``w(rate t)``, a sweep of the same kind with its
    frequencies times `rate` and its duration over `rate` (exact for the linear and
    the hyperbolic sweep, and for the taper)."""
    return Waveform(
        waveform.kind,
        waveform.f_start_hz * rate,
        waveform.f_end_hz * rate,
        waveform.duration_s / rate,
        waveform.taper,
        waveform.amplitude,
    )


@lru_cache(maxsize=1024)
def _node_count(x: float, tolerance: float) -> int:
    """The fewest Chebyshev nodes that interpolate exp(i x s) on [-1, 1] to
    `tolerance`."""
    k = 1
    while k < 64 and _chebyshev_error(k, x) > tolerance:
        k += 1
    return k


def _chebyshev_error(k: int, x: float) -> float:
    """Largest error of interpolating exp(i x s), s in [-1, 1], at k Chebyshev nodes."""
    nodes = np.cos((2 * np.arange(k) + 1) * np.pi / (2 * k))
    s = np.linspace(-1, 1, 801)
    return float(np.max(np.abs(_lagrange(nodes, s) @ np.exp(1j * x * nodes) - np.exp(1j * x * s))))


def _lagrange(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Lagrange basis of `nodes` (K,) at `x` (...): weights (..., K) (barycentric)."""
    x = np.asarray(x, float)
    K = nodes.size
    if K == 1:
        return np.ones((*x.shape, 1))
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    bw = 1.0 / np.prod(diff, axis=1)
    w = x[..., None] - nodes  # in place from here: (..., K) is the large array
    hit = w == 0
    if hit.any():
        w[hit] = 1.0
    np.divide(bw, w, out=w)
    w /= (w @ np.ones(K))[..., None]  # a product: faster than a sum along a short axis
    if hit.any():
        on = hit.any(axis=-1)
        w[on] = hit[on]
    return w


def doppler_nodes(
    rate_min: float,
    rate_max: float,
    waveform: Waveform,
    sample_rate_hz: float,
    tolerance: float = DOPPLER_TOLERANCE,
) -> np.ndarray:
    """Chebyshev nodes (K,) covering [rate_min, rate_max] (widened to multiples of
    :data:`NODE_QUANTUM`): K is the fewest that interpolate ``w(p + a (s - p))``
    in a to `tolerance` (p = T / 2, the pivot of :func:`render_doppler`: the phase
    ``2 pi f (s - p) a`` spans ``x = 2 pi f_top (T / 2 + ringing) h``, h the half
    width; f_top the call's top frequency, the band limit for an untapered call,
    whose band-limit ringing of 256 samples counts too)."""
    if rate_max - rate_min < 1e-12:
        return np.array([rate_min])
    lo = np.floor(rate_min / NODE_QUANTUM) * NODE_QUANTUM
    hi = np.ceil(rate_max / NODE_QUANTUM) * NODE_QUANTUM
    f_top = max(waveform.band_hz) if waveform.taper > 0 else ANTI_ALIAS_CUTOFF * sample_rate_hz / 2
    # the templates are scaled about the call's middle (:func:`render_doppler`): the
    # time from the pivot reaches half the scaled call, and for an untapered call the
    # ringing of its band limit (a tapered call has no energy there)
    ringing = 0 if waveform.taper > 0 else 256 / sample_rate_hz
    reach = waveform.duration_s / (2 * lo) + ringing
    x = 2 * np.pi * f_top * reach * (hi - lo) / 2
    k = _node_count(float(np.ceil(x * 100) / 100), float(tolerance))
    centre, half = (hi + lo) / 2, (hi - lo) / 2
    return centre + half * np.cos((2 * np.arange(k) + 1) * np.pi / (2 * k))


_TEMPLATES: dict = {}


def _templates(waveform: Waveform, fs: float, nodes: np.ndarray) -> tuple[np.ndarray, int]:
    """Band-limited time-scaled calls (K, L), sample i at time (i + start) / fs."""
    calls = []
    start = 0
    for a in nodes:
        key = (waveform, fs, float(a))
        found = _TEMPLATES.get(key)  # one look-up: threads share the cache
        if found is None:
            if len(_TEMPLATES) > 256:
                _TEMPLATES.clear()
            # a tapered call has no energy where 8x oversampling would alias it
            over = 8 if waveform.taper > 0 else 64
            found = scaled_call(waveform, float(a)).band_limited(fs, oversample=over)
            _TEMPLATES[key] = found
        y, start = found
        calls.append(y)
    L = max(y.size for y in calls)
    out = np.zeros((len(calls), L))
    for j, y in enumerate(calls):
        out[j, : y.size] = y
    return out, start


@dataclass(frozen=True, eq=False)
class DopplerPlan:
    """What :func:`render_doppler` computes from the echoes before the samples
    (:func:`plan_doppler`, steps 1-3): where the impulses go, the path gains times
    the Doppler terms and the path responses' separable terms.
    :func:`render_planned` compresses them into gain sets and makes the samples
    (steps 4-5).  A simulator plans the next measurement while the current one
    renders.

    positions (M, N): impulse positions, samples from the span's start (the span is
    output samples ``lo .. hi``); terms (K, N, M): path gains times the Chebyshev
    terms of their Doppler factors; responses (N, Q) and response_spectra (B, Q):
    the path responses' separable terms; templates (K, B): the Chebyshev
    coefficients of the time-scaled calls' spectra and products their products
    (:func:`_products`), over the ``band`` (F,) bins of an ``n_fft``-point real FFT;
    direct_paths (N,) and direct_terms (Q,): the direct path's group; single: the
    impulses and their spectra in single precision (with a path response).
    """

    positions: np.ndarray
    terms: np.ndarray
    responses: np.ndarray
    response_spectra: np.ndarray
    templates: np.ndarray
    products: np.ndarray
    direct_paths: np.ndarray
    direct_terms: np.ndarray
    band: np.ndarray
    lo: int
    hi: int
    n_fft: int
    n_mics: int
    n_samples: int
    interpolator: FractionalDelay
    taps: int
    compress_tolerance: float
    single: bool

    @property
    def empty(self) -> bool:
        return self.terms.shape[1] == 0


def render_doppler(
    echoes: Echoes,
    rate: np.ndarray,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    emission_index: int = 0,
    interpolator: FractionalDelay = "sinc",
    taps: int = DEFAULT_TAPS,
    response: PathResponse | None = None,
    tolerance: float = DOPPLER_TOLERANCE,
    compress_tolerance: float = COMPRESS_TOLERANCE,
) -> np.ndarray:
    """Microphone signals (M, T) of echoes time-scaled by `rate` (M, N): echo n at
    microphone m is ``g w_bl(rate (t - delay))`` (see the module docstring).

    `interpolator`: 'sinc' or 'lagrange' fractional delays, as the static renderer.
    `response`: air absorption and emitter directivity, factorised as the static
    renderer does (:mod:`acousim.synth.response`).  `tolerance`: of the Doppler
    nodes' interpolation; `compress_tolerance`: of the gain sets' compression.
    The same as :func:`render_planned` of :func:`plan_doppler`.
    """
    plan = plan_doppler(
        echoes,
        rate,
        waveform,
        sample_rate_hz,
        n_samples,
        emission_index=emission_index,
        interpolator=interpolator,
        taps=taps,
        response=response,
        tolerance=tolerance,
        compress_tolerance=compress_tolerance,
    )
    return render_planned(plan)


def plan_doppler(
    echoes: Echoes,
    rate: np.ndarray,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    emission_index: int = 0,
    interpolator: FractionalDelay = "sinc",
    taps: int = DEFAULT_TAPS,
    response: PathResponse | None = None,
    tolerance: float = DOPPLER_TOLERANCE,
    compress_tolerance: float = COMPRESS_TOLERANCE,
) -> DopplerPlan:
    """Steps 1-3 of :func:`render_doppler` (same arguments): the
    :class:`DopplerPlan` that :func:`render_planned` turns into samples."""
    check_interpolator(
        interpolator,
        ("sinc", "lagrange"),
        need="a moving scene",
        key="simulation.fractional_delay",
    )
    M = echoes.delay_s.shape[0]

    def nothing() -> DopplerPlan:
        none = np.zeros((0, 0))
        return DopplerPlan(
            np.zeros((M, 0)), np.zeros((1, 0, M)), none, none, none, none,
            np.zeros(0, bool), np.zeros(0, bool), np.zeros(0, bool),
            0, 0, 0, M, n_samples, interpolator, taps, compress_tolerance, False,
        )  # fmt: skip

    if echoes.n_paths == 0:
        return nothing()
    fs = sample_rate_hz
    # 1. Doppler nodes and the time-scaled calls there
    nodes = doppler_nodes(float(rate.min()), float(rate.max()), waveform, fs, tolerance)
    calls, start = _templates(waveform, fs, nodes)
    K, L = calls.shape
    # 2. the span of the output the echoes reach; each echo placed where its call's
    # middle (the pivot p) arrives less p: ``t0 + p / a - p``, and template j
    # advanced by p (1 / a_j - 1), so that every template is scaled about the pivot
    # (half the phase excursion over the Doppler factors of scaling about the start:
    # fewer nodes and sets)
    pivot = waveform.duration_s / 2
    advance = pivot * (1 / nodes - 1)  # (K,) s
    margin = int(np.ceil(np.abs(advance).max() * fs)) + 1
    d = (echoes.delay_s + pivot * (1 / rate - 1)) * fs + emission_index + start
    lo = int(np.floor(d.min())) - taps - margin
    hi = min(int(np.ceil(d.max())) + taps + L + 1 + margin, n_samples)
    if hi <= max(lo, 0):
        return nothing()
    n_span = hi - lo
    n = sfft.next_fast_len(n_span + L + 2 * taps + 258 + 2 * margin, real=True)
    key = (waveform, fs, tuple(nodes.tolist()), n)
    spectra = _cached(("spectra", *key), _template_spectra, calls, advance * fs, n)  # (K, F)
    g = echoes.gain
    N = echoes.n_paths
    # 3. path responses as separable terms u_q(f) v_q(n) (as the static renderer)
    shaped = response is not None and response.active
    if shaped:
        g, U, V, band, direct = response_factors(echoes, g, spectra[K // 2], fs, n, response)
    else:
        band = np.ones(spectra.shape[1], bool)
        U = np.ones((band.size, 1))
        V = np.ones((echoes.n_paths, 1))
        direct = np.zeros(1, bool)
    # the direct path is a group of its own only where it has its own response terms
    path_direct = echoes.order == 0 if direct.any() else np.zeros(N, bool)
    # the interpolant in the Doppler factor as a Chebyshev series: path gains times
    # T_p(s) (s the factor mapped onto [-1, 1]), (K, N, M), and the
    # templates' Chebyshev coefficients (the same polynomial as the Lagrange form,
    # with a three-term recurrence in place of the barycentric weights)
    gl = _chebyshev_terms(nodes, rate.T, g.T)
    W = _cached(("coefficients", *key, band.sum()), _chebyshev_coefficients, spectra[:, band])
    WW = _cached(("products", *key, band.sum()), _products, W)
    return DopplerPlan(
        d - lo, gl, V, U, W, WW, path_direct, direct, band,
        lo, hi, n, M, n_samples, interpolator, taps, compress_tolerance, shaped,
    )  # fmt: skip


def render_planned(plan: DopplerPlan) -> np.ndarray:
    """Steps 4-5 of :func:`render_doppler`: the microphone signals (M, T) of a
    :class:`DopplerPlan`."""
    out = np.zeros((plan.n_mics, plan.n_samples))
    if plan.empty:
        return out
    lo, hi, n = plan.lo, plan.hi, plan.n_fft
    n_span = hi - lo
    dtype = np.float32 if plan.single else np.float64
    # 4. gain sets (path, microphone) x filters (template j times response term q):
    # the K x Q products compressed per group (direct path, echoes) to the rank
    # their sum needs
    gains, filt_band = _compress(
        plan.terms,
        plan.responses,
        plan.templates,
        plan.products,
        plan.response_spectra,
        plan.direct_paths,
        plan.direct_terms,
        plan.compress_tolerance,
    )
    # the filters over the bins from the band's first to its last (zero elsewhere)
    band = plan.band
    b0, b1 = np.flatnonzero(band)[[0, -1]] + [0, 1]
    cdtype = np.complex64 if plan.single else complex
    filt = np.zeros((filt_band.shape[1], b1 - b0), cdtype)  # (sets, bins), contiguous
    filt[:, band[b0:b1]] = filt_band.T
    # 5. impulses per set, FFT, sum of products over the band, back: blocks of
    # microphones (the rows are independent: the same bits)
    M = plan.n_mics
    for m0 in range(0, M, MICS_PER_BLOCK):
        mics = slice(m0, min(m0 + MICS_PER_BLOCK, M))
        # gains (M, N, R): the sets contiguous, as the impulse sums take them
        h, pad = _impulses(
            plan.positions[mics], gains[mics], n_span, plan.interpolator, plan.taps, n, dtype
        )
        spectra = sfft.rfft(h, axis=-1, workers=FFT_WORKERS)  # (sets, mics, F)
        spec = np.zeros(spectra.shape[1:], spectra.dtype)
        inband = spec[:, b0:b1]
        np.multiply(spectra[0, :, b0:b1], filt[0], out=inband)
        term = np.empty_like(inband)
        for q in range(1, spectra.shape[0]):
            inband += np.multiply(spectra[q, :, b0:b1], filt[q], out=term)
        y = sfft.irfft(spec, n, axis=-1, workers=FFT_WORKERS)[:, pad : pad + n_span]
        out[mics, max(lo, 0) : hi] = y[:, max(lo, 0) - lo :]
    return out


def _chebyshev_terms(nodes: np.ndarray, rate: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """``gain T_p(s)`` (K, ...) for p < K, s the Doppler factors `rate` (...) mapped
    from the interval of the Chebyshev `nodes` (K,) onto [-1, 1]."""
    K = nodes.size
    out = np.empty((K, *rate.shape))
    out[0] = gain
    if K > 1:
        x = np.cos((2 * np.arange(K) + 1) * np.pi / (2 * K))
        half = (nodes[0] - nodes[-1]) / (x[0] - x[-1])
        s = (rate - (nodes[0] - half * x[0])) / half
        np.multiply(gain, s, out=out[1])
        s *= 2
        for p in range(2, K):
            np.multiply(s, out[p - 1], out=out[p])
            out[p] -= out[p - 2]
    return out


def _chebyshev_coefficients(values: np.ndarray) -> np.ndarray:
    """Chebyshev coefficients (K, ...) of the interpolant through `values` (K, ...)
    at the K Chebyshev nodes of :func:`doppler_nodes` (first kind, in its order)."""
    K = values.shape[0]
    theta = (2 * np.arange(K) + 1) * np.pi / (2 * K)
    C = np.cos(np.outer(np.arange(K), theta)) * (2.0 / K)  # C[p, j] = 2 T_p(x_j) / K
    C[0] /= 2
    return np.tensordot(C, values, axes=1)


def _template_spectra(calls: np.ndarray, advance: np.ndarray, n: int) -> np.ndarray:
    """Spectra (K, n // 2 + 1) of the templates `calls` (K, L) advanced by `advance`
    (K,) samples: ``y_j(i + advance_j)``, band-limited, exact (a linear phase)."""
    spectra = sfft.rfft(calls, n, axis=-1)
    if np.any(advance):
        f = np.arange(spectra.shape[1]) / n  # cycles per sample
        spectra *= np.exp(2j * np.pi * advance[:, None] * f[None, :])
    return spectra


def _products(W: np.ndarray) -> np.ndarray:
    """Re(conj(W_j) W_k) of the template spectra W (K, F) for j <= k (symmetric):
    (K (K + 1) / 2, F), rows in the order of ``np.triu_indices(K)``."""
    j, k = np.triu_indices(W.shape[0])
    return np.ascontiguousarray((W.conj()[j] * W[k]).real)


_CACHE: dict = {}


def _cached(key, fn, *args):
    """``fn(*args)``, computed once per key (one look-up: threads share the cache)."""
    found = _CACHE.get(key)
    if found is None:
        if len(_CACHE) > 8:
            _CACHE.clear()
        found = _CACHE[key] = fn(*args)
    return found


def _compress(gl, V, W, WW, U, path_direct, set_direct, tolerance):
    """Sets of impulse gains and their filters: ``sum_(j,q) h(g l_j v_q) * b_jq``
    with fewer sets.

    gl (K, N, M) path gains times the Doppler terms (term j, path n, microphone
    m: the Chebyshev polynomials of :func:`_chebyshev_terms`), V (N, Q) response terms; the filters
    ``b_jq(f) = W_j(f) U_q(f)`` from the template spectra W (K, F), their products
    WW (:func:`_products`) and the response terms U (F, Q); path_direct (N,) and
    set_direct (Q,) which paths and response terms belong to the direct path.  Per
    group of paths (the
    direct path, the echoes), with G (paths x S) the gains and B (F x S) the filters
    (S = K Q' sets): ``G B^T = U' D``, ``G = U' L^(1/2) E^T`` (eigendecomposition of
    the Gram matrix G^T G, formed from the factors without G), ``D = L^(1/2) E^T
    B^T``; the real SVD of D (real and imaginary parts side by side, from its Gram
    matrix) truncated where the discarded energy falls below `tolerance`^2 of the
    total gives real gains ``G E L^(-1/2) Y_r`` and filters ``Y_r^T D``.  Returns
    (gains (M, N, R), filters (F, R)).
    """
    K, N, M = gl.shape
    A = gl.transpose(1, 0, 2)  # (N, K, M)
    # per path, sum over microphones of g^2 l_j l_k: (N, K, K), for every group
    X = np.matmul(A, A.transpose(0, 2, 1))
    out_p, out_f = [], []
    for group in (True, False):
        paths = path_direct == group
        terms = set_direct == group
        if not paths.any() or not terms.any():
            continue
        Vp = np.where(paths[:, None], V[:, terms], 0.0)  # (N, Q'): zero off the group
        Q = Vp.shape[1]
        # Gram matrix of G[(m, n), (j, q)] = g l_j(a_mn) v_nq, from its factors
        VV = Vp[:, :, None] * Vp[:, None, :]  # (n, q, r)
        gram = (X.reshape(-1, K * K).T @ VV.reshape(-1, Q * Q)).reshape(K, K, Q, Q)
        gram = gram.transpose(0, 2, 1, 3).reshape(K * Q, K * Q)
        lam, E = np.linalg.eigh(gram)
        keep = lam > 1e-13 * max(lam.max(), 1e-300)
        if not keep.any():
            continue
        lam, E = lam[keep], E[:, keep]
        Uq = U[:, terms]
        S = np.sqrt(lam)[:, None] * E.T  # D = S B^T, (s, F)
        # Re(B^T conj(B)) from the template products and the response terms
        qa, qb = np.triu_indices(Q)
        part = WW @ (Uq[:, qa] * Uq[:, qb])  # both symmetric: upper triangles only
        full = np.empty((K, K, Q, Q))
        ja, jb = np.triu_indices(K)
        for c, (a, b) in enumerate(zip(qa, qb)):
            full[ja, jb, a, b] = full[jb, ja, a, b] = part[:, c]
            full[ja, jb, b, a] = full[jb, ja, b, a] = part[:, c]
        BB = full.transpose(0, 2, 1, 3).reshape(K * Q, K * Q)
        s2, Y = np.linalg.eigh(S @ BB @ S.T)
        s2, Y = np.maximum(s2[::-1], 0.0), Y[:, ::-1]
        tail = np.cumsum(s2[::-1])[::-1]  # energy from index r on
        r = max(1, int(np.sum(tail > tolerance**2 * tail[0])))
        T = ((E / np.sqrt(lam)) @ Y[:, :r]).reshape(K, Q, r)
        out_p.append((Vp @ T.transpose(1, 0, 2).reshape(Q, K * r)).reshape(N, K, r))
        Tf = (Y[:, :r].T @ S).T  # (K Q, r): filters sum_jq W_j U_q Tf[(j, q)]
        WU = (W.T[:, :, None] * Uq[:, None, :]).reshape(-1, K * Q)  # (F, K Q)
        out_f.append(WU @ Tf)
    # the new gains of all groups at once: g_new[m, n] = gl[:, n, m] P[n], stored
    # (M, N, R), the sets innermost as the impulse sums take them
    P = np.concatenate(out_p, axis=2)  # (N, K, R)
    g_new = np.empty((M, N, P.shape[2]))
    np.matmul(gl.transpose(1, 2, 0), P, out=g_new.transpose(1, 0, 2))
    return g_new, np.concatenate(out_f, axis=1)


def render_doppler_reference(
    paths: MovingPaths,
    trajectory,
    pose,
    array: Array,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    speed_of_sound_m_s: float,
    gain: np.ndarray,
    *,
    oversample: int = 64,
) -> np.ndarray:
    """The exact echoes (M, T): per output sample at `oversample` times the rate the
    emission time solved on the continuous `trajectory` (None: static sensor), the
    analytic call evaluated there times `gain` (M, N), low-passed at 0.8 Nyquist and
    decimated.  No air absorption or directivity."""
    c = speed_of_sound_m_s
    fs_fine = sample_rate_hz * oversample
    n_fine = n_samples * oversample
    window = n_samples / sample_rate_hz
    kin = SensorKinematics(trajectory, pose, array, window, None)
    M, N = array.n_mics, len(paths)
    T = waveform.duration_s
    out = np.zeros((M, n_samples))
    for m in range(M):
        fine = np.zeros(n_fine)
        for k in range(N):
            one = paths.select(slice(k, k + 1))
            ends, _, _ = _arrival_times(one, kin, np.array([[0.0, T]]), c, mic=m)
            t_a, t_b = ends[0]
            i0 = max(int(np.floor(t_a * fs_fine)) - 2, 0)
            i1 = min(int(np.ceil(t_b * fs_fine)) + 2, n_fine)
            if i1 <= i0:
                continue
            t = np.arange(i0, i1) / fs_fine
            a = T / (t_b - t_a)
            tau = a * (t - t_a)
            for _ in range(12):  # Newton with the secant slope
                arr, _, _ = _arrival_times(one, kin, tau[None, :], c, mic=m)
                step = a * (t - arr[0])
                tau = tau + step
                if np.max(np.abs(step)) < 1e-16:
                    break
            fine[i0:i1] += gain[m, k] * waveform.at(tau)
        spec = sfft.rfft(fine)
        spec[int(ANTI_ALIAS_CUTOFF * n_samples / 2) + 1 :] = 0.0
        out[m] = sfft.irfft(spec, n_fine)[::oversample]
    return out
