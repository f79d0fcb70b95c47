"""Compiled kernels of :mod:`processing.imaging.broadband.energyscape` (numba; optional).

Both kernels delay every microphone's complex baseband by linear interpolation on
a copy upsampled U times by FFT, apply the carrier phase ``exp(-j 2 pi f0 d)``, and
accumulate per direction and output sample: the sum ``S = sum s_m``, the energy
``E = sum |s_m|^2`` (for CF) and, for DMAS of order P, the power sums
``p_k = sum s^_m^k`` (k = 1..P) of the signed P-th roots, which are interpolated
from a rooted copy of the upsampled baseband (the root of an interpolation and the
interpolation of the root differ by the interpolation error; the benchmark
measures it against the plain formula).  Then DAS ``|S/M|^2`` or DMAS
``|e_P / C(M, P)|^2`` (Newton-Girard), times CF, averaged over blocks of D samples
and over the K measurements.

* :func:`far_field`: delays constant per (direction, microphone); the upsampled
  signal is stored polyphase, ``zp[k, m, phase, n] = z_fine[k, m, n U + phase]``,
  as float32 real and imaginary parts, so each (direction, microphone) streams
  contiguous rows in a loop that vectorises.
* :func:`far_das_spectrum`: plain far-field DAS only, exact: the phase-ramped
  spectra summed over the microphones (one beam spectrum per direction, inverse-
  transformed by the caller), no upsampling or interpolation.
* :func:`near_field`: delays computed per (direction, microphone, range) from the
  geometry inside the kernel (no G x M x N delay table in memory).

No kernel here uses ``fastmath``: with ``parallel=True`` numba's freshly compiled
code and the code it loads from its cache contract (fuse) different multiply-adds,
so the first run after an install gave images about 1e-6 off every later run's
(numba 0.68; plain IEEE arithmetic is the same both ways, and costs about 10 % of
:func:`far_field` alone).  ``tests/processing/imaging/test_kernel_cache.py``
compares the two.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always")
def _combine(S, E, P, M, order, cf, binom):
    """Power of one output sample from S, E and the power sums P[1..5] (no
    allocation: the Newton-Girard recursion written out to order 5)."""
    if order == 1:
        v = S / M
    else:
        p1, p2, p3, p4, p5 = P[1], P[2], P[3], P[4], P[5]
        e = (p1 * p1 - p2) / 2
        if order >= 3:
            e3 = (e * p1 - p1 * p2 + p3) / 3
            if order >= 4:
                e4 = (e3 * p1 - e * p2 + p1 * p3 - p4) / 4
                if order == 5:
                    e = (e4 * p1 - e3 * p2 + e * p3 - p1 * p4 + p5) / 5
                else:
                    e = e4
            else:
                e = e3
        v = e / binom
    out = v.real * v.real + v.imag * v.imag
    if cf:
        if E > 0:
            out *= (S.real * S.real + S.imag * S.imag) / (M * E)
        else:
            out = 0.0
    return out


@njit(cache=True, inline="always")
def _interpolate(zr, zi, k, m, g, q, ph, w, Nw, xr, xi, add):
    """The interpolated, phase-rotated channel m of direction g: written to (or, with
    `add`, added to) xr, xi (Nw,).  The 4-tap (cubic) case sums its taps in one pass,
    so the accumulators are loaded and stored once instead of once per tap (twice
    when written: zeroed first)."""
    T = q.shape[2]
    if not add:  # written: start from zero, then every tap is added
        xr[:] = 0
        xi[:] = 0
    if T == 4:
        p0, p1, p2, p3 = ph[g, m, 0], ph[g, m, 1], ph[g, m, 2], ph[g, m, 3]
        s0, s1, s2, s3 = q[g, m, 0], q[g, m, 1], q[g, m, 2], q[g, m, 3]
        a0r, a0i = zr[k, m, p0, s0 : s0 + Nw], zi[k, m, p0, s0 : s0 + Nw]
        a1r, a1i = zr[k, m, p1, s1 : s1 + Nw], zi[k, m, p1, s1 : s1 + Nw]
        a2r, a2i = zr[k, m, p2, s2 : s2 + Nw], zi[k, m, p2, s2 : s2 + Nw]
        a3r, a3i = zr[k, m, p3, s3 : s3 + Nw], zi[k, m, p3, s3 : s3 + Nw]
        w0r, w0i = np.float32(w[g, m, 0].real), np.float32(w[g, m, 0].imag)
        w1r, w1i = np.float32(w[g, m, 1].real), np.float32(w[g, m, 1].imag)
        w2r, w2i = np.float32(w[g, m, 2].real), np.float32(w[g, m, 2].imag)
        w3r, w3i = np.float32(w[g, m, 3].real), np.float32(w[g, m, 3].imag)
        for j in range(Nw):
            xr[j] += (
                a0r[j] * w0r
                - a0i[j] * w0i
                + a1r[j] * w1r
                - a1i[j] * w1i
                + a2r[j] * w2r
                - a2i[j] * w2i
                + a3r[j] * w3r
                - a3i[j] * w3i
            )
            xi[j] += (
                a0r[j] * w0i
                + a0i[j] * w0r
                + a1r[j] * w1i
                + a1i[j] * w1r
                + a2r[j] * w2i
                + a2i[j] * w2r
                + a3r[j] * w3i
                + a3i[j] * w3r
            )
        return
    for t in range(T):
        wr, wi = np.float32(w[g, m, t].real), np.float32(w[g, m, t].imag)
        ar = zr[k, m, ph[g, m, t], q[g, m, t] : q[g, m, t] + Nw]
        ai = zi[k, m, ph[g, m, t], q[g, m, t] : q[g, m, t] + Nw]
        for j in range(Nw):
            xr[j] += ar[j] * wr - ai[j] * wi
            xi[j] += ar[j] * wi + ai[j] * wr


@njit(parallel=True, cache=True)
def far_field(zr, zi, rr, ri, q, ph, w, order, cf, binom, D, out):
    """zr, zi (and rooted rr, ri): (K, M, U, Nq) float32 real and imaginary parts;
    q, ph (G, M, T) int: polyphase row and start of each of the T interpolation taps;
    w (G, M, T) complex: tap weights times the carrier phase; out (R, G) written.

    Real and imaginary parts in separate float32 rows so the inner loop over output
    samples vectorises; sums of M = 32 terms in float32 err by about 1e-6.
    """
    K, M, U, Nq = zr.shape
    G, _, T = q.shape
    R = out.shape[0]
    Nw = R * D
    for g in prange(G):
        acc = np.zeros(Nw)
        Sr = np.empty(Nw, np.float32)
        Si = np.empty(Nw, np.float32)
        E = np.empty(Nw, np.float32)
        xr = np.empty(Nw, np.float32)
        xi = np.empty(Nw, np.float32)
        Pr = np.empty((6, Nw), np.float32)
        Pi = np.empty((6, Nw), np.float32)
        Pj = np.zeros(6, np.complex128)
        for k in range(K):
            Sr[:] = 0
            Si[:] = 0
            E[:] = 0
            Pr[:] = 0
            Pi[:] = 0
            for m in range(M):
                if order == 1 and not cf:  # plain DAS: accumulate the sum directly
                    _interpolate(zr, zi, k, m, g, q, ph, w, Nw, Sr, Si, True)
                    continue
                _interpolate(zr, zi, k, m, g, q, ph, w, Nw, xr, xi, False)
                for j in range(Nw):
                    Sr[j] += xr[j]
                    Si[j] += xi[j]
                    E[j] += xr[j] * xr[j] + xi[j] * xi[j]
                if order > 1:
                    _interpolate(rr, ri, k, m, g, q, ph, w, Nw, xr, xi, False)
                    # every power up to 5, branch-free so the loop vectorises
                    p1r, p1i, p2r, p2i = Pr[1], Pi[1], Pr[2], Pi[2]
                    p3r, p3i, p4r, p4i = Pr[3], Pi[3], Pr[4], Pi[4]
                    p5r, p5i = Pr[5], Pi[5]
                    for j in range(Nw):
                        ur, ui = xr[j], xi[j]
                        x2r = ur * ur - ui * ui
                        x2i = 2 * ur * ui
                        x3r = x2r * ur - x2i * ui
                        x3i = x2r * ui + x2i * ur
                        x4r = x2r * x2r - x2i * x2i
                        x4i = 2 * x2r * x2i
                        p1r[j] += ur
                        p1i[j] += ui
                        p2r[j] += x2r
                        p2i[j] += x2i
                        p3r[j] += x3r
                        p3i[j] += x3i
                        p4r[j] += x4r
                        p4i[j] += x4i
                        p5r[j] += x4r * ur - x4i * ui
                        p5i[j] += x4r * ui + x4i * ur
            for j in range(Nw):
                if order > 1:
                    for kk in range(1, 6):
                        Pj[kk] = complex(Pr[kk, j], Pi[kk, j])
                acc[j] += _combine(complex(Sr[j], Si[j]), E[j], Pj, M, order, cf, binom)
        for r in range(R):
            v = 0.0
            for j in range(r * D, (r + 1) * D):
                v += acc[j]
            out[r, g] = v / (D * K)


@njit(cache=True, inline="always")
def _near_delay(u0, u1, u2, rj, pos, emitter, c, out):
    """Delays (s) of every microphone for the focus point at range rj along u."""
    x0, x1, x2 = rj * u0, rj * u1, rj * u2
    de = math.sqrt((x0 - emitter[0]) ** 2 + (x1 - emitter[1]) ** 2 + (x2 - emitter[2]) ** 2)
    for m in range(pos.shape[0]):
        dm = math.sqrt((x0 - pos[m, 0]) ** 2 + (x1 - pos[m, 1]) ** 2 + (x2 - pos[m, 2]) ** 2)
        out[m] = (2 * rj - de - dm) / c


@njit(parallel=True, cache=True)
def near_field(
    zf, rf, u, pos, emitter, range0, range_step, t0, rate_fine, f0, c, order, cf, binom, D, out
):
    """zf, rf (K, M, Nf) complex upsampled baseband (rf: rooted); u (G, 3); pos (M, 3).

    Output sample j is at range ``range0 + j range_step`` and, before its delay, at
    fine index ``t0 + j rate_fine range_step * 2 / c``.  The delays are exact at the
    ends of each block of D samples and linear in between (their curvature over one
    block is below 1e-8 s at 0.5 m for a 6 cm aperture), the carrier phase follows
    them by a constant rotation per sample; out (R, G) written.
    """
    K, M, Nf = zf.shape
    G = u.shape[0]
    R = out.shape[0]
    two_pi_f0 = 2 * math.pi * f0
    fine_per_sample = rate_fine * 2 * range_step / c
    for g in prange(G):
        P = np.zeros(6, np.complex128)
        d_lo = np.empty(M)
        d_hi = np.empty(M)
        ph = np.empty(M, np.complex128)
        rot = np.empty(M, np.complex128)
        _near_delay(u[g, 0], u[g, 1], u[g, 2], range0, pos, emitter, c, d_lo)
        for r in range(R):
            _near_delay(
                u[g, 0], u[g, 1], u[g, 2], range0 + (r + 1) * D * range_step, pos, emitter, c, d_hi
            )
            for m in range(M):
                ph[m] = complex(math.cos(two_pi_f0 * d_lo[m]), -math.sin(two_pi_f0 * d_lo[m]))
                step = two_pi_f0 * (d_hi[m] - d_lo[m]) / D
                rot[m] = complex(math.cos(step), -math.sin(step))
            v = 0.0
            for jj in range(D):
                j = r * D + jj
                tj = t0 + j * fine_per_sample
                for k in range(K):
                    S = 0j
                    E = 0.0
                    for kk in range(6):
                        P[kk] = 0
                    for m in range(M):
                        d = d_lo[m] + (d_hi[m] - d_lo[m]) * jj / D
                        p = tj - d * rate_fine
                        i0 = int(math.floor(p))
                        if i0 < 0:
                            i0 = 0
                        if i0 > Nf - 2:
                            i0 = Nf - 2
                        fr = min(max(p - i0, 0.0), 1.0)
                        s = (zf[k, m, i0] * (1 - fr) + zf[k, m, i0 + 1] * fr) * ph[m]
                        S += s
                        E += s.real * s.real + s.imag * s.imag
                        if order > 1:
                            rr = (rf[k, m, i0] * (1 - fr) + rf[k, m, i0 + 1] * fr) * ph[m]
                            t = rr
                            P[1] += t
                            for kk in range(2, order + 1):
                                t = t * rr
                                P[kk] += t
                    v += _combine(S, E, P, M, order, cf, binom)
                for m in range(M):
                    ph[m] *= rot[m]
            for m in range(M):
                d_lo[m] = d_hi[m]
            out[r, g] = v / (D * K)


@njit(parallel=True, cache=True)
def far_das_spectrum(Xr, Xi, d, f_start, df, beams):
    """Plain far-field DAS summed in the frequency domain, exactly (no interpolation).

    Xr, Xi (K, M, Nb) float32: the baseband spectrum in ascending frequency, bin n at
    ``f_start + n df`` (absolute, Hz; Nb a multiple of 16, zero-padded); d (G, M)
    delays, s; beams (K, G, N) complex64 written with
    ``sum_m X[k, m, n] exp(-2j pi (f_start + n df) d[g, m])`` for the N <= Nb bins
    in FFT order (the ``N - (N + 1) // 2`` negative ones first in X, last in beams).

    The steering phases of one (direction, microphone) are built without trigonometry
    in the loop: 16 bins from float64 values, then each bin from the one 16 bins below
    by one float32 complex product (phase drift about 1e-5 rad over a few thousand
    bins); then one multiply-accumulate pass over the bins, which vectorises.
    """
    K, M, Nb = Xr.shape
    G = d.shape[0]
    L = 16
    for g in prange(G):
        Br = np.empty(Nb, np.float32)
        Bi = np.empty(Nb, np.float32)
        pr = np.empty(Nb, np.float32)
        pi = np.empty(Nb, np.float32)
        for k in range(K):
            Br[:] = 0
            Bi[:] = 0
            for m in range(M):
                a = -2 * math.pi * d[g, m]
                w = complex(math.cos(a * f_start), math.sin(a * f_start))
                s1 = complex(math.cos(a * df), math.sin(a * df))
                for n in range(L):
                    pr[n] = w.real
                    pi[n] = w.imag
                    w *= s1
                sr = np.float32(math.cos(a * df * L))
                si = np.float32(math.sin(a * df * L))
                for n in range(L, Nb):
                    pr[n] = pr[n - L] * sr - pi[n - L] * si
                    pi[n] = pr[n - L] * si + pi[n - L] * sr
                xr = Xr[k, m]
                xi = Xi[k, m]
                for n in range(Nb):
                    Br[n] += xr[n] * pr[n] - xi[n] * pi[n]
                    Bi[n] += xr[n] * pi[n] + xi[n] * pr[n]
            N = beams.shape[2]  # back to FFT order: the n_neg negative bins come first
            n_neg = N - (N + 1) // 2
            for n in range(n_neg):
                beams[k, g, N - n_neg + n] = complex(Br[n], Bi[n])
            for n in range(n_neg, N):
                beams[k, g, n - n_neg] = complex(Br[n], Bi[n])
