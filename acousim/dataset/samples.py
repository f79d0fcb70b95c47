"""One dataset sample: its random choices (a pure function of the spec's seed and the
sample index), its varied scene and its simulated recording. Shared by the shard
writers (:mod:`acousim.dataset.generation`, :mod:`acousim.dataset.chirp_shards`)."""

from __future__ import annotations

import dataclasses
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from acousim.dataset.spec import DatasetSpec, SpecError
from acousim.scene import Pose, load_scene
from acousim.scene.model import Environment
from acousim.scene.rig import Mount, sonar_scene
from acousim.scene.trajectory import Trajectory
from acousim.simulator import Simulator
from acousim.trace.tracer import caster_of
from acousim.trace.world.build import build_world


@lru_cache(maxsize=8)
def _scene(path: str):
    return load_scene(path)


@lru_cache(maxsize=4)
def _world_caster(path: str):
    """Geometry for collision checks, built once per scene file and process."""
    scene = _scene(path)
    if not scene.meshes:
        return None
    return caster_of(build_world(scene), threads=1)


def _clear(path: str, position: np.ndarray, clearance: float) -> bool:
    caster = _world_caster(path)
    if caster is None:
        return True
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    t, f = caster.first_hit(np.broadcast_to(position, dirs.shape), dirs)
    return bool(np.all(t >= clearance)) and bool(np.all(f >= 0))  # inside and clear


def sample_parameters(spec: DatasetSpec, i: int) -> dict:
    """The random choices of sample i: scene (relative to the spec's folder), pose
    (``Pose.to_dict`` form: position_m, yaw_deg, pitch_deg, roll_deg), conditions,
    noise seed."""
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, i]))
    w = np.array([s.weight for s in spec.scenes])
    k = int(rng.choice(len(spec.scenes), p=w / w.sum()))
    choice = spec.scenes[k]
    scene = _scene(str(choice.file))
    position, yaw, pitch, roll, extra = _drawn_pose(spec, i, k, scene, rng)
    cond = {
        name: d.draw(rng)
        for name, d in sorted(spec.randomize.items())
        if name not in ("mount_jitter_deg", "mount_jitter_m")
    }
    if "mount_jitter_deg" in spec.randomize:  # the sensor's mounting: yaw and pitch
        cond["mount_yaw_deg"] = spec.randomize["mount_jitter_deg"].draw(rng)
        cond["mount_pitch_deg"] = spec.randomize["mount_jitter_deg"].draw(rng)
        yaw = yaw + float(np.deg2rad(cond["mount_yaw_deg"]))
        pitch = pitch + float(np.deg2rad(cond["mount_pitch_deg"]))
    if "mount_jitter_m" in spec.randomize:
        shift = [spec.randomize["mount_jitter_m"].draw(rng) for _ in range(3)]
        cond["mount_shift_m"] = shift
        position = np.asarray(position) + shift
    # one pose representation in every file (recordings too): Pose.to_dict, degrees
    drawn = Pose(position, float(yaw), float(pitch), float(roll))
    pose = {**drawn.to_dict(), **extra}
    del pose["time_s"]
    params = {
        "index": i,
        "scene": _relative(choice.file, spec),
        "pose": pose,
        "conditions": cond,
        "noise_seed": int(rng.integers(2**62)),
    }
    if scene.rig is not None:  # the pose drawn is the body's; the sonar's from its mount
        mount = _mount(scene, choice, rng)
        sonar = {**mount.place(drawn).to_dict(), **extra}
        del sonar["time_s"]
        params.update(sensor=choice.sensor, mount=mount.to_dict(), body_pose=pose, pose=sonar)
    return params


def _drawn_pose(spec: DatasetSpec, i: int, k: int, scene, rng) -> tuple:
    """Sample i's pose in scene choice k (a rig's: the body's): position (3,) m, yaw,
    pitch, roll (rad) and what to add to the stored pose (its trajectory index)."""
    choice = spec.scenes[k]
    if choice.poses == "trajectory":  # a rig: the body's poses
        trajectory = scene.sensor.poses if scene.rig is None else scene.rig.poses
        j = int(rng.integers(len(trajectory)))
        p = trajectory[j]
        return p.position_m, p.yaw_rad, p.pitch_rad, p.roll_rad, {"trajectory_index": j}
    reg = choice.region
    for _attempt in range(100):
        pos = np.array([rng.uniform(*reg[a]) for a in ("x", "y", "z")])
        if _clear(str(choice.file), pos, choice.clearance_m):
            break
    else:
        raise SpecError(
            f"sample {i}: no collision-free pose (clearance {choice.clearance_m:g} m) "
            f"in 100 draws in the region of {choice.file}; widen the region or lower "
            "clearance_m",
            file=spec.source,
            key=f"scenes[{k}].region",
            value=reg,
        )
    yaw = np.deg2rad(rng.uniform(*reg.get("yaw_deg", (0.0, 0.0))))
    return pos, yaw, 0.0, 0.0, {}


def _mount(scene, choice, rng):
    """The mount of the rig's sonar `choice.sensor`: each key of `choice.mount` drawn
    uniformly in its [low, high], the others as the rig declares them."""

    sonar = next(s for s in scene.rig.sonars if s.name == choice.sensor)
    declared = sonar.mount.to_dict()
    position = list(declared["position_m"])
    rotation = list(declared["rotation_deg"])  # roll, pitch, yaw
    for n, key in enumerate(("x", "y", "z")):
        if key in choice.mount:
            position[n] = float(rng.uniform(*choice.mount[key]))
    for n, key in enumerate(("roll_deg", "pitch_deg", "yaw_deg")):
        if key in choice.mount:
            rotation[n] = float(rng.uniform(*choice.mount[key]))
    return Mount.degrees(position, rotation)


def _relative(file: str | Path, spec: DatasetSpec) -> str:
    """A scene path as stored: relative to the spec's folder, normalised, '/' separated."""
    folder = Path(spec.source).parent
    return Path(os.path.relpath(os.path.normpath(Path(file)), os.path.normpath(folder))).as_posix()


def _scene_path(params: dict, spec: DatasetSpec) -> str:
    return os.path.normpath(Path(spec.source).parent / params["scene"])


def _pose(p: dict):
    yaw, pitch, roll = np.deg2rad([p["yaw_deg"], p["pitch_deg"], p["roll_deg"]])
    return Pose(p["position_m"], float(yaw), float(pitch), float(roll))


def _varied_scene(params: dict, spec: DatasetSpec):
    scene = _scene(_scene_path(params, spec))
    c = params["conditions"]
    env = Environment(
        c.get("temperature_c", scene.environment.temperature_c),
        c.get("humidity_percent", scene.environment.humidity_percent),
        scene.environment.pressure_kpa,
    )
    sim = dataclasses.replace(
        scene.simulation, seed=params["noise_seed"], snr_db=c.get("snr_db", scene.simulation.snr_db)
    )
    meshes = scene.meshes
    if "reflection_scale" in c:
        s = min(
            max(c["reflection_scale"], 0.0),
            1.0
            / max(
                [x.reference[0] for m in meshes for x in (m.material, *m.materials.values())]
                or [1.0]
            ),
        )
        meshes = tuple(
            dataclasses.replace(
                m,
                material=m.material.scaled(s),
                materials={g: x.scaled(s) for g, x in m.materials.items()},
            )
            for m in meshes
        )
    return dataclasses.replace(scene, environment=env, simulation=sim, meshes=meshes)


def simulate_sample(spec: DatasetSpec, i: int, n_samples: int | None = None):
    """(recording, parameters, varied scene, pose) of sample i; `n_samples`: the
    recording's length (default: the scene's maximum range in the sample's air)."""
    params = sample_parameters(spec, i)
    scene = _sonar_alone(_varied_scene(params, spec), params)
    pose = _pose(params["pose"])
    sim = Simulator(scene, threads=1)
    motion = _motion(pose, params["conditions"])
    return sim.simulate_pose(pose, 0, n_samples=n_samples, motion=motion), params, scene, pose


def _sonar_alone(scene, params: dict):
    """A rig's scene as the sample's sonar alone on its drawn mount (no crosstalk);
    any other scene as it is."""
    if scene.rig is None:
        return scene

    m = params["mount"]
    return sonar_scene(scene, params["sensor"], Mount.degrees(m["position_m"], m["rotation_deg"]))


def sample_array(params: dict, spec: DatasetSpec):
    """The array of sample `params` (a rig's: its sonar's)."""
    scene = _scene(_scene_path(params, spec))
    if scene.rig is None:
        return scene.sensor.array
    return next(s.sensor.array for s in scene.rig.sonars if s.name == params["sensor"])


def _motion(pose, conditions: dict):
    """The sensor driving forward (along its axis) at ``speed_m_s`` and turning about
    the vertical at ``turn_rate_deg_s`` during the measurement, when the spec
    randomises them; None (a frozen pose) otherwise."""
    speed = conditions.get("speed_m_s", 0.0)
    turn = conditions.get("turn_rate_deg_s", 0.0)
    if speed == 0 and turn == 0:
        return None
    return Trajectory.constant(pose, speed * pose.rotation[:, 0], [0, 0, np.deg2rad(turn)])
