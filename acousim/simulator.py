"""Scene files to recordings: trace every pose, render, add noise.

``Simulator(scene).run()`` returns one Recording per pose, each carrying what is
needed to redo or compare it: the scene file's hash, the package version, the seed,
the pose, and the ground truth (paths: position, amplitude at the array centre,
order and kind).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterable
from importlib.metadata import PackageNotFoundError, version

import numpy as np

import processing as P
from acousim.scene.model import Scene
from acousim.scene.pose import Pose
from acousim.synth.model import simulate
from acousim.synth.response import PathResponse
from acousim.trace.tracer import KIND, TracedPaths, Tracer
from processing.errors import InputError

__all__ = ["Simulator", "package_version"]

KIND_NAMES = {v: k for k, v in KIND.items()}

log = logging.getLogger(__name__)


def package_version() -> str:
    try:
        return version("acousim")
    except PackageNotFoundError:  # pragma: no cover
        return "unknown"


class Simulator:
    """Simulates a scene; the ray-tracing scene is built once and reused for every pose."""

    def __init__(self, scene: Scene, threads: int = 2) -> None:
        self.scene = scene
        self.tracer = Tracer(scene, threads)
        env = scene.environment
        self.c = env.speed_of_sound_m_s
        self.response = PathResponse(
            speed_of_sound_m_s=self.c,
            absorption=scene.simulation.absorption,
            temperature_c=env.temperature_c,
            humidity_percent=env.humidity_percent,
            pressure_kpa=env.pressure_kpa,
            emitter_radius_m=scene.sensor.emitter_radius_m,
        )

    def paths(self, pose: Pose) -> TracedPaths:
        return self.tracer.trace(pose)

    def simulate_pose(
        self, pose: Pose, index: int = 0, seed: int | None = None, n_samples: int | None = None
    ) -> P.Recording:
        """One recording at `pose`; the noise seed is derived from (scene seed, index).

        `n_samples` overrides the length the scene's maximum range implies (to match a
        real recording).
        """
        scene = self.scene
        sensor = scene.sensor
        scene.check_memory(1, n_samples)  # an InputError with the estimate, before allocating
        paths = self.tracer.trace(pose)
        mics = pose.to_world(sensor.array.positions_m)
        echoes = paths.echoes(mics, pose.rotation[:, 0], self.c)
        if sensor.mic_radius_m > 0:
            echoes = self._mic_directivity(echoes, paths, mics, pose.rotation[:, 0])
        base = scene.simulation.seed if seed is None else seed
        noise_seed = int(np.random.SeedSequence([base, index]).generate_state(1)[0])
        receiver = mics.mean(axis=0)
        level = paths.level_at(receiver)  # magnitudes: diffraction paths are signed
        meta = {
            "scene": scene.name,
            "scene_file": str(scene.source) if scene.source else None,
            "scene_sha256": scene.file_sha256,
            "max_range_m": float(scene.simulation.max_range_m),
            "acousim_version": package_version(),
            "pose": pose.to_dict(),
            "pose_index": index,
        }
        truth = P.GroundTruth(
            position_world_m=paths.position_m,
            position_sensor_m=pose.to_sensor(paths.position_m),
            amplitude=level,
            order=paths.order,
            kind=np.array([KIND_NAMES[c] for c in paths.kind.tolist()], dtype=str),
        )
        rec = simulate(
            echoes,
            sensor.array,
            sensor.call,
            sensor.sample_rate_hz,
            n_samples or scene.n_samples(),
            speed_of_sound_m_s=self.c,
            snr_db=scene.simulation.snr_db,
            seed=noise_seed,
            method=scene.simulation.fractional_delay,
            response=self.response,
            snr_reference="echoes",
            metadata=meta,
        )
        return dataclasses.replace(rec, truth=truth)

    def _mic_directivity(self, echoes, paths, mics, axis):
        """Microphone directivity: a baffled piston of radius mic_radius_m facing the
        sensor's axis, at the centre of the call's band (MEMS ports are small: the
        pattern barely changes across the band), as a gain per microphone and path."""
        from acousim.synth.echoes import Echoes
        from acousim.synth.response import piston_directivity

        arrival = paths.anchor_m[None, :, :] - mics[:, None, :]  # towards the source
        arrival /= np.maximum(np.linalg.norm(arrival, axis=2, keepdims=True), 1e-12)
        theta = np.arccos(np.clip(arrival @ axis, -1, 1))  # (M, N)
        f_c = float(np.mean(self.scene.sensor.call.band_hz))
        d = piston_directivity(f_c, theta, self.scene.sensor.mic_radius_m, self.c)
        return Echoes(
            echoes.delay_s,
            echoes.gain * d,
            echoes.path_length_m,
            echoes.order,
            echoes.emitter_angle_rad,
        )

    def run(
        self, poses: Iterable[int] | None = None, progress: Callable[[int, int], None] | None = None
    ) -> list[P.Recording]:
        """Recordings for the scene's poses (all, or the given indices)."""
        all_poses = self.scene.sensor.poses
        idx = list(range(len(all_poses))) if poses is None else list(poses)
        for i in idx:
            if not 0 <= i < len(all_poses):
                raise InputError(
                    f"pose index {i} out of range: the scene has {len(all_poses)} pose(s)"
                )
        self.scene.check_memory(len(idx))  # every recording is kept: refuse before starting
        # trace the next pose while the current one is rendered (Embree, the FFTs and
        # the sparse products release the GIL)
        from concurrent.futures import ThreadPoolExecutor

        out = []
        with ThreadPoolExecutor(1) as pool:
            ahead = pool.submit(self.tracer.trace, all_poses[idx[0]]) if idx else None
            for k, i in enumerate(idx):
                ahead.result()
                if k + 1 < len(idx):
                    ahead = pool.submit(self.tracer.trace, all_poses[idx[k + 1]])
                out.append(self.simulate_pose(all_poses[i], i))
                if progress:
                    progress(k + 1, len(idx))
        return out
