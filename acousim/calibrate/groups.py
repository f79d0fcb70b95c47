"""Trace once, render each group of paths once.

The fitted materials are given to the tracer as tables of one point at a tracing
reference (their start values, the diffuse fraction raised to at least
:data:`TRACE_MIN_DIFFUSE` so that every surface returns a Lambert tail whose level
the fit can move), so that every path counts its interactions with each of them
(:attr:`acousim.trace.paths.TracedPaths.interactions`).  Paths with the same counts
(a *signature*) share one gain factor (:mod:`.parameters`); each group is rendered
once as the simulator renders a recording (its render options, fractional delays,
air absorption, emitter and microphone directivity, the tables of materials that
are not fitted) and reduced to its band envelopes (:class:`~.features.FeatureSpace`).
A pose is measured as a recording of it is: along the scene's trajectory if it has
one (the sensor moving during the window, each echo's Doppler factors), since the
millimetres it moves redraw the speckle of every diffuse bin.  The direct path is a group
of its own: used to align the recording in time, never fitted.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

import processing as P
from acousim.calibrate.features import FeatureSpace
from acousim.calibrate.parameters import MaterialFit
from acousim.core.echoes import Echoes
from acousim.scene.model import Material, Scene
from acousim.simulator import SCENE_MOTION, Simulator
from acousim.synth.options import Capture
from acousim.synth.signal_model import in_window, simulate
from processing.base.errors import InputError

__all__ = ["PoseGroups", "GroupModel", "TRACE_MIN_DIFFUSE", "with_materials"]

#: the diffuse fraction the tracer sees at least for a fitted material
TRACE_MIN_DIFFUSE = 0.1


def with_materials(scene: Scene, replace: dict[str, Material]) -> Scene:
    """`scene` with the materials named in `replace` replaced (in the scene's table
    and in every mesh that uses them)."""

    def swap(m: Material) -> Material:
        return replace.get(m.name, m)

    meshes = tuple(
        dataclasses.replace(
            item,
            material=swap(item.material),
            materials={g: swap(m) for g, m in item.materials.items()},
        )
        for item in scene.meshes
    )
    materials = {k: swap(m) for k, m in scene.materials.items()}
    return dataclasses.replace(scene, meshes=meshes, materials=materials)


def _tracing_material(m: Material, fit: MaterialFit) -> Material:
    R = max(fit.reflection)
    d = max(float(np.mean(fit.diffuse)), TRACE_MIN_DIFFUSE)
    f = float(np.mean(fit.frequencies_hz)) / 1e3 or 40.0
    return dataclasses.replace(m, frequencies_khz=(f,), reflection=(R,), diffuse=(d,))


@dataclass(frozen=True, eq=False)
class PoseGroups:
    """The path groups of one pose.

    envelopes : (G, B, D, T') complex64 band envelopes of each group at its traced
    (reference) gains; counts : (G, 2 J) interactions with the fitted materials;
    direct : (M, T) the direct path's signal (zeros without one), direct_envelopes
    (B, D, T') its envelopes (a fixed part of the model: what leaks past the gate);
    signals : (G, M, T)
    the groups' signals (kept only when asked, for pictures and checks).
    """

    envelopes: np.ndarray
    counts: np.ndarray
    direct: np.ndarray
    direct_envelopes: np.ndarray
    signals: np.ndarray | None = None

    @property
    def n_groups(self) -> int:
        return self.counts.shape[0]


class GroupModel:
    """The scene traced with the fitted materials counted, for rendering path groups.

    `fits` are the materials to fit (:class:`~.parameters.MaterialFit`).  Raises
    InputError naming a material that no mesh of the scene uses.
    """

    def __init__(self, scene: Scene, fits: tuple[MaterialFit, ...]) -> None:
        missing = [f.name for f in fits if f.name not in scene.materials]
        if missing:
            raise InputError("no such material in the scene", key="materials", value=missing[0])
        tracing = {f.name: _tracing_material(scene.materials[f.name], f) for f in fits}
        self.scene = with_materials(scene, tracing)
        self.simulator = Simulator(self.scene)
        world = self.simulator.tracer.world
        spectra = world.spectra if world is not None else None
        names = () if spectra is None else spectra.names
        unused = [f.name for f in fits if f.name not in names]
        if unused:
            raise InputError(
                "no mesh of the scene uses this material", key="materials", value=unused[0]
            )
        cols = []
        ref = []
        for f in fits:
            j = names.index(f.name)
            cols += [2 * j, 2 * j + 1]
            R0, d0 = spectra.ref[j]
            ref += [np.log(R0) + 0.5 * np.log1p(-d0), np.log(R0) + 0.5 * np.log(d0)]
        self.columns = np.array(cols, int)
        #: log of the reference gain of each fitted interaction column (2 J,)
        self.log_reference = np.array(ref)

    def pose(
        self,
        pose_index: int,
        recording: P.Recording,
        space: FeatureSpace,
        *,
        keep_signals: bool = False,
    ) -> PoseGroups:
        """Trace pose `pose_index` (in motion along the scene's trajectory, as a
        recording of it is simulated), render its groups at the recording's length and
        emission sample and reduce them to band envelopes."""
        sim, scene = self.simulator, self.scene
        poses = scene.sensor.poses
        if not 0 <= pose_index < len(poses):
            raise InputError(f"the scene has {len(poses)} pose(s)", key="poses", value=pose_index)
        n = recording.n_samples
        # the pose measured as a recording of it is: along the scene's trajectory
        # (Doppler, the sensor moving during the window), not frozen
        prep = sim._prepare(poses[pose_index], pose_index, n, SCENE_MOTION)
        echoes, rate = prep.echoes, prep.rate
        inside = in_window(echoes, n, recording.sample_rate_hz, recording.emission_index)
        echoes = echoes.select(inside)
        rate = None if rate is None else rate[:, inside]
        counts = echoes.interactions
        if counts is None:
            counts = np.zeros((echoes.n_paths, 0), int)
        sig = counts[:, self.columns] if counts.shape[1] else np.zeros((echoes.n_paths, 0))
        direct = echoes.order == 0
        keys, inv = np.unique(sig[~direct], axis=0, return_inverse=True)
        idx = np.flatnonzero(~direct)
        signals = np.zeros((keys.shape[0], echoes.delay_s.shape[0], n))
        for g in range(keys.shape[0]):
            signals[g] = self._render(echoes, rate, idx[inv.ravel() == g], recording)
        d = self._render(echoes, rate, np.flatnonzero(direct), recording)
        env = space.envelopes(signals)
        return PoseGroups(
            env, keys.astype(int), d, space.envelopes(d), signals if keep_signals else None
        )

    def _render(
        self, echoes: Echoes, rate: np.ndarray | None, rows: np.ndarray, recording: P.Recording
    ) -> np.ndarray:
        """The noise-free signals (M, T) of the paths `rows` of `echoes` (their Doppler
        factors `rate`, None: static), rendered as the simulator renders a recording
        (its options and path response) at `recording`'s length and emission sample."""
        sim, sensor = self.simulator, self.scene.sensor
        capture = Capture(
            sensor.array, sensor.call, sensor.sample_rate_hz, recording.n_samples, sim.c
        )
        options = dataclasses.replace(sim.options, emission_index=recording.emission_index)
        doppler = None if rate is None else rate[:, rows]
        rec = simulate(
            echoes.select(rows), capture, options=options, response=sim.response, doppler=doppler
        )
        return np.asarray(rec.samples, float)
