"""The fit: robust least squares on log energies, with the exact Jacobian.

For pose p, band b, direction d and range bin r the model's energy is

``E = L sum_{t in r} |z0_bd(t) + sum_G w_Gb(theta) z_Gbd(t)|^2 + s_p N_br``

(z: a group's envelope at its traced gains, w its gain factor (:mod:`.parameters`),
z0 the direct path's (fixed: what of it leaks past the gate),
L an overall level (1 unless fitted), s_p the noise variance of recording p and
N_br the noise energy a unit variance leaves in that bin, :class:`.FeatureSpace`).
The residual is ``log E - c - log E_measured``: a bin 3 dB off counts the same at
every range, whether the echo is loud or the tail is faint; c (:meth:`Problem.log_bias`)
is how far a noisy bin's log energy lies under the log of its mean on average (the
log of a chi-square of few degrees of freedom), so that the fit compares like with
like.  Its derivatives:

``dE/dw_Gb = 2 L Re sum_t conj(y_bd(t)) z_Gbd(t)``, ``dw_Gb/dtheta`` from the gains'
derivatives (:func:`group_factor_derivatives`: products, not logs, since a perfectly
specular material's diffuse gain is 0)

and ``dlog E / dlog s_p = s_p N / E``, ``dlog E / dlog L = 1 - s_p N / E``.  Every
evaluation costs one weighted sum of the stored envelopes per pose (and one
correlation per group for the Jacobian): no tracing, no rendering.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.special import digamma

from acousim.calibrate.features import FeatureSpace
from acousim.calibrate.groups import PoseGroups
from acousim.calibrate.parameters import ParameterSet

__all__ = [
    "Problem",
    "Solution",
    "solve",
    "robust_cost",
    "robust_weights",
    "cluster_sigma",
    "group_factors",
    "group_factor_derivatives",
]


def robust_cost(r: np.ndarray, loss: str, scale: float) -> float:
    """The cost :func:`scipy.optimize.least_squares` minimises:
    ``0.5 C^2 sum rho((r / C)^2)``."""
    z = (np.asarray(r) / scale) ** 2
    rho = {
        "linear": lambda: z,
        "soft_l1": lambda: 2 * (np.sqrt(1 + z) - 1),
        "huber": lambda: np.where(z <= 1, z, 2 * np.sqrt(z) - 1),
        "cauchy": lambda: np.log1p(z),
        "arctan": lambda: np.arctan(z),
    }[loss]()
    return float(0.5 * scale**2 * np.sum(rho))


def robust_weights(r: np.ndarray, loss: str, scale: float) -> np.ndarray:
    """``rho'((r / C)^2)`` (N,): each residual's weight in the robust cost's gradient
    (:func:`robust_cost`)."""
    z = (np.asarray(r) / scale) ** 2
    return {
        "linear": lambda: np.ones_like(z),
        "soft_l1": lambda: 1 / np.sqrt(1 + z),
        "huber": lambda: np.where(z <= 1, 1.0, 1 / np.sqrt(np.maximum(z, 1.0))),
        "cauchy": lambda: 1 / (1 + z),
        "arctan": lambda: 1 / (1 + z**2),
    }[loss]()


def cluster_sigma(
    r: np.ndarray, J: np.ndarray, clusters: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """One-sigma uncertainties (P,) of a robust least-squares fit from its residuals
    r (N,), their Jacobian J (N, P), the cluster of each (N,) ints and the robust
    weights (N,): the sandwich ``H^-1 M H^-1`` with ``H = sum w J J^T`` and M the
    spread of the clusters' gradients ``sum_(i in g) w_i r_i J_i`` (G clusters,
    scaled by ``G / (G - P)``).  Residuals within a cluster may be correlated in any
    way (overlapping beams, one draw of a diffuse tail); clusters are taken as
    independent."""
    H = (J * weights[:, None]).T @ J
    ids, g = np.unique(clusters, return_inverse=True)
    scores = np.zeros((ids.size, J.shape[1]))
    np.add.at(scores, g, (weights * r)[:, None] * J)
    M = scores.T @ scores * ids.size / max(ids.size - J.shape[1], 1)
    try:
        Hi = np.linalg.pinv(H)
    except np.linalg.LinAlgError:  # pragma: no cover
        return np.full(J.shape[1], np.nan)
    return np.sqrt(np.maximum(np.diag(Hi @ M @ Hi), 0.0))


def group_factors(counts: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``w_Gb = prod_c q_bc^n_Gc``: (G, B) from counts n (G, C) and gain ratios q
    (B, C) (a ratio of 0 raised to a count of 0 is 1: a perfectly specular material
    silences only the groups that met it diffusely)."""
    return np.prod(q[None] ** counts[:, None, :], axis=-1)


def group_factor_derivatives(counts: np.ndarray, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """``dw_Gb / dtheta_p`` (G, B, P) from counts (G, C), ratios q (B, C) and their
    derivatives dq (B, C, P): ``sum_c n_c q_c^(n_c - 1) dq_c prod_(c' != c) q_c'^n_c'``
    (finite where a ratio is 0)."""
    n = counts[:, None, :]  # (G, 1, C)
    powers = q[None] ** n  # (G, B, C)
    out = np.zeros((counts.shape[0], q.shape[0], dq.shape[-1]))
    for c in range(q.shape[1]):
        nc = n[..., c]
        lead = np.where(nc > 0, nc * q[None, :, c] ** np.maximum(nc - 1, 0), 0.0)
        rest = np.prod(np.delete(powers, c, axis=-1), axis=-1)
        out += (lead * rest)[..., None] * dq[None, :, c, :]
    return out


#: how far (natural log of energy: 100 dB) a fitted noise variance may go under
#: the quietest bin's
NOISE_BELOW_QUIETEST = np.log(1e10)


@dataclass(frozen=True, eq=False)
class Problem:
    """Everything a fit evaluates: the parameters, the feature space, and per pose
    its groups and measured energies (B, D, R)."""

    parameters: ParameterSet
    space: FeatureSpace
    groups: tuple[PoseGroups, ...]
    measured: tuple[np.ndarray, ...]
    log_reference: np.ndarray
    fit_level: bool = False

    @property
    def n_materials(self) -> int:
        return len(self.parameters.layout())

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(material parameters, log noise variances (poses,), log level)."""
        P, K = self.n_materials, len(self.groups)
        return x[:P], x[P : P + K], (x[P + K] if self.fit_level else 0.0)

    def start(self) -> np.ndarray:
        theta = self.parameters.start()
        # noise: the quietest tenth of the bins, as if they held noise alone
        noise = [
            np.log(np.quantile(m / self.space.noise_unit[:, None, :], 0.1) + 1e-300)
            for m in self.measured
        ]
        return np.concatenate([theta, noise, [0.0] if self.fit_level else []])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of x: the materials' (:meth:`.ParameterSet.bounds`); each log noise
        variance between :data:`NOISE_BELOW_QUIETEST` under the quietest bin's (there
        noise changes no bin: a noise-free recording) and the loudest bin's (the
        exponential stays finite however the solver steps); the level free."""
        lo, hi = self.parameters.bounds()
        ratios = [m / self.space.noise_unit[:, None, :] for m in self.measured]
        n_lo = [np.log(r.min()) - NOISE_BELOW_QUIETEST for r in ratios]
        n_hi = [np.log(r.max()) for r in ratios]
        level = [-np.inf] if self.fit_level else []
        return (
            np.concatenate([lo, n_lo, level]),
            np.concatenate([hi, n_hi, np.negative(level)]),
        )

    def model(self, x: np.ndarray, jacobian: bool = False):
        """Model energies per pose (B, D, R) and, with `jacobian`, d log E / dx per
        pose (B, D, R, len(x))."""
        theta, log_noise, log_level = self.unpack(x)
        gains, grad = self.parameters.gains(theta)  # (B, C), (B, C, P)
        ref = np.exp(self.log_reference)
        q, dq = gains / ref, grad / ref[:, None]
        level = np.exp(log_level)
        energies, jacs = [], []
        unit = self.space.noise_unit
        for p, g in enumerate(self.groups):
            w = group_factors(g.counts, q)  # (G, B)
            y = np.einsum("gb,gbdt->bdt", w.astype(np.complex64), g.envelopes)
            y += g.direct_envelopes
            echo = self.space.energies(y)
            noise = np.exp(log_noise[p]) * unit[:, None, :]
            E = level * echo + noise
            energies.append(E)
            if not jacobian:
                continue
            J = np.zeros((*E.shape, x.size))
            # dE/dw (G, B, D, R), then through w to the material parameters
            dEdw = 2 * self.space.bin_sums(np.real(np.conj(y)[None] * g.envelopes))
            dw = group_factor_derivatives(g.counts, q, dq)  # (G, B, P)
            J[..., : theta.size] = level * np.einsum("gbdr,gbp->bdrp", dEdw, dw) / E[..., None]
            J[..., theta.size + p] = noise / E
            if self.fit_level:
                J[..., -1] = level * echo / E
            jacs.append(J)
        return (energies, jacs) if jacobian else energies

    def coherent(self, x: np.ndarray) -> list[np.ndarray]:
        """Per pose the echo energy (B, D, R) of the paths that met no fitted material
        diffusely (and the direct path), at x: the model's deterministic part; the
        rest of its echo is a Lambert tail, one draw of a random field (another
        draw, a real wall's, puts other energies in its bins)."""
        theta, _, log_level = self.unpack(x)
        q = self.parameters.gains(theta)[0] / np.exp(self.log_reference)
        out = []
        for g in self.groups:
            w = group_factors(g.counts, q) * (g.counts[:, 1::2].sum(axis=1) == 0)[:, None]
            y = np.einsum("gb,gbdt->bdt", w.astype(np.complex64), g.envelopes)
            out.append(np.exp(log_level) * self.space.energies(y + g.direct_envelopes))
        return out

    def clusters(self) -> np.ndarray:
        """(N,) the cluster of each residual (:meth:`residuals`' order): one per
        recording and range bin (its bands and directions share one stretch of one
        recording: the same echoes, the same noise, overlapping beams)."""
        out, first = [], 0
        for m in self.measured:
            R = m.shape[-1]
            out.append(first + np.broadcast_to(np.arange(R), m.shape).ravel())
            first += R
        return np.concatenate(out)

    def _noise_share(self, x: np.ndarray, energies: list[np.ndarray]):
        """``beta(n) = log n - digamma(n)`` (B, 1, R), n = ``noise_dof``, and per pose
        the noise's share q = N / E of each bin's energy (B, D, R), at most 1."""
        _, log_noise, _ = self.unpack(x)
        n = self.space.noise_dof
        unit = self.space.noise_unit[:, None, :]
        q = [np.minimum(np.exp(v) * unit / E, 1.0) for v, E in zip(log_noise, energies)]
        return (np.log(n) - digamma(n))[:, None, :], q

    def log_bias(self, x: np.ndarray, energies: list[np.ndarray]) -> list[np.ndarray]:
        """Per pose, ``log E - E[log E_measured]`` (B, D, R): how far under the log
        of its mean E the log energy of a noisy bin lies on average (the log of a
        chi-square of 2 n degrees of freedom, n = ``noise_dof``, lies
        ``beta(n) = log n - digamma(n)`` under the log of its mean: 1.2 dB for n =
        2; an echo S in the bin shrinks that, to leading order as ``1 - (S / E)^2``:
        ``beta(n) (2 q - q^2)`` with q = N / E the noise's share)."""
        beta, shares = self._noise_share(x, energies)
        return [beta * q * (2 - q) for q in shares]

    def log_residuals(self, x: np.ndarray, jacobian: bool = False):
        """Per pose ``E[log E_measured] - log E_measured`` (B, D, R) at x (the model's
        mean log energy, :meth:`log_bias`) and, with `jacobian`, its derivatives (B, D,
        R, len(x))."""
        out = self.model(x, jacobian)
        energies, jacs = out if jacobian else (out, None)
        beta, shares = self._noise_share(x, energies)
        res = [
            np.log(E) - beta * q * (2 - q) - np.log(m)
            for E, q, m in zip(energies, shares, self.measured)
        ]
        if not jacobian:
            return res
        P = self.n_materials
        for p, (q, J) in enumerate(zip(shares, jacs)):
            # dc = 2 beta (1 - q) q (dlog N - dlog E); zero where q is clipped at 1
            g = 2 * beta * (1 - q) * q
            J *= (1 + g)[..., None]
            J[..., P + p] -= g
        return res, jacs

    def residuals(self, x: np.ndarray) -> np.ndarray:
        return np.concatenate([r.ravel() for r in self.log_residuals(x)])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        _, jacs = self.log_residuals(x, jacobian=True)
        return np.concatenate([J.reshape(-1, x.size) for J in jacs])


@dataclass(frozen=True, eq=False)
class Solution:
    """x : the fitted vector (diffuse fractions as amplitudes ``sqrt(d)``,
    :meth:`.ParameterSet.public` turns them into fractions); sigma : its one-sigma
    uncertainties of x (:func:`cluster_sigma`: the robust Gauss-Newton Hessian and
    the spread of the cost's gradient over clusters of one recording's range bin,
    whose bands and overlapping beams are correlated);
    start : the start; evaluations; cost_start, cost : the robust costs; status :
    the solver's message; converged : false when it stopped at its evaluation cap;
    jacobian : (N, len(x)) the robust residuals' Jacobian at
    the solution (``least_squares``'s ``jac``: ``J^T J`` is the Hessian's
    Gauss-Newton approximation), what :mod:`.diagnose` reads."""

    x: np.ndarray
    sigma: np.ndarray
    start: np.ndarray
    evaluations: int
    cost_start: float
    cost: float
    status: str
    jacobian: np.ndarray | None = None
    converged: bool = True


def solve(problem: Problem, *, loss: str, loss_scale: float, max_evaluations: int) -> Solution:
    """Fit `problem` (:func:`scipy.optimize.least_squares`, trust-region reflective
    within the parameters' bounds, the analytic Jacobian)."""
    x0 = problem.start()
    lo, hi = problem.bounds()
    x0 = np.clip(x0, lo, hi)
    res = least_squares(
        problem.residuals,
        x0,
        jac=problem.jacobian,
        bounds=(lo, hi),
        loss=loss,
        f_scale=loss_scale,
        max_nfev=max_evaluations,
        x_scale="jac",
        method="trf",
    )
    rho0 = robust_cost(problem.residuals(x0), loss, loss_scale)
    sigma = cluster_sigma(
        res.fun,
        problem.jacobian(res.x),
        problem.clusters(),
        robust_weights(res.fun, loss, loss_scale),
    )
    return Solution(
        res.x,
        sigma,
        x0,
        int(res.nfev),
        float(rho0),
        float(res.cost),
        res.message,
        np.asarray(res.jac),
        bool(res.status != 0),  # 0: max_nfev reached
    )
