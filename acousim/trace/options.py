"""The settings the tracer's stages take, read once from a scene."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.scene.model import Diffraction, FloorRule, Scene

__all__ = ["STEP_FREQUENCY_HZ", "TraceSettings", "resolution_length"]

#: the frequency (Hz) whose quarter wavelength the default edge-element step is
STEP_FREQUENCY_HZ = 85e3


def resolution_length(call, speed_of_sound_m_s: float) -> float:
    """The call's range resolution as a path length (m): c / bandwidth, with the
    bandwidth no smaller than 1 / duration (a pure tone resolves c * duration)."""
    lo, hi = call.band_hz
    return speed_of_sound_m_s / max(hi - lo, 1.0 / call.duration_s)


@dataclass(frozen=True)
class TraceSettings:
    """What the stages need to know (SI units).

    rays : rays shot over the beam per pose (None: the automatic budget of
    :mod:`.budget`, at most ``rays_max``); bounces : maximum reflections of a ray;
    beam_rad : half-angle of the cone of rays; max_path_m : longest path (twice the
    maximum range); resolution_m : the call's range resolution as a path length;
    energy_floor_db : paths this far below the strongest echo are dropped;
    energy_floor_rule : what that floor bounds, each dropped path ("path") or their
    summed energy ("sum") (:mod:`.floor`);
    direct_path : include the emitter -> microphone path; diffraction : the scene's
    :class:`~acousim.scene.model.Diffraction` settings, whole (stage 3);
    diffraction_pair_step_m : the element step of edge to edge: the edge-element
    step scaled to the call's highest frequency (the default step, 1 mm, is a
    quarter wavelength at :data:`STEP_FREQUENCY_HZ`; a 25-50 kHz call takes 1.7 mm);
    min_path_m : the paths shorter than this (m, at the array centre) are not asked
    for (0: every path; a call heard late in another sonar's window,
    :meth:`~acousim.trace.tracer.Tracer.traced`): the diffraction stage may leave
    them out.
    """

    rays: int | None
    bounces: int
    beam_rad: float
    max_path_m: float
    resolution_m: float
    energy_floor_db: float
    direct_path: bool
    diffraction: Diffraction
    diffraction_pair_step_m: float | None = None
    rays_max: int = 400_000
    min_path_m: float = 0.0
    energy_floor_rule: FloorRule = "path"

    @classmethod
    def from_scene(cls, scene: Scene) -> TraceSettings:
        sim = scene.simulation
        return cls(
            rays=sim.rays,
            bounces=sim.bounces,
            beam_rad=float(np.deg2rad(sim.beam_deg)),
            max_path_m=2 * sim.max_range_m,
            resolution_m=resolution_length(scene.sensor.call, scene.environment.speed_of_sound_m_s),
            energy_floor_db=sim.energy_floor_db,
            direct_path=scene.sensor.direct_path,
            diffraction=sim.diffraction,
            diffraction_pair_step_m=sim.diffraction.step_m
            * max(1.0, STEP_FREQUENCY_HZ / max(scene.sensor.call.band_hz)),
            rays_max=sim.rays_max,
            energy_floor_rule=sim.energy_floor_rule,
        )
