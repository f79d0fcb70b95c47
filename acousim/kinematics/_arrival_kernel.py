"""Compiled Newton solve of :func:`acousim.kinematics.retarded._newton_by_axis` (numba;
optional: without numba the same iteration runs on whole arrays in numpy).

Per microphone m (a row), Newton on ``f(t) = t - t_r - |m(t) - A| / c`` for every
path at once, the microphone's position and velocity polynomials in the normalised
time evaluated by Horner's rule with the paths innermost (vectorised by the
compiler), until the row's largest step falls below `stop` (the array version
stops when the whole array's does: the two agree within the stated Newton error,
not to the bit).  The GIL is released, so the renderer's thread runs meanwhile.

:func:`arrive_echoes` (what :func:`acousim.kinematics.retarded.arrivals` takes):
the call's first, last and middle sample solved in one pass over the microphones,
each Newton started where the solution nearly is (the previous microphone's, moved
to first order), every path's last step below `stop` (error about the step squared
times |f''| / 2), and each microphone's reception times turned into its echoes at
once.  Its loops take the microphones' polynomials padded to DEGREE and one
division per step, so that the compiler vectorises them over the paths (numba's
``error_model="numpy"``: a division by zero gives inf, no exception check).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def newton(t_r, A, guess, poly, poly_v, mid, half, c, stop, out):  # pragma: no cover - compiled
    """Reception times into `out` (M, N).

    t_r (M, N): when the sound leaves the anchor (s); A (M or 1, 3, N): the anchors
    (m); guess (M, N): starting times (s); poly (M, D + 1, 3) and poly_v (M, D, 3):
    each microphone's position (m) and velocity (m/s) as polynomials in
    ``x = (t - mid) / half`` (coefficients of x^0 first).
    """
    M, N = out.shape
    D = poly.shape[1] - 1
    t = np.empty(N)
    x = np.empty(N)
    p = np.empty((3, N))
    v = np.empty((3, N))
    step = np.empty(N)
    for m in range(M):
        a = 0 if A.shape[0] == 1 else m
        for n in range(N):
            t[n] = guess[m, n]
        for _ in range(20):
            for n in range(N):
                x[n] = (t[n] - mid) / half
            for i in range(3):
                for n in range(N):
                    p[i, n] = poly[m, D, i]
                    v[i, n] = poly_v[m, D - 1, i]
                for k in range(D - 1, -1, -1):
                    ck = poly[m, k, i]
                    for n in range(N):
                        p[i, n] = p[i, n] * x[n] + ck
                for k in range(D - 2, -1, -1):
                    ck = poly_v[m, k, i]
                    for n in range(N):
                        v[i, n] = v[i, n] * x[n] + ck
            for n in range(N):
                dx = p[0, n] - A[a, 0, n]
                dy = p[1, n] - A[a, 1, n]
                dz = p[2, n] - A[a, 2, n]
                dist = np.sqrt(dx * dx + dy * dy + dz * dz)
                slope = 1.0 - (v[0, n] * dx + v[1, n] * dy + v[2, n] * dz) / (max(dist, 1e-12) * c)
                step[n] = (t[n] - t_r[m, n] - dist / c) / slope
                t[n] -= step[n]
            largest = 0.0
            for n in range(N):
                largest = max(largest, abs(step[n]))
            if largest < stop:
                break
        for n in range(N):
            out[m, n] = t[n]


@njit(cache=True, nogil=True)
def newton_pieces(t_r, A, guess, bounds, mid, half, poly, poly_v, c, stop, out):  # pragma: no cover
    """:func:`newton` for motion in pieces (:class:`acousim.kinematics.sensor.Pieces`):
    each iterate evaluates the polynomials of the piece its time falls in.

    bounds (P - 1,), mid (P,), half (P,) (s); poly (P, M, D + 1, 3) and poly_v
    (P, M, D, 3); the rest as :func:`newton`.
    """
    M, N = out.shape
    P = mid.size
    D = poly.shape[2] - 1
    t = np.empty(N)
    x = np.empty(N)
    j = np.empty(N, np.int64)
    p = np.empty((3, N))
    v = np.empty((3, N))
    for m in range(M):
        a = 0 if A.shape[0] == 1 else m
        for n in range(N):
            t[n] = guess[m, n]
        for _ in range(20):
            for n in range(N):
                k = 0
                while k < P - 1 and t[n] >= bounds[k]:
                    k += 1
                j[n] = k
                x[n] = (t[n] - mid[k]) / half[k]
            for i in range(3):
                for n in range(N):
                    p[i, n] = poly[j[n], m, D, i]
                    v[i, n] = poly_v[j[n], m, D - 1, i]
                for k in range(D - 1, -1, -1):
                    for n in range(N):
                        p[i, n] = p[i, n] * x[n] + poly[j[n], m, k, i]
                for k in range(D - 2, -1, -1):
                    for n in range(N):
                        v[i, n] = v[i, n] * x[n] + poly_v[j[n], m, k, i]
            largest = 0.0
            for n in range(N):
                dx = p[0, n] - A[a, 0, n]
                dy = p[1, n] - A[a, 1, n]
                dz = p[2, n] - A[a, 2, n]
                dist = np.sqrt(dx * dx + dy * dy + dz * dz)
                slope = 1.0 - (v[0, n] * dx + v[1, n] * dy + v[2, n] * dz) / (max(dist, 1e-12) * c)
                step = (t[n] - t_r[m, n] - dist / c) / slope
                t[n] -= step
                largest = max(largest, abs(step))
            if largest < stop:
                break
        for n in range(N):
            out[m, n] = t[n]


def solve_pieces(t_r, A, guess, pieces, c, stop) -> np.ndarray:
    """:func:`newton_pieces` into a new array (M, N)."""
    out = np.empty(np.shape(guess))
    newton_pieces(
        t_r,
        A,
        guess,
        pieces.bounds,
        pieces.mid,
        pieces.half,
        pieces.mic_poly,
        pieces.mic_poly_v,
        float(c),
        float(stop),
        out,
    )
    return out


def solve(t_r, A, guess, poly, poly_v, mid, half, c, stop) -> np.ndarray:
    """:func:`newton` into a new array (M, N)."""
    out = np.empty(np.shape(guess))
    newton(t_r, A, guess, poly, poly_v, float(mid), float(half), float(c), float(stop), out)
    return out


#: the compiled solve of :func:`arrive` evaluates the microphones' polynomials at
#: this degree (acousim.kinematics.sensor.POLY_DEGREE) or at LOW, the higher
#: coefficients of a lower degree zero (the same values: Horner's rule adds exact
#: zeros first), so that its loops unroll and the paths vectorise
DEGREE = 6
#: polynomials of this degree or lower are padded to it alone (a sensor on a
#: trajectory through poses: the cubic of its segment), their Horner loops half
#: as long (the same values: the padding adds exact zeros); the degree reaches
#: the compiled functions as the length of a tuple `tag`, a constant of each
#: compiled version (numba compiles one per tuple type), so that their loops
#: still unroll
LOW = 3


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _newton_step(t, t_r, ax, ay, az, pm, pv, mid, ih, ic, tag):  # pragma: no cover - compiled
    """One Newton step on ``f(t) = t - t_r - |m(t) - A| / c`` of one path at one
    microphone: the step ``f / f'`` (s) and the microphone's offset from the anchor
    over ``c |m - A| f'`` (how the solution moves with the microphone, three
    components, s/m).  One division: ``f' = (d - v.(m - A) / c) / d`` with d the
    distance (at least 1e-12 m).

    pm (D + 1, 3) and pv (D, 3): the microphone's position (m) and velocity (m/s)
    in ``x = (t - mid) ih``, x^0 first, D the length of `tag` (DEGREE or LOW); ih
    = 1 / half (1/s), ic = 1 / c (s/m).
    """
    x = (t - mid) * ih
    D = len(tag)  # a constant of the compiled version
    px = pm[D, 0]
    py = pm[D, 1]
    pz = pm[D, 2]
    for k in range(D - 1, -1, -1):
        px = px * x + pm[k, 0]
        py = py * x + pm[k, 1]
        pz = pz * x + pm[k, 2]
    vx = pv[D - 1, 0]
    vy = pv[D - 1, 1]
    vz = pv[D - 1, 2]
    for k in range(D - 2, -1, -1):
        vx = vx * x + pv[k, 0]
        vy = vy * x + pv[k, 1]
        vz = vz * x + pv[k, 2]
    dx = px - ax
    dy = py - ay
    dz = pz - az
    dist = np.sqrt(dx * dx + dy * dy + dz * dz)
    dist = dist if dist > 1e-12 else 1e-12
    z = 1.0 / (dist - (vx * dx + vy * dy + vz * dz) * ic)  # 1 / (d f')
    w = ic * z
    return (t - t_r - dist * ic) * dist * z, dx * w, dy * w, dz * w


@njit(cache=True, nogil=True, error_model="numpy")
def _newton_pass(t, t_r, A, pm, pv, mid, ih, ic, stop, step, g, tag):  # pragma: no cover
    """One Newton step (:func:`_newton_step`) of every path at one microphone, in
    place on `t` (N,) (vectorised over the paths); the steps into `step` (N,) and
    the offsets over ``c |m - A| f'`` into `g` (three arrays (N,), s/m); how many
    steps were at least `stop` (s).  t_r (N,) s; A (3, N) m.  `g` None: the
    offsets not kept (nor computed: the call's last and middle samples need none)."""
    over = 0
    if g is None:
        for n in range(t.size):
            s = _newton_step(t[n], t_r[n], A[0, n], A[1, n], A[2, n], pm, pv, mid, ih, ic, tag)[0]
            t[n] -= s
            step[n] = s
            over += 1 if abs(s) >= stop else 0
        return over
    gx, gy, gz = g
    for n in range(t.size):
        s, gx[n], gy[n], gz[n] = _newton_step(
            t[n], t_r[n], A[0, n], A[1, n], A[2, n], pm, pv, mid, ih, ic, tag
        )
        t[n] -= s
        step[n] = s
        over += 1 if abs(s) >= stop else 0
    return over


@njit(cache=True, nogil=True, error_model="numpy")
def _solve(t, t_r, A, pm, pv, mid, ih, ic, stop, step, g, tag):  # pragma: no cover - compiled
    """Newton on `t` (N,) in place until each path's last step is below `stop` (s),
    at most 20 steps: passes over every path while more than an eighth of them
    move, then each remaining path on its own; the offsets of the last pass into
    `g` (None: not computed, :func:`_newton_pass`)."""
    N = t.size
    passes = 0
    while passes < 20:
        over = _newton_pass(t, t_r, A, pm, pv, mid, ih, ic, stop, step, g, tag)
        passes += 1
        if over == 0:
            return
        if 8 * over < N:
            break
    for n in range(N):
        s = step[n]
        for _ in range(20 - passes):
            if abs(s) < stop:
                break
            s = _newton_step(t[n], t_r[n], A[0, n], A[1, n], A[2, n], pm, pv, mid, ih, ic, tag)[0]
            t[n] -= s


@njit(cache=True, nogil=True, error_model="numpy")
def arrive(t_r, A, duration, poly, poly_v, mid, half, c, stop, out, tag):  # pragma: no cover
    """Reception times of the call's first, last and middle sample (instants 0, 1, 2)
    of every path at every microphone into `out` (M, 3, N) (s): per microphone and
    instant, Newton on ``f(t) = t - t_r - |m(t) - A| / c`` (as :func:`newton`) until
    each path's last step is below `stop` (s), started where the solution nearly is:

    - the first sample: at the first microphone from t_r (the first step exact for
      a microphone at constant velocity); at each next one from the previous one's
      solution moved by the first-order change of the distance, the offset between
      the microphones (at the window's middle, x = 0) along the previous one's
      direction to the anchor (left: the offset's square over the distance, and
      the turn during the delay);
    - the last sample: the first sample's plus the call's length at the previous
      microphone (at the first one `duration`, s);
    - the middle sample: the chord's middle plus its curvature at the previous
      microphone (at the first one, none).

    t_r (3, N): when each instant's sample leaves the path's last anchor (s); A
    (3, 3, N): the anchors then (instant, coordinate, path; m); poly (M, D + 1, 3)
    and poly_v (M, D, 3): each microphone's position (m) and velocity (m/s) in
    ``x = (t - mid) / half``, x^0 first; `tag`: a tuple of D zeros (D = DEGREE or
    LOW: :func:`_padded`).
    """
    M, _, N = out.shape
    work = _work(N, tag)
    for m in range(M):
        prev = out[m - 1] if m > 0 else out[0]
        _arrive_row(m, t_r, A, duration, poly, poly_v, mid, half, c, stop, prev, out[m], work)


@njit(cache=True, nogil=True, error_model="numpy")
def arrive_echoes(t_r, A, duration, poly, poly_v, mid, half, c, stop, echo, tag):  # noqa: E501  # pragma: no cover
    """:func:`arrive`, each microphone's reception times turned into its echoes at
    once (:func:`_echo_row`; only two microphones' times are kept): `echo` the
    first legs (N,) (m) and amplitudes (N,) at the start of the emission, then the
    delays, gains, lengths, rates and curvatures (M, N) written."""
    first_leg, amplitude, delay, gain, length, rate, curvature = echo
    M, N = delay.shape
    work = _work(N, tag)
    rows = np.empty((2, 3, N))
    for m in range(M):
        cur, prev = rows[m % 2], rows[(m + 1) % 2]
        _arrive_row(m, t_r, A, duration, poly, poly_v, mid, half, c, stop, prev, cur, work)
        _echo_row(
            cur,
            first_leg,
            amplitude,
            c,
            duration,
            delay[m],
            gain[m],
            length[m],
            rate[m],
            curvature[m],
        )


@njit(cache=True, nogil=True)
def _work(N, tag):  # pragma: no cover - compiled
    """The scratch arrays of :func:`_arrive_row` for N paths: the steps, and the
    first sample's sensitivity to the microphone's position (s/m, three arrays: at
    the previous microphone; the other instants need none); and `tag` (the
    polynomials' degree, :func:`arrive`)."""
    g = (np.empty(N), np.empty(N), np.empty(N))
    return np.empty(N), g, tag


@njit(cache=True, nogil=True, error_model="numpy")
def _arrive_row(m, t_r, A, duration, poly, poly_v, mid, half, c, stop, prev, cur, work):  # noqa: E501  # pragma: no cover
    """Microphone m's reception times of the three instants into `cur` (3, N), the
    previous microphone's in `prev` (3, N) (m > 0): :func:`arrive`'s starts."""
    N = cur.shape[1]
    ih = 1.0 / half
    ic = 1.0 / c
    step, g, tag = work
    first, last, middle = cur[0], cur[1], cur[2]
    if m == 0:
        first[:] = t_r[0]
    else:
        ox = poly[m, 0, 0] - poly[m - 1, 0, 0]
        oy = poly[m, 0, 1] - poly[m - 1, 0, 1]
        oz = poly[m, 0, 2] - poly[m - 1, 0, 2]
        gx, gy, gz = g
        for n in range(N):
            first[n] = prev[0, n] + (gx[n] * ox + gy[n] * oy + gz[n] * oz)
    _solve(first, t_r[0], A[0], poly[m], poly_v[m], mid, ih, ic, stop, step, g, tag)
    if m == 0:
        for n in range(N):
            last[n] = first[n] + duration
    else:
        for n in range(N):
            last[n] = first[n] + (prev[1, n] - prev[0, n])
    _solve(last, t_r[1], A[1], poly[m], poly_v[m], mid, ih, ic, stop, step, None, tag)
    if m == 0:
        for n in range(N):
            middle[n] = 0.5 * (first[n] + last[n])
    else:
        for n in range(N):
            bend = prev[2, n] - 0.5 * (prev[0, n] + prev[1, n])
            middle[n] = 0.5 * (first[n] + last[n]) + bend
    _solve(middle, t_r[2], A[2], poly[m], poly_v[m], mid, ih, ic, stop, step, None, tag)


@njit(cache=True, nogil=True, error_model="numpy")
def _echo_row(t, first, amplitude, c, duration, delay, gain, length, rate, curvature):  # noqa: E501  # pragma: no cover
    """One microphone's echoes from its reception times `t` (3, N) of the call's
    first, last and middle sample (s), as :func:`acousim.kinematics.retarded.
    _echo_terms` computes them (the same operations in the same order): the last leg
    ``max(c t0 - first, 1e-6)`` (m), the length, the gain ``amplitude / last``, the
    curvature ``tm - (t0 + t1) / 2``, the delay ``t0 + 2/3 curvature`` and the rate
    ``duration / (t1 - t0)``, each into its (N,) array.  first (N,): the first legs
    (m); amplitude (N,): the strengths times the spreading of the first leg."""
    for n in range(t.shape[1]):
        t0 = t[0, n]
        t1 = t[1, n]
        last = c * t0 - first[n]
        if last < 1e-6:
            last = 1e-6
        length[n] = first[n] + last
        gain[n] = amplitude[n] / last
        bend = t[2, n] - 0.5 * (t0 + t1)
        curvature[n] = bend
        delay[n] = t0 + bend * (2.0 / 3.0)
        rate[n] = duration / (t1 - t0)


def _padded(poly, poly_v):
    """The polynomials (M, K, 3), (M, K - 1, 3) padded with zeros to LOW (K - 1 up
    to LOW) or DEGREE, and the compiled functions' `tag` of that degree."""
    M, K, _ = poly.shape
    if K > DEGREE + 1:
        raise ValueError(f"polynomials of degree {K - 1}: at most {DEGREE}")
    D = LOW if K <= LOW + 1 else DEGREE
    pm = np.zeros((M, D + 1, 3))
    pm[:, :K] = poly
    pv = np.zeros((M, D, 3))
    pv[:, : K - 1] = poly_v
    return pm, pv, (0,) * D


def solve_arrivals(t_r, A, duration, poly, poly_v, mid, half, c, stop) -> np.ndarray:
    """:func:`arrive` into a new array (3, M, N) (a view), the polynomials padded to
    LOW or DEGREE."""
    pm, pv, tag = _padded(poly, poly_v)
    out = np.empty((poly.shape[0], 3, t_r.shape[1]))
    args = (np.array(t_r, float), np.ascontiguousarray(A, float), float(duration), pm, pv)
    arrive(*args, float(mid), float(half), float(c), float(stop), out, tag)
    return out.transpose(1, 0, 2)


def solve_echoes(t_r, A, duration, poly, poly_v, mid, half, c, stop, first_leg, amplitude):
    """:func:`arrive_echoes` into new arrays: delays (s), gains, lengths (m), rates and
    curvatures (s), each (M, N)."""
    pm, pv, tag = _padded(poly, poly_v)
    M, N = poly.shape[0], t_r.shape[1]
    terms = tuple(np.empty((M, N)) for _ in range(5))
    echo = (np.array(first_leg, float), np.array(amplitude, float), *terms)
    args = (np.array(t_r, float), np.ascontiguousarray(A, float), float(duration), pm, pv)
    arrive_echoes(*args, float(mid), float(half), float(c), float(stop), echo, tag)
    return terms


@njit(cache=True, nogil=True)
def leaving_still(anchor, mirror, legs, departure, emitter, tau, c, out):  # pragma: no cover
    """:func:`acousim.kinematics.retarded._retarded` of still anchors (no velocity,
    no acceleration: they move with the emitter alone) at the emission times `tau`
    (Q,) (s): per instant q and path n, the anchor ``a0 + J de`` (de the emitter's
    displacement from the start of the emission) and the first leg (held, by
    Fermat's law or exact, as the path's code says), the same operations as there.

    anchor (N, 3) m, mirror (N, 3, 3), departure (N, 3); `legs`: the first legs at
    tau = 0 (N,) (m), their codes (N,) (FirstLeg: 0 held, 1 Fermat, 2 exact) and
    Fermat lengths (N,) (m); `emitter`: its positions at `tau` (Q, 3) and at the
    start of the emission (3,) (m).  Into `out`: when each sample leaves the anchor
    (Q, N) (s), the anchors then (Q, 3, N) (instant, coordinate, path; m) and the
    first legs at the first instant (N,) (m).
    """
    f0, mode, lf = legs
    e, e0 = emitter
    t_r, A, first0 = out
    for q in range(tau.size):
        dx, dy, dz = e[q, 0] - e0[0], e[q, 1] - e0[1], e[q, 2] - e0[2]
        dd = dx * dx + dy * dy + dz * dz
        for n in range(f0.size):
            for i in range(3):
                shift = mirror[n, i, 0] * dx + mirror[n, i, 1] * dy + mirror[n, i, 2] * dz
                A[q, i, n] = anchor[n, i] + shift
            first = f0[n]
            if mode[n] == 1:
                along = departure[n, 0] * dx + departure[n, 1] * dy + departure[n, 2] * dz
                first = f0[n] - along + (dd - along * along) / (2 * lf[n])
            elif mode[n] == 2:
                ux, uy, uz = A[q, 0, n] - e[q, 0], A[q, 1, n] - e[q, 1], A[q, 2, n] - e[q, 2]
                first = np.sqrt(ux * ux + uy * uy + uz * uz)
            t_r[q, n] = tau[q] + first / c
            if q == 0:
                first0[n] = first
