"""When the call reaches each microphone along each path: retarded time, Doppler.

A sample of the call emitted at time tau (after the start of the emission) from
the emitter at ``e(tau)`` reaches microphone m at the time t that solves

    t = t_r + |m(t) - A(tau, t_r)| / c,      t_r = tau + F(tau, t_r) / c

with A the path's last anchor (image source, scatterer or reflector) and F its first
leg (:class:`acousim.trace.motion.following.MovingPaths`, whose docstring states how the
paths follow the motion).  The microphone records ``g w(tau(t))``: the call
delayed and time-compressed (Doppler), exactly.  :func:`arrivals` solves it at the
call's first, middle and last sample for every path and microphone: a typed
:class:`Arrivals` (echoes at the start of the call, Doppler factors, curvature) for
the renderer (:mod:`acousim.synth.doppler`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.core.echoes import Echoes
from acousim.kinematics.sensor import SensorKinematics
from acousim.trace.motion.following import FirstLeg, MovingPaths
from processing.base.kernels import optional_kernel

__all__ = ["Arrivals", "arrivals", "arrival_times", "NEWTON_STOP_S"]

#: Newton on the reception time stops after a step below this (error: about the
#: step squared times |f''| / 2, |f''| below 1.5 / s: under 1e-12 s, see
#: :func:`_newton_by_axis`)
NEWTON_STOP_S = 1e-6


def arrival_times(paths: MovingPaths, kin: SensorKinematics, tau, c: float, mic=None, guess=None):
    """Reception times of the samples emitted at `tau`: a number (one emission time
    for every path and microphone), (M, N) with mic None (row i: microphone i), or
    (N, S) for microphone `mic` (path n in row n).  `c` in m/s; `guess`: reception
    times to start Newton from (the shape of the result).

    Returns (t, anchor, first_leg): t (M, N) (a number or mic None) or (N, S), the
    others broadcast against it (anchor with a last axis 3).
    """
    tau = np.asarray(tau, float)
    t_r, anchor, first = _retarded(paths, kin, tau, c, mic)
    if mic is None and getattr(kin, "poly", None) is not None and t_r.ndim == 2:
        return _newton_by_axis(kin, t_r, anchor, c, guess), anchor, first
    if mic is None and getattr(kin, "pieces", None) is not None and t_r.ndim == 2:
        return _newton_pieces(kin, t_r, anchor, c, guess), anchor, first
    if mic is None and not kin.static and kin.step is not None:
        return _newton_tabulated(kin, t_r, anchor, c, guess), anchor, first
    t = t_r + np.linalg.norm(kin.mics(t_r, mic) - anchor, axis=-1) / c
    for _ in range(20):
        new = t_r + np.linalg.norm(kin.mics(t, mic) - anchor, axis=-1) / c
        change = np.max(np.abs(new - t)) if new.size else 0.0
        t = new
        if change < 1e-14:
            break
    return t, anchor, first


def _retarded(paths: MovingPaths, kin: SensorKinematics, tau: np.ndarray, c: float, mic):
    """The emitting side of :func:`arrival_times`: when the sound emitted at `tau`
    leaves the path's last anchor (t_r), where the anchor is then, and the first
    leg, shaped as :func:`arrival_times` returns them."""
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
    shift = _anchor_shift(paths, J, de, scalar, mic)

    still = not moving and not accelerating  # the anchors move with the emitter only

    def at(t):  # the anchors where they are at t (s)
        if still:  # (u t and the acceleration's term zero)
            return a0 + shift
        out = a0 + shift + u * t[..., None]
        return out + 0.5 * acc * t[..., None] ** 2 if accelerating else out

    held = _held_legs(paths, f0, mode, dep, lf, de)
    exact_any = bool(np.any(paths.first_leg == FirstLeg.exact))
    for _ in range(8 if moving else 1):
        anchor = at(t_r)
        first = held
        if exact_any:
            first = np.where(mode == FirstLeg.exact, np.linalg.norm(anchor - e, axis=-1), held)
        new = tau + first / c
        done = not moving or np.max(np.abs(new - t_r)) < 1e-15
        t_r = new
        if done:
            break
    if not still:
        anchor = at(t_r)
    first = np.broadcast_to(first, np.shape(t_r))
    if scalar:
        shape = (kin.mics0.shape[0], len(paths))
        t_r, anchor = np.broadcast_to(t_r, shape), anchor[None]
        first = np.broadcast_to(first, shape)
    return t_r, anchor, first


def _anchor_shift(paths: MovingPaths, J, de, scalar: bool, mic) -> np.ndarray:
    """How far each path's anchor moves with the emitter displaced by `de` (m), shaped
    as :func:`_retarded` takes it: one matrix-vector product for a single emission
    time (batched 3 x 3 products cost 50 times more)."""
    if scalar:
        return (paths.mirror.reshape(-1, 3) @ de).reshape(-1, 3)
    if mic is None and de.shape[1:] == (1, 3):  # an emission time per row: one product
        shift = (paths.mirror.reshape(-1, 3) @ de[:, 0].T).reshape(-1, 3, len(de))
        return shift.transpose(2, 0, 1)
    return np.matmul(J, de[..., None])[..., 0]


def _held_legs(paths: MovingPaths, f0, mode, dep, lf, de):
    """The first legs (m) that do not depend on where the anchors are: held, or by
    Fermat's law where a path takes it (the emitter displaced by `de`)."""
    if not np.any(paths.first_leg == FirstLeg.fermat):
        return f0
    along = np.sum(dep * de, axis=-1)
    fermat = f0 - along + (np.sum(de * de, axis=-1) - along**2) / (2 * lf)
    return np.where(mode == FirstLeg.fermat, fermat, f0)


def _newton_tabulated(kin: SensorKinematics, t_r, anchor, c: float, guess) -> np.ndarray:
    """Reception times (M, N) for the tabulated kinematics (as :func:`_newton_by_axis`)."""
    t = t_r + np.linalg.norm(kin.mics(t_r) - anchor, axis=-1) / c if guess is None else guess
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
    return t


#: Newton over pieces of motion stops after a step below this (s): a step may cross
#: a knot, where the microphones' velocity (the slope) jumps, so the quadratic
#: error bound of :data:`NEWTON_STOP_S` does not hold; as the table's, this one
#: leaves below 1e-10 s whatever the slope's jump
PIECES_STOP_S = 1e-7


def _newton_pieces(kin: SensorKinematics, t_r, anchor, c: float, guess) -> np.ndarray:
    """Reception times (M, N) for kinematics in pieces (:class:`~acousim.kinematics.
    sensor.Pieces`): Newton as :func:`_newton_by_axis`, each iterate on the
    polynomials of its piece."""
    pieces = kin.pieces
    A = np.ascontiguousarray(np.moveaxis(anchor, -1, -2))  # (M or 1, 3, N)
    t = np.array(np.broadcast_to(t_r, t_r.shape) if guess is None else guess, float)
    t_r = np.broadcast_to(t_r, t.shape)
    compiled = optional_kernel("acousim.kinematics._arrival_kernel", "solve_pieces")
    if compiled is not None:
        return compiled(t_r, A, t, pieces, c, PIECES_STOP_S)
    rows = np.arange(t.shape[0])[:, None]
    for _ in range(20):
        j = np.searchsorted(pieces.bounds, t, side="right")  # (M, N): each time's piece
        x = ((t - pieces.mid[j]) / pieces.half[j])[..., None]
        poly, poly_v = pieces.mic_poly[j, rows], pieces.mic_poly_v[j, rows]  # (M, N, D+1, 3)
        pos = poly[:, :, -1]
        for k in range(poly.shape[2] - 2, -1, -1):
            pos = pos * x + poly[:, :, k]
        vel = poly_v[:, :, -1]
        for k in range(poly_v.shape[2] - 2, -1, -1):
            vel = vel * x + poly_v[:, :, k]
        diff = pos - np.moveaxis(A, -2, -1)
        dist = np.sqrt(np.sum(diff * diff, axis=-1))
        slope = 1 - np.sum(vel * diff, axis=-1) / (np.maximum(dist, 1e-12) * c)
        step = (t - t_r - dist / c) / slope
        t = t - step
        if np.max(np.abs(step)) < PIECES_STOP_S:
            break
    return t


def _newton_by_axis(kin: SensorKinematics, t_r, anchor, c: float, guess) -> np.ndarray:
    """Reception times (M, N) for the polynomial kinematics: Newton on
    ``f(t) = t - t_r - |m(t) - A| / c`` as in :func:`arrival_times`, with the
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
        # 1e-13 s, 8e-13 s (-128 dB at 80 kHz)
        if np.max(np.abs(step)) < NEWTON_STOP_S:
            break
    return t


def _arrival_kernel():
    """The compiled Newton solve, or None when numba is not installed."""
    return optional_kernel("acousim.kinematics._arrival_kernel", "solve")


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
    #: (N,) when the call's first sample leaves each path's last anchor (s), and
    #: (N, 3) where that anchor is then (m): the start of the last leg
    leave_s: np.ndarray | None = None
    anchor_m: np.ndarray | None = None


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
    fused = _leaving(paths, kin, duration_s, c)
    if fused is None:
        t0, anchor, first = arrival_times(paths, kin, 0.0, c)
        # started from a line, then from the chord: one or two Newton steps each
        t1, _, _ = arrival_times(paths, kin, duration_s, c, guess=t0 + duration_s)
        tm, _, _ = arrival_times(paths, kin, duration_s / 2, c, guess=0.5 * (t0 + t1))
    else:
        t_r, A, anchor, first = fused
    # spreading: strength is a_k / r_e at tau = 0; a moving point's first leg is
    # the one at its reflection
    exact = paths.first_leg == FirstLeg.exact
    # the first leg is one per path at tau = 0 (a broadcast row): the factor per path
    one = first[0] if first.ndim == 2 and first.strides[0] == 0 else first
    spread = np.where(exact, paths.first_leg_m / np.maximum(one, 1e-9), 1.0)
    amplitude = paths.strength * spread
    if fused is None:
        delay, gain, length, rate, curvature = _echo_terms(
            t0, t1, tm, first, amplitude, c, duration_s
        )
    else:  # solved and turned into echoes microphone by microphone, compiled
        poly, poly_v, mid, half = kin.mic_poly, kin.mic_poly_v, kin.mid, kin.half
        delay, gain, length, rate, curvature = _kernel("solve_echoes")(
            t_r, A, duration_s, poly, poly_v, mid, half, c, NEWTON_STOP_S, one, amplitude
        )
    cos = np.clip(paths.departure @ emitter_axis, -1, 1)
    echoes = Echoes(delay, gain, length, paths.order.copy(), np.arccos(cos))
    leave = np.broadcast_to(first, delay.shape)[0] / c
    start = np.broadcast_to(anchor, (*delay.shape, 3))[0]
    return Arrivals(echoes, rate, curvature, leave, start)


def _echo_terms(t0, t1, tm, first, amplitude, c: float, duration_s: float):
    """Delays, gains, lengths, rates and curvatures (M, N) of :func:`arrivals` from
    the reception times (M, N) of the call's first, last and middle sample (s), the
    first legs (m) and the amplitudes (N,) (array version of the compiled
    :func:`acousim.kinematics._arrival_kernel._echo_row`)."""
    # the last leg from the solved retarded-time equation, t0 = first / c + last / c
    # (within c times its error, below 1e-10 m)
    last = np.maximum(c * t0 - first, 1e-6)
    length = first + last
    gain = amplitude / last
    # the linear law through the first and last sample, shifted by the mean of the
    # (parabolic) deviation: two thirds of the deviation at the middle
    curvature = tm - 0.5 * (t0 + t1)
    return t0 + curvature * (2 / 3), gain, length, duration_s / (t1 - t0), curvature


def _leaving(paths: MovingPaths, kin: SensorKinematics, duration_s: float, c: float):
    """For the compiled solve (:func:`acousim.kinematics._arrival_kernel.
    arrive_echoes`): when the call's first, last and middle sample leave each path's
    last anchor (3, N) (s), and the anchors then (3, 3, N) (instant, coordinate,
    path; m), with the anchors (1, N, 3) and first legs (N,) at the start of the
    emission; None where it does not apply (no numba; kinematics not one
    polynomial)."""
    if kin.static or kin.step is None or getattr(kin, "poly", None) is None:
        return None
    if _kernel("solve_echoes") is None:
        return None
    tau = np.array([[0.0], [duration_s], [duration_s / 2]])
    still = _kernel("leaving_still")
    if still is not None and not np.any(paths.velocity_m_s) and not np.any(paths.acceleration_m_s2):
        # the anchors move with the emitter alone: compiled, the arrays the solve takes
        N = len(paths)
        out = (np.empty((3, N)), np.empty((3, 3, N)), np.empty(N))
        legs = (paths.first_leg_m, np.asarray(paths.first_leg, np.int64), paths.fermat_length_m)
        emitter = (kin.emitter(tau)[:, 0], kin.emitter0)
        still(paths.anchor_m, paths.mirror, legs, paths.departure, emitter, tau[:, 0], c, out)
        return out[0], out[1], out[1][:1].transpose(0, 2, 1), out[2]
    t_r, anchor, first = _retarded(paths, kin, tau, c, None)  # (3, N), (3, N, 3), (3, N)
    return t_r, anchor.transpose(0, 2, 1), anchor[:1], np.array(first[0])


def _kernel(name: str):
    """A compiled function of :mod:`acousim.kinematics._arrival_kernel`, or None
    when numba is not installed."""
    return optional_kernel("acousim.kinematics._arrival_kernel", name)
