"""Boundary-element solves (bempp-cl) of a rigid object lit by a point source.

Conventions: fields ~ exp(+ikr) (bempp's), unit point source G(x, s) = exp(ik|x - s|) /
(4 pi |x - s|); the result is the scattered pressure at the receivers. Continuous
piecewise-linear (P1) elements, dense assembly (numba), GMRES.

Closed object (Neumann problem, Burton-Miller): the total surface pressure u satisfies

1. (1/2 I - K) u = p_inc                  (exterior trace of the Helmholtz formula)
2. W u = dp_inc/dn                        (its normal derivative; W = -d/dn K, bempp's)
3. (1/2 I - K + eta W) u = p_inc + eta dp_inc/dn,  eta = i / k: unique at every k
   (1 alone fails at the interior Dirichlet eigenfrequencies);
4. p_s(x) = int dG(x, y)/dn_y u(y) dS(y)  (double-layer potential).

Zero-thickness rigid screen (open surface, no interior, so no spurious resonances): the
jump phi = u+ - u- of the pressure across it vanishes at the rim (P1 without boundary
dofs), W phi = dp_inc/dn, and p_s = double-layer potential of phi.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Solve:
    """One frequency: scattered pressure at the receivers (complex, (N,)), degrees of
    freedom, GMRES iterations, and seconds for assembly and solution."""

    pressure: np.ndarray
    dofs: int
    iterations: int
    assemble_s: float
    solve_s: float


def _bempp():
    import bempp_cl.api as bempp

    return bempp


@functools.cache
def _incident_callable():
    """The incident-field callable, compiled once (numba) per process: w p_inc + eta
    dp_inc/dn for a unit point source; parameters (k, source x, y, z, eta, w) as a
    complex array (w = 1: the combined field of a closed surface; w = 0, eta = 1:
    dp_inc/dn alone, a screen's)."""
    from bempp_cl.api.assembly.grid_function import callable as bempp_callable

    @bempp_callable(complex=True, jit=True, parameterized=True)
    def incident(x, n, domain_index, result, p):  # noqa: ARG001
        kk = p[0].real
        d0, d1, d2 = x[0] - p[1].real, x[1] - p[2].real, x[2] - p[3].real
        r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        g = np.exp(1j * kk * r) / (4 * np.pi * r)
        dgdr = g * (1j * kk - 1 / r)
        result[0] = p[5] * g + p[4] * dgdr * (d0 * n[0] + d1 * n[1] + d2 * n[2]) / r

    return incident


def _incident(bempp, space, k: float, source: np.ndarray, eta: complex, closed: bool):
    """Projection on the space of p_inc + eta dp_inc/dn (closed) or of dp_inc/dn
    (screen), for a unit point source."""
    eta, weight = (eta, 1.0) if closed else (1.0, 0.0)
    params = np.array([k, source[0], source[1], source[2], eta, weight], complex)
    return bempp.GridFunction(space, fun=_incident_callable(), function_parameters=params)


def _gmres(matrix: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, int]:
    from scipy.sparse.linalg import gmres

    count = [0]

    def cb(_):
        count[0] += 1

    x, info = gmres(
        matrix, rhs, rtol=1e-8, restart=200, maxiter=2000, callback=cb, callback_type="pr_norm"
    )
    if info != 0:  # not converged: solve directly
        x = np.linalg.solve(matrix, rhs)
    return x, count[0]


def rigid(
    vertices: np.ndarray,
    triangles: np.ndarray,
    k: float,
    sources: np.ndarray,
    closed: bool,
    eta: complex | None = None,
) -> Solve:
    """Monostatic echoes of a rigid closed surface (Burton-Miller, coupling eta, default
    i/k; 0 gives the plain equation 1) or screen (closed=False): for each unit point
    source in sources ((S, 3) m) the scattered pressure back at that source ((S,));
    one assembly serves all sources; k in rad/m."""
    bempp = _bempp()
    sources = np.atleast_2d(np.asarray(sources, float))
    t0 = time.perf_counter()
    grid = bempp.Grid(vertices.T.astype(float), triangles.T.astype(np.uint32))
    helm = bempp.operators.boundary.helmholtz
    if closed:
        eta = 1j / k if eta is None else eta
        space = bempp.function_space(grid, "P", 1)
        mat = bempp.as_matrix(helm.hypersingular(space, space, space, k).weak_form())
        mat *= eta
        mat -= bempp.as_matrix(helm.double_layer(space, space, space, k).weak_form())
        ident = bempp.operators.boundary.sparse.identity(space, space, space)
        mat += 0.5 * bempp.as_matrix(ident.weak_form())
    else:
        eta = 0.0
        space = bempp.function_space(grid, "P", 1, include_boundary_dofs=False)
        mat = bempp.as_matrix(helm.hypersingular(space, space, space, k).weak_form())
    t1 = time.perf_counter()
    out, iterations = np.zeros(len(sources), complex), 0
    for i, src in enumerate(sources):
        rhs = _incident(bempp, space, k, src, eta, closed)
        coef, its = _gmres(mat, rhs.projections(space))
        iterations = max(iterations, its)
        u = bempp.GridFunction(space, coefficients=coef)
        pot = bempp.operators.potential.helmholtz.double_layer(space, src[:, None], k)
        out[i] = np.asarray(pot * u).ravel()[0]
    t2 = time.perf_counter()
    return Solve(out, space.global_dof_count, iterations, t1 - t0, t2 - t1)
