"""``calibrate(scene, recordings)``: fit a scene's materials to recordings of it.

1. The recordings are checked against the scene's sensor (sample rate, array).
2. The scene is traced once per recording's pose with the fitted materials counted,
   each group of paths rendered once and reduced to band envelopes (:mod:`.groups`,
   :mod:`.features`).
3. Each recording is shifted onto the simulation (its direct path's lag,
   :func:`acousim.compare.alignment.align`; reported) and reduced to energies per band,
   direction and range bin.
4. Robust least squares (:mod:`.fit`) from the scene's values.
5. The result: the fitted materials with their uncertainties (clustered per
   recording and range bin, :func:`.fit.cluster_sigma`), the residual per range bin
   before and after, and the bins the fitted scene still cannot explain: 6 dB above
   it and beyond what its noise and another draw of its diffuse tail reach (echoes
   the scene lacks: reported, their weight kept small by the robust loss).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import ncx2, norm

import processing as P
from acousim.calibrate.diagnose import LEVEL, FitWarning, diagnose
from acousim.calibrate.features import FeatureSpace
from acousim.calibrate.fit import Problem, Solution, group_factors, solve
from acousim.calibrate.groups import GroupModel
from acousim.calibrate.options import CalibrationSettings
from acousim.calibrate.parameters import MaterialFit, ParameterSet
from acousim.compare.alignment import align as align_lag
from acousim.compare.alignment import fractional_shift, mean_samples
from acousim.scene.model import Material, Scene
from processing.base.errors import InputError

__all__ = [
    "calibrate",
    "Calibration",
    "FittedParameter",
    "FitWarning",
    "Unexplained",
    "DB_PER_NEPER",
]

DB_PER_NEPER = 10 / np.log(10)  # a natural log of energy in dB
UNEXPLAINED_DB = 6.0  # a bin this far above the fitted model, and beyond chance:
UNEXPLAINED_FALSE_RATE = 0.01  # the chance that the noise alone lists a bin
NONCENTRAL_LIMIT = 1e4  # above, a bin's non-central chi-square taken as normal
MAX_UNEXPLAINED = 20


@dataclass(frozen=True)
class FittedParameter:
    """One fitted number: ``name`` (``material.reflection[@f kHz]``), start, value,
    sigma (one standard deviation)."""

    name: str
    start: float
    value: float
    sigma: float


@dataclass(frozen=True)
class Unexplained:
    """A bin the fitted scene leaves well below the recording, beyond what its noise
    and its diffuse tail's randomness explain: an echo the scene lacks (or a model
    error).  pose (the recording's index), range_m, azimuth_deg,
    elevation_deg, excess_db (recording over model)."""

    recording: int
    range_m: float
    azimuth_deg: float
    elevation_deg: float
    excess_db: float


@dataclass(frozen=True, eq=False)
class Calibration:
    """What :func:`calibrate` found.

    parameters : every fitted number; materials : {name: fitted Material};
    material_sigma : {name: (sigma of reflection, sigma of diffuse)} (arrays for
    tables); range_m (R,) and residual_db_before, residual_db_after (R,): the rms of
    the log-energy residual per range bin over recordings, bands and directions;
    rms_db_before, rms_db_after: over every bin; lag_samples (per recording):
    the shift applied to the simulation to align it; noise_db (per recording): the
    fitted noise variance (dB re 1); level_db: the fitted overall level (0 unless
    fitted); unexplained: bins the fit leaves under the recording; solution: the
    solver's numbers; seconds: the whole call's time; warnings: what the fitted
    numbers cannot be trusted for (:mod:`.diagnose`: values at a bound, parameters
    the recordings do not determine, an unknown or confounded level).
    """

    parameters: tuple[FittedParameter, ...]
    materials: dict[str, Material]
    material_sigma: dict[str, tuple]
    range_m: np.ndarray
    residual_db_before: np.ndarray
    residual_db_after: np.ndarray
    rms_db_before: float
    rms_db_after: float
    lag_samples: tuple[float, ...]
    noise_db: tuple[float, ...]
    level_db: float
    unexplained: tuple[Unexplained, ...]
    solution: Solution
    seconds: float
    seconds_fit: float = 0.0
    warnings: tuple[FitWarning, ...] = ()

    def to_dict(self) -> dict:
        """Every number of the report (JSON-ready)."""
        return {
            "parameters": [dataclasses.asdict(p) for p in self.parameters],
            "rms_db_before": self.rms_db_before,
            "rms_db_after": self.rms_db_after,
            "range_m": self.range_m.tolist(),
            "residual_db_before": self.residual_db_before.tolist(),
            "residual_db_after": self.residual_db_after.tolist(),
            "lag_samples": list(self.lag_samples),
            "noise_db": list(self.noise_db),
            "level_db": self.level_db,
            "unexplained": [dataclasses.asdict(u) for u in self.unexplained],
            "warnings": [dataclasses.asdict(w) for w in self.warnings],
            "evaluations": self.solution.evaluations,
            "status": self.solution.status,
            "seconds": self.seconds,
            "seconds_fit": self.seconds_fit,
        }

    def to_json(self) -> str:
        import json

        return json.dumps(self.to_dict(), indent=2) + "\n"

    def summary(self) -> str:
        """A human-readable report."""
        lines = [
            f"residual (rms log energy): {self.rms_db_before:.2f} dB -> {self.rms_db_after:.2f} "
            f"dB in {self.solution.evaluations} evaluations, {self.seconds:.1f} s "
            f"({self.seconds_fit:.2f} s of them fitting)",
            "parameter                           start    fitted   +- sigma",
        ]
        lines += [
            f"{p.name:<34} {p.start:7.3f}  {p.value:7.3f}  {p.sigma:7.3f}" for p in self.parameters
        ]
        lines.append("range_m  residual before -> after (dB)")
        lines += [
            f"{r:6.2f}   {a:6.2f} -> {b:6.2f}"
            for r, a, b in zip(self.range_m, self.residual_db_before, self.residual_db_after)
        ]
        if self.unexplained:
            lines.append("unexplained (recording above the fitted scene):")
            lines += [
                f"  recording {u.recording} at {u.range_m:.2f} m, az {u.azimuth_deg:+.0f} deg, "
                f"el {u.elevation_deg:+.0f} deg: +{u.excess_db:.1f} dB"
                for u in self.unexplained
            ]
        lines += [f"warning: {w.message}" for w in self.warnings]
        return "\n".join(lines)


def _check(scene: Scene, recs: Sequence[P.Recording], poses: Sequence[int]) -> None:
    if not recs:
        raise InputError("no recording to calibrate against", key="recordings")
    if len(poses) != len(recs):
        raise InputError(
            f"{len(recs)} recording(s) but {len(poses)} pose(s)", key="poses", value=list(poses)
        )
    s = scene.sensor
    for i, r in enumerate(recs):
        if r.sample_rate_hz != s.sample_rate_hz or r.array.n_mics != s.array.n_mics:
            raise InputError(
                f"recording {i} ({r.array.n_mics} mics at {r.sample_rate_hz:g} Hz) does not "
                f"match the scene's sensor ({s.array.n_mics} at {s.sample_rate_hz:g} Hz)",
                file=scene.source,
            )
        if r.n_samples != recs[0].n_samples or r.emission_index != recs[0].emission_index:
            raise InputError(
                "recordings of different lengths or emission indices", key="recordings"
            )


def _poses(scene: Scene, recs, poses) -> tuple[list[int], list[str]]:
    """Each recording's pose (as :func:`calibrate` says) and where it came from."""
    if poses is not None:
        return list(poses), ["given in poses (--poses)"] * len(poses)
    indices = [r.provenance.pose_index for r in recs]
    one = len(scene.sensor.poses) == 1
    out = [(0 if one else i) if q is None else q for i, q in enumerate(indices)]
    return out, [
        "its place in the file" if q is None else "its pose_index (in the file)" for q in indices
    ]


def _check_poses(scene: Scene, poses: list[int], origins: list[str]) -> None:
    """InputError naming the first recording whose pose the scene lacks, and where
    that pose index came from."""
    n = len(scene.sensor.poses)
    for k, (q, origin) in enumerate(zip(poses, origins)):
        if not 0 <= q < n:
            raise InputError(
                f"recording {k} is at pose {q}, {origin}, but the scene has {n} pose(s) "
                f"(0..{n - 1}): give each recording's scene pose with --poses (poses)",
                file=scene.source,
                key="poses",
                value=q,
            )


def _used_materials(scene: Scene) -> list[str]:
    names = []
    for item in scene.meshes:
        for m in (item.material, *item.materials.values()):
            if m.name not in names:
                names.append(m.name)
    return names


def _measured(rec, sim_direct, groups_signal, space, align: bool) -> tuple[np.ndarray, float]:
    """A recording's energies (B, D, R) after aligning it on the start model."""

    x = mean_samples(rec)
    lag = 0.0
    if align:
        sim = rec.with_samples(groups_signal + sim_direct)
        lag = align_lag(rec, sim)[0]
        x = fractional_shift(x, -lag)
    return space.energies(space.envelopes(x)), lag


def _observe(model: GroupModel, params, space, recs, poses, align: bool, progress=None):
    """Per recording: its pose's path groups, its measured energies (aligned on the
    start model) and the lag applied; `progress(done, total)` after each."""
    groups, measured, lags = [], [], []
    q0 = params.gains(params.start())[0] / np.exp(model.log_reference)  # (B, C)
    for k, (rec, pose) in enumerate(zip(recs, poses)):
        g = model.pose(pose, rec, space, keep_signals=align)
        start = 0.0
        if align:  # the start model at the bands' (geometric) mean gain
            with np.errstate(divide="ignore"):
                w0 = np.exp(np.log(group_factors(g.counts, q0)).mean(axis=1))
            start = np.einsum("g,gmt->mt", w0, g.signals)
            g = dataclasses.replace(g, signals=None)
        E, lag = _measured(rec, g.direct, start, space, align)
        groups.append(g)
        measured.append(np.maximum(E, 1e-300))
        lags.append(lag)
        if progress:
            progress(k + 1, len(recs))
    return groups, measured, lags


def calibrate(
    scene: Scene,
    recordings: Sequence[P.Recording],
    poses: Sequence[int] | None = None,
    settings: CalibrationSettings | None = None,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> Calibration:
    """Fit the materials of `scene` to `recordings` (recording i taken at pose
    ``poses[i]``; default: its ``provenance.pose_index``, else i, or 0 for every
    recording of a scene of one pose: repeated measurements of it).  Raises
    InputError naming what does not fit together. `progress(done, total)` is called
    after each recording's pose is traced and rendered (the long part; the fit
    follows)."""
    t0 = time.perf_counter()
    settings = settings or CalibrationSettings()
    recs = list(recordings)
    poses, origins = _poses(scene, recs, poses)
    _check(scene, recs, poses)
    _check_poses(scene, poses, origins)
    fits = _material_fits(scene, settings)
    space = _feature_space(scene, recs[0], fits, settings)
    params = ParameterSet(fits, space.band_hz)
    model = GroupModel(scene, fits)
    groups, measured, lags = _observe(model, params, space, recs, poses, settings.align, progress)
    problem = Problem(
        params, space, tuple(groups), tuple(measured), model.log_reference, settings.fit_level
    )
    t1 = time.perf_counter()
    sol = solve(
        problem,
        loss=settings.loss,
        loss_scale=settings.loss_scale,
        max_evaluations=settings.max_evaluations,
    )
    t2 = time.perf_counter()
    out = _result(problem, sol, scene, lags, t2 - t0)
    kinds = [r.provenance.kind for r in recs]
    cap = None if sol.converged else settings.max_evaluations
    warnings = _warnings(problem, sol, kinds, cap)
    return dataclasses.replace(out, seconds_fit=t2 - t1, warnings=warnings)


def _material_fits(scene: Scene, settings: CalibrationSettings) -> tuple[MaterialFit, ...]:
    """The materials `settings` frees (of those the scene's meshes use), each at the
    scene's values.  InputError for a scene of point reflectors alone (nothing to fit)
    or a table (``settings.tables``) of a material not fitted."""
    used = _used_materials(scene)
    if not used:  # point reflectors alone: strengths, no material
        raise InputError(
            "has no material to fit: no mesh (a point reflector has a strength, not a material)",
            file=scene.source,
            key="scene",
            value=scene.name,
        )
    free = settings.free(used)
    for name in settings.tables:
        if name not in free:
            raise InputError(
                f"is not a fitted material ({', '.join(free)})", key="tables", value=name
            )
    return tuple(
        MaterialFit.start(
            scene.materials[name],
            settings.tables.get(name),
            fit_reflection=a,
            fit_diffuse=b,
        )
        for name, (a, b) in free.items()
    )


def _feature_space(
    scene: Scene, rec: P.Recording, fits: Sequence[MaterialFit], settings: CalibrationSettings
) -> FeatureSpace:
    """The feature space of recordings sampled as `rec`: ``settings.bands`` bands (by
    default one for materials of one value, else two per table point, at most 16) and
    its range bins up to the scene's reach."""
    points = max(f.n_points for f in fits)
    bands = settings.bands or (1 if points == 1 else min(2 * points, 16))
    return FeatureSpace(
        rec,
        bands=bands,
        directions=settings.directions,
        min_range_m=settings.min_range_m,
        max_range_m=settings.max_range_m or scene.simulation.max_range_m - settings.bin_m,
        bin_m=settings.bin_m,
    )


def _warnings(
    problem: Problem, sol: Solution, kinds: Sequence[str], cap: int | None
) -> tuple[FitWarning, ...]:
    """:func:`.diagnose.diagnose` of a solution (the materials in public units)."""
    params, P_ = problem.parameters, problem.n_materials
    value, sigma = params.public(sol.x[:P_], sol.sigma[:P_])
    lo, hi = (params.public(b, np.zeros(P_))[0] for b in params.bounds())
    extra = [f"noise[{k}]" for k in range(len(problem.groups))]
    return diagnose(
        names=params.names,
        value=value,
        sigma=sigma,
        bounds=(lo, hi),
        jacobian=sol.jacobian,
        all_names=[*params.names, *extra, *([LEVEL] if problem.fit_level else [])],
        kinds=kinds,
        evaluations_cap=cap,
    )


def _per_bin(problem: Problem, x: np.ndarray) -> np.ndarray:
    """(recordings, B, D, R) residuals in dB at x."""
    return DB_PER_NEPER * np.stack(problem.log_residuals(x))


def _result(problem: Problem, sol: Solution, scene: Scene, lags, seconds: float) -> Calibration:
    params = problem.parameters
    P_ = problem.n_materials
    names = params.names
    start, _ = params.public(sol.start[:P_], np.zeros(P_))
    value, sigma = params.public(sol.x[:P_], sol.sigma[:P_])
    fitted = tuple(
        FittedParameter(n, float(a), float(b), float(s))
        for n, a, b, s in zip(names, start, value, sigma)
    )
    materials, sigmas = _fitted_materials(params, sol.x[:P_], sigma, scene)
    before, after = _per_bin(problem, sol.start), _per_bin(problem, sol.x)
    _, log_noise, log_level = problem.unpack(sol.x)
    return Calibration(
        fitted,
        materials,
        sigmas,
        problem.space.range_m,
        np.sqrt(np.mean(before**2, axis=(0, 1, 2))),
        np.sqrt(np.mean(after**2, axis=(0, 1, 2))),
        float(np.sqrt(np.mean(before**2))),
        float(np.sqrt(np.mean(after**2))),
        tuple(float(v) for v in lags),
        tuple(float(DB_PER_NEPER * v) for v in log_noise),
        float(DB_PER_NEPER * log_level),
        _unexplained(problem, sol.x, -after),
        sol,
        seconds,
    )


def _fitted_materials(
    params: ParameterSet, theta: np.ndarray, sigma: np.ndarray, scene: Scene
) -> tuple[dict[str, Material], dict[str, tuple]]:
    """The fitted materials at `theta` (the fitted vector's material part) with their
    one-sigma uncertainties `sigma` (public units, :meth:`.ParameterSet.public`):
    {name: Material} (each keeps the scene's lobe) and {name: (sigma of reflection,
    sigma of diffuse)}, numbers for a material of one value, arrays for a table."""
    materials, sigmas = {}, {}
    values = params.values(theta)
    sig = [[np.zeros(m.n_points), np.zeros(m.n_points)] for m in params.materials]
    for s, (j, k, i) in zip(sigma, params.layout()):
        sig[j][0 if k == "reflection" else 1][i] = s
    for m, (R, d), (sR, sd) in zip(params.materials, values, sig):
        base = scene.materials[m.name]
        if m.is_table:
            materials[m.name] = Material(
                m.name,
                tuple(float(v) for v in R),
                tuple(float(v) for v in d),
                base.lobe_deg,
                tuple(f / 1e3 for f in m.frequencies_hz),
            )
            sigmas[m.name] = (sR, sd)
        else:
            materials[m.name] = Material(m.name, float(R[0]), float(d[0]), base.lobe_deg)
            sigmas[m.name] = (float(sR[0]), float(sd[0]))
    return materials, sigmas


def _unexplained(problem: Problem, x: np.ndarray, excess_db: np.ndarray) -> tuple:
    """Bins at least UNEXPLAINED_DB above the fitted model that neither its noise
    nor another draw of its diffuse tail reach (:func:`_beyond_chance`): per
    recording and range bin the direction of the largest excess."""
    angles = problem.space.directions.angles_deg()
    model, coherent = problem.model(x), problem.coherent(x)
    n_bins = sum(m.size for m in problem.measured)
    out = []
    for k, (m, E, S, ex) in enumerate(zip(problem.measured, model, coherent, excess_db)):
        loud = (ex > UNEXPLAINED_DB) & _beyond_chance(problem.space.noise_dof, m, E, S, n_bins)
        score = np.where(loud, ex, -np.inf).max(axis=0)  # over bands: (D, R)
        for r in np.flatnonzero(np.isfinite(score.max(axis=0))):
            d = int(np.argmax(score[:, r]))
            out.append(
                Unexplained(
                    k, float(problem.space.range_m[r]), *map(float, angles[d]), float(score[d, r])
                )
            )
    out.sort(key=lambda u: -u.excess_db)
    return tuple(out[:MAX_UNEXPLAINED])


def _beyond_chance(
    dof: np.ndarray, measured: np.ndarray, model: np.ndarray, coherent: np.ndarray, n_bins: int
) -> np.ndarray:
    """(B, D, R) mask of the bins whose measured energy the fitted model reaches
    less than once in ``1 / UNEXPLAINED_FALSE_RATE`` calibrations of `n_bins` bins.
    Of the model's energy E per bin, S (`coherent`: its specular echoes) is fixed;
    the rest, the noise and the diffuse tail, is random with the noise's n = `dof`
    (B, R) independent complex samples per bin (a tail's wavelets pass the same
    band filter): ``2 n E_measured / (E - S)`` is a non-central chi-square of 2 n
    degrees of freedom and non-centrality ``2 n S / (E - S)``."""
    n = np.broadcast_to(dof[:, None, :], model.shape)
    rest = np.maximum(model - np.minimum(coherent, model), 1e-300)
    x, df = 2 * n * measured / rest, 2 * n
    nc = 2 * n * np.minimum(coherent, model) / rest
    # far above the random part (its series no longer converges) the normal limit
    exact = nc < NONCENTRAL_LIMIT
    p = np.empty(model.shape)
    p[exact] = ncx2.sf(x[exact], df[exact], nc[exact])
    far = ~exact
    p[far] = norm.sf((x[far] - df[far] - nc[far]) / np.sqrt(2 * (df[far] + 2 * nc[far])))
    return p < UNEXPLAINED_FALSE_RATE / n_bins
