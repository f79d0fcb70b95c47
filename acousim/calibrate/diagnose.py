"""What a calibration's fit cannot say: the warnings of its report.

A least-squares fit always returns numbers; whether the recordings determine them is
read from the fit itself, at its solution:

* a value at (or within :data:`BOUND_TOLERANCE` of its range from) one of its bounds:
  the solver stopped against a wall, not at a minimum, and the linearised sigma
  (from the curvature there) says nothing about how far off the value is;
* the Gauss-Newton matrix ``J^T J`` (J: the robust residuals' Jacobian,
  ``scipy.optimize.least_squares``'s ``jac``), its columns normalised to unit
  length (a correlation-like matrix): an eigenvalue under
  :data:`SINGULAR_EIGENVALUE` of its largest is a combination of parameters the
  data do not change (the parameters with a large share of its eigenvector are
  named); a column of zeros, a parameter that changes nothing;
* a correlation of two parameters' estimates (``pinv(J^T J)``) beyond
  :data:`CORRELATION_LIMIT` in magnitude: they trade against each other;
* a sigma larger than the parameter's whole range;
* the solver stopped at its evaluation cap, not at a minimum;
* the level: recordings not simulated (``emulated`` or ``real`` provenance) have an
  unknown level (a sensor's gain, ADC units), which a fit without ``fit_level``
  takes as the simulation's and puts into the reflections; with ``fit_level``, the
  material parameters confounded with the level are named.

Pure functions of arrays; :func:`diagnose` returns typed :class:`FitWarning`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = [
    "FitWarning",
    "WarningKind",
    "diagnose",
    "normalised_gram",
    "correlations",
    "BOUND_TOLERANCE",
    "SINGULAR_EIGENVALUE",
    "CORRELATION_LIMIT",
    "LEVEL",
]

WarningKind = Literal[
    "not_converged",
    "at_bound",
    "no_effect",
    "undetermined",
    "correlated",
    "level_unknown",
    "level_confounded",
]

#: a value this fraction of its range from a bound (or nearer) is "at" the bound
BOUND_TOLERANCE = 0.01
#: an eigenvalue of the normalised J^T J under this fraction of the largest: singular
SINGULAR_EIGENVALUE = 1e-6
#: a correlation of two estimates beyond this (in magnitude): they trade
CORRELATION_LIMIT = 0.95
#: an eigenvector's component of at least this names its parameter
EIGENVECTOR_SHARE = 0.2
#: the name of the fitted overall level among the parameters
LEVEL = "level"


@dataclass(frozen=True)
class FitWarning:
    """One thing the report must not hide: its kind, the parameters it names, and a
    one-line message saying what it means."""

    kind: WarningKind
    parameters: tuple[str, ...]
    message: str


def normalised_gram(jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``J^T J`` of `jacobian` (N, P) with unit-length columns (P, P), and the
    columns' norms (P,) (a zero column keeps its zeros)."""
    J = np.asarray(jacobian, float)
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    return Jn.T @ Jn, norms


def correlations(gram: np.ndarray) -> np.ndarray:
    """The correlation matrix (P, P) of the estimates whose Gauss-Newton matrix is
    `gram` (P, P): ``C = pinv(gram)``, ``C_ij / sqrt(C_ii C_jj)`` (0 where a variance
    is 0)."""
    C = np.linalg.pinv(np.asarray(gram, float))
    s = np.sqrt(np.maximum(np.diag(C), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        R = C / np.outer(s, s)
    return np.where(np.outer(s, s) > 0, R, 0.0)


def _at_bounds(names, value, lo, hi) -> list[FitWarning]:
    out = []
    for n, v, a, b in zip(names, value, lo, hi):
        tol = BOUND_TOLERANCE * (b - a)
        for bound, side in ((a, "lower"), (b, "upper")):
            if abs(v - bound) <= tol:
                out.append(
                    FitWarning(
                        "at_bound",
                        (n,),
                        f"{n} = {v:.4g} is at its {side} bound {bound:g} (within {tol:.2g}): "
                        "the fit stopped against the bound, its sigma is not meaningful",
                    )
                )
    return out


def _wide(names, sigma, lo, hi) -> list[FitWarning]:
    return [
        FitWarning(
            "undetermined",
            (n,),
            f"{n}: sigma {s:.3g} is larger than its whole range {a:g}..{b:g}: "
            "the recordings do not determine it",
        )
        for n, s, a, b in zip(names, sigma, lo, hi)
        if not s <= b - a  # NaN too
    ]


def _singular(names, gram, norms, checked) -> list[FitWarning]:
    out = [
        FitWarning(
            "no_effect", (names[i],), f"{names[i]} does not change the model at the fitted values"
        )
        for i in checked
        if norms[i] == 0
    ]
    w, V = np.linalg.eigh(gram)
    top = max(float(w[-1]), 1e-300)
    for k in np.flatnonzero(w < SINGULAR_EIGENVALUE * top):
        share = np.abs(V[:, k])
        who = tuple(names[i] for i in np.argsort(-share) if share[i] >= EIGENVECTOR_SHARE)
        if not any(names.index(n) in checked for n in who) or len(who) < 2:
            continue
        out.append(
            FitWarning(
                "undetermined",
                who,
                f"{', '.join(who)} are not determined separately: the data do not change "
                f"along one combination of them (eigenvalue {w[k] / top:.1e} of the largest "
                "of the normalised J^T J)",
            )
        )
    return out


def _correlated(names, corr, checked) -> list[FitWarning]:
    out = []
    for i in checked:
        for j in range(len(names)):
            if j == i or (j in checked and j < i) or names[j] == LEVEL:
                continue
            if abs(corr[i, j]) >= CORRELATION_LIMIT:
                out.append(
                    FitWarning(
                        "correlated",
                        (names[i], names[j]),
                        f"{names[i]} and {names[j]} trade against each other (correlation "
                        f"{corr[i, j]:+.3f}): the data fix a combination of them, not each",
                    )
                )
    return out


def _level(names, corr, kinds: Sequence[str], fit_level: bool) -> list[FitWarning]:
    foreign = sorted({k for k in kinds if k in ("emulated", "real")})
    if not fit_level:
        if not foreign:
            return []
        return [
            FitWarning(
                "level_unknown",
                (),
                f"the recordings are {' and '.join(foreign)}, not simulated: a real sensor's "
                "level (its gain) is unknown, and without --fit-level (fit_level) the fit "
                "takes the simulation's and puts the difference into the reflections; "
                "rerun with --fit-level",
            )
        ]
    k = names.index(LEVEL)
    tied = [
        (names[i], corr[k, i])
        for i in range(len(names))
        if i != k and not names[i].startswith("noise") and abs(corr[k, i]) >= CORRELATION_LIMIT
    ]
    if not tied:
        return []
    listed = ", ".join(f"{n} (correlation {c:+.3f})" for n, c in tied)
    return [
        FitWarning(
            "level_confounded",
            (LEVEL, *(n for n, _ in tied)),
            f"the fitted level is confounded with {listed}: a level times a reflection "
            "gives the same echoes, so the data fix their product, not each value (nor "
            "its sigma); hold the reflection at a known value (fit the rest with --param) "
            "or add recordings that separate them (several materials, paths of two bounces)",
        )
    ]


def diagnose(
    *,
    names: Sequence[str],
    value: np.ndarray,
    sigma: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray],
    jacobian: np.ndarray,
    all_names: Sequence[str],
    kinds: Sequence[str] = (),
    evaluations_cap: int | None = None,
) -> tuple[FitWarning, ...]:
    """The warnings of a fit.

    names, value, sigma, bounds (lower, upper) : the P material parameters as the
    report gives them (public units: diffuse fractions, not amplitudes) and their
    bounds; jacobian : (N, Q) the robust residuals' Jacobian at the solution over
    every fitted number, whose first P columns are the materials'; all_names : (Q,)
    the names of its columns (``noise[k]`` for recording k's noise, :data:`LEVEL`
    when the level was fitted); kinds : each recording's provenance kind;
    evaluations_cap : the cap the
    solver stopped at before converging (None: it converged)."""
    names, all_names = list(names), list(all_names)
    lower, upper = bounds
    fit_level = LEVEL in all_names
    gram, norms = normalised_gram(jacobian)
    corr = correlations(gram)
    checked = list(range(len(names)))
    out = []
    if evaluations_cap is not None:
        out.append(
            FitWarning(
                "not_converged",
                tuple(names),
                f"the solver stopped at its cap of {evaluations_cap} evaluations "
                "(--max-evaluations, max_evaluations) before converging: the values may not "
                "be the best fit",
            )
        )
    out += _at_bounds(names, value, lower, upper)
    out += _wide(names, sigma, lower, upper)
    out += _singular(all_names, gram, norms, checked)
    out += _correlated(all_names, corr, checked)
    out += _level(all_names, corr, kinds, fit_level)
    return _without_repeats(out)


def _without_repeats(warnings: list[FitWarning]) -> tuple[FitWarning, ...]:
    """Drop an undetermined pair that a correlation warning already names."""
    pairs = [set(w.parameters) for w in warnings if w.kind in ("correlated", "level_confounded")]
    return tuple(
        w
        for w in warnings
        if not (
            w.kind == "undetermined"
            and len(w.parameters) == 2
            and any(set(w.parameters) <= p for p in pairs)
        )
    )
