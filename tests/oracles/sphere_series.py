"""Exact monostatic echo of a rigid sphere for a point source (the validation case).

A point source at distance r0 from the centre of a rigid sphere of radius a; the
scattered pressure at the source itself. With fields ~ exp(+ikr) (time factor
exp(-i w t)) and the free-space Green's function G = exp(ikR) / (4 pi R):

    G(x, s) = (ik / 4 pi) sum_n (2n + 1) j_n(k r<) h_n(k r>) P_n(cos gamma)
    p_s(s)  = (ik / 4 pi) sum_n (2n + 1) h_n(k r0)^2 (-j_n'(ka) / h_n'(ka))

(h_n = h_n^(1); P_n(1) = 1; the Neumann condition d(p_inc + p_s)/dr = 0 at r = a fixes
each coefficient).
"""

from __future__ import annotations

import numpy as np
from scipy.special import spherical_jn, spherical_yn


def rigid_sphere_monostatic(k: np.ndarray, radius_m: float, distance_m: float) -> np.ndarray:
    """Scattered pressure (complex, shape of k) back at a unit point source
    (G = exp(ikR) / 4 pi R) at distance_m (m) from the centre of a rigid sphere of
    radius_m (m); k in rad/m."""
    k = np.atleast_1d(np.asarray(k, float))
    out = np.zeros(k.shape, complex)
    for i, kk in enumerate(k):
        n = np.arange(int(kk * radius_m + 30 + 2 * np.cbrt(kk * radius_m)))
        ka, kr = kk * radius_m, kk * distance_m
        jp = spherical_jn(n, ka, derivative=True)
        hp = jp + 1j * spherical_yn(n, ka, derivative=True)
        h = spherical_jn(n, kr) + 1j * spherical_yn(n, kr)
        out[i] = 1j * kk / (4 * np.pi) * np.sum((2 * n + 1) * h**2 * (-jp / hp))
    return out
