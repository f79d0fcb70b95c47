"""One dataset sample: its random choices (a pure function of the spec's seed and the
sample index), its varied scene and its simulated recording. Shared by the shard
writers (:mod:`acousim.dataset.generation`, :mod:`acousim.dataset.chirp_shards`)."""

from __future__ import annotations

import dataclasses
import os
from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from acousim.dataset.spec import DatasetSpec, SpecError, _relative_to
from acousim.rig import RigSimulator
from acousim.scene import Pose, load_scene
from acousim.scene.model import Environment
from acousim.scene.rig import Firing, Mount, sonar_scene
from acousim.scene.trajectory import Trajectory
from acousim.simulator import Simulator
from acousim.trace.direct import MIN_POINT_DISTANCE_M, point_gaps
from acousim.trace.motion.moving_world import _with_meshes
from acousim.trace.tracer import caster_of, enclosing_materials
from acousim.trace.world.build import World, build_world
from acousim.trace.world.clearance import (
    SENSOR_CLEARANCE_M,
    surface_distance,
    surface_mesh,
    too_near,
)
from acousim.trace.world.embree import RayCaster


@lru_cache(maxsize=8)
def _scene(path: str):
    return load_scene(path)


@dataclasses.dataclass(frozen=True)
class _Geometry:
    """A scene's meshes for testing random poses: the world, its ray caster and its
    faces as a trimesh mesh (true distances)."""

    world: World
    caster: RayCaster
    mesh: trimesh.Trimesh


def _geometry(path: str, t_s: float = 0.0) -> _Geometry | None:
    """The scene's meshes where they are at time `t_s` (s; a sample's pose is at time
    0, a rig's sonar fires at its firing's offset), built once per scene file, time
    (for moving meshes) and process; None without meshes."""
    moving = any(m.moving for m in _scene(path).meshes)
    return _geometry_at(path, t_s if moving else 0.0)


@lru_cache(maxsize=8)  # as many as _scene keeps: a rig's moving meshes at each firing
def _geometry_at(path: str, t_s: float) -> _Geometry | None:
    scene = _scene(path)
    if not scene.meshes:
        return None
    world = build_world(_with_meshes(scene, [m.placed_at(t_s) for m in scene.meshes]))
    return _Geometry(world, caster_of(world, threads=1), surface_mesh(world))


def _world_caster(path: str) -> RayCaster | None:
    """The ray caster of the scene's meshes at time 0 (:func:`_geometry`)."""
    geometry = _geometry(path)
    return None if geometry is None else geometry.caster


#: the test rays of the inside rule: +-x, +-y, +-z (world frame)
_RAYS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def _first_hits(path: str, position: np.ndarray) -> np.ndarray | None:
    """Distance (m) to the first surface along each test ray (6,), inf where a ray
    meets none; None for a scene without meshes."""
    caster = _world_caster(path)
    if caster is None:
        return None
    t, f = caster.first_hit(np.broadcast_to(position, _RAYS.shape), _RAYS)
    return np.where(np.asarray(f) >= 0, t, np.inf)


@lru_cache(maxsize=8)
def _enclosed(path: str) -> bool:
    """Whether the scene is a closed space: every test ray from its own sensor's first
    position (a rig's: its first sonar's) meets a surface."""
    hits = _first_hits(path, _scene(path).sensor.poses[0].position_m)
    return hits is not None and bool(np.all(np.isfinite(hits)))


def _clear(path: str, position: np.ndarray, clearance: float) -> str | None:
    """Why a random position (3,) m (the sensor's, a rig's body's) is refused, or
    None (accepted):

    * ``"near"``: a surface nearer than `clearance` (m, true distance);
    * ``"outside"``: in a closed scene (:func:`_enclosed`: the scene's own sensor sees
      a surface along every test ray, +-x, +-y, +-z), a test ray meets no surface:
      the pose is outside the room (or inside a wall).

    In an open scene (a wall, a corridor's open end) a ray that meets nothing is clear."""
    hits = _first_hits(path, position)
    if hits is None:
        return None
    if clearance > 0 and surface_distance(_geometry(path).mesh, position)[0] < clearance:
        return "near"
    if _enclosed(path) and not np.all(np.isfinite(hits)):
        return "outside"
    return None


@dataclasses.dataclass(frozen=True)
class _Ends:
    """Where the simulation of a sample checks its sensor (:func:`_ends`): at time
    `t_s` (s; moving meshes placed then) its emitters (E, 3) and microphones (M, 3),
    m, world frame."""

    t_s: float
    emitters_m: np.ndarray
    mics_m: np.ndarray


def _refused_ends(path: str, ends: _Ends, clearance: float) -> str | None:
    """Why the emitters and microphones of a drawn pose are refused, or None.  By
    the tracer's own rules (the simulation would stop): ``"point"``, a point
    reflector within 1 mm of one (:func:`acousim.trace.direct.point_gaps`);
    ``"tracer"``, one nearer than 1 cm to a surface
    (:func:`acousim.trace.world.clearance.too_near`); ``"enclosed"``, an emitter
    inside a closed mesh (:func:`acousim.trace.tracer.enclosing_materials`, when the
    scene shoots rays).  By the spec: ``"ends"``, one nearer than `clearance` (m,
    true distance) to a surface."""
    scene, every = _scene(path), np.vstack([ends.emitters_m, ends.mics_m])
    if scene.points and np.any(point_gaps(scene.points, ends.t_s, every)[1] < MIN_POINT_DISTANCE_M):
        return "point"
    geometry = _geometry(path, ends.t_s)
    if geometry is None:
        return None
    if np.any(too_near(geometry.caster, geometry.world, every)):
        return "tracer"
    if scene.simulation.rays != 0 and any(
        enclosing_materials(geometry.caster, geometry.world, e) for e in ends.emitters_m
    ):
        return "enclosed"
    if clearance > 0 and np.any(surface_distance(geometry.mesh, every) < clearance):
        return "ends"
    return None


#: draws of a random pose (a position refused, or a whole pose) before the region is
#: declared unusable, when it is checked before any work (:func:`check_regions`)
DRAWS = 100

#: draws of a random pose for one sample: more than the region's check, so that a
#: region whose check found a pose does not stop the run at a sample (a region where
#: 1 draw in 100 fits: one sample in 23000 runs out)
SAMPLE_DRAWS = 1000

#: what each refusal of a draw says (:func:`_no_pose`)
_WHY = {
    "near": "had a surface nearer than clearance_m = {c:g} m (lower clearance_m or move "
    "the region away from it)",
    "outside": "were outside the closed scene (a test ray along +-x, +-y or +-z met no "
    "surface, while the scene's own sensor sees one along each): move the region inside "
    "the room",
    "ends": "put the emitter or a microphone nearer than clearance_m = {c:g} m to a surface "
    "(lower clearance_m or move the region away from it)",
    "tracer": "put the emitter or a microphone within the simulation's "
    f"{SENSOR_CLEARANCE_M:g} m of a surface (move the region away from it)",
    "point": "put the emitter or a microphone within the simulation's "
    f"{MIN_POINT_DISTANCE_M:g} m of a point reflector (move the region away from it)",
    "enclosed": "put an emitter inside a closed mesh (a wall's or an object's solid, which "
    "the simulation refuses): move the region out of it",
}


def _no_pose(spec: DatasetSpec, k: int, what: str, refused: dict) -> SpecError:
    """The error of scene choice k's region where no draw was accepted."""
    choice = spec.scenes[k]
    reasons = [f"{n} " + _WHY[why].format(c=choice.clearance_m) for why, n in refused.items() if n]
    return SpecError(
        f"{what}: no usable pose in {sum(refused.values())} draws in the region of "
        f"{choice.file}: " + "; ".join(reasons),
        file=spec.source,
        key=f"scenes[{k}].region",
        value=choice.region,
    )


def _draw_position(spec: DatasetSpec, k: int, rng, refused: dict, draws: int) -> np.ndarray | None:
    """A position (3,) m in scene choice k's region that :func:`_clear` accepts,
    counting the refused draws in `refused`; None once it holds `draws`."""
    choice = spec.scenes[k]
    reg = choice.region
    while sum(refused.values()) < draws:
        pos = np.array([rng.uniform(*reg[a]) for a in ("x", "y", "z")])
        why = _clear(str(choice.file), pos, choice.clearance_m)
        if why is None:
            return pos
        refused[why] += 1
    return None


def check_regions(spec: DatasetSpec) -> None:
    """Draw a pose in every random-pose scene's region (seeded by the spec's seed), so
    that a region without a usable pose fails before any work starts (a SpecError
    naming the scene's key)."""
    for k, choice in enumerate(spec.scenes):
        if choice.poses == "random":
            rng = np.random.default_rng(np.random.SeedSequence([spec.seed, k, 2**32]))
            _parameters(spec, 0, k, rng, "checking the region", DRAWS)


def sample_parameters(spec: DatasetSpec, i: int) -> dict:
    """The random choices of sample i: scene (relative to the spec's folder), pose
    (``Pose.to_dict`` form: position_m, yaw_deg, pitch_deg, roll_deg), conditions,
    noise seed.  A random pose is drawn again, from the same generator, while the
    simulation would refuse it or it breaks the scene's clearance_m
    (:func:`_parameters`)."""
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, i]))
    w = np.array([s.weight for s in spec.scenes])
    k = int(rng.choice(len(spec.scenes), p=w / w.sum()))
    return _parameters(spec, i, k, rng, f"sample {i}", SAMPLE_DRAWS)


def _parameters(spec: DatasetSpec, i: int, k: int, rng, what: str, draws: int) -> dict:
    """Sample i's choices in scene choice k, drawn from `rng`.  A random pose: a
    position that :func:`_clear` accepts, then the rest of the choices; the whole
    drawn again while :func:`_refused_ends` refuses the emitter or a microphone
    where the sample puts them (:func:`_ends`), at most `draws` draws in all (then
    a SpecError naming the region and how many draws each rule refused)."""
    choice = spec.scenes[k]
    if choice.poses != "random":
        return _drawn(spec, i, k, rng, None)
    refused = dict.fromkeys(_WHY, 0)
    while (position := _draw_position(spec, k, rng, refused, draws)) is not None:
        params = _drawn(spec, i, k, rng, position)
        why = _refused_ends(str(choice.file), _ends(params, spec), choice.clearance_m)
        if why is None:
            return params
        refused[why] += 1
    raise _no_pose(spec, k, what, refused)


def _drawn(spec: DatasetSpec, i: int, k: int, rng, position: np.ndarray | None) -> dict:
    """Sample i's choices in scene choice k (a random pose at `position`, its yaw
    drawn here; None: a pose of the trajectory), drawn from `rng`."""
    choice = spec.scenes[k]
    scene = _scene(str(choice.file))
    position, yaw, pitch, roll, extra = _drawn_pose(spec, k, scene, rng, position)
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


def _drawn_pose(spec: DatasetSpec, k: int, scene, rng, position: np.ndarray | None) -> tuple:
    """The pose in scene choice k (a rig's: the body's): position (3,) m, yaw,
    pitch, roll (rad) and what to add to the stored pose (its trajectory index);
    a random pose at `position`, a trajectory's pose (drawn) when None."""
    choice = spec.scenes[k]
    if position is None:  # a pose of the trajectory (a rig: the body's)
        trajectory = scene.sensor.poses if scene.rig is None else scene.rig.poses
        j = int(rng.integers(len(trajectory)))
        p = trajectory[j]
        return p.position_m, p.yaw_rad, p.pitch_rad, p.roll_rad, {"trajectory_index": j}
    yaw = np.deg2rad(rng.uniform(*choice.region.get("yaw_deg", (0.0, 0.0))))
    return position, yaw, 0.0, 0.0, {}


def _ends(params: dict, spec: DatasetSpec) -> _Ends:
    """Where the simulation of sample `params` checks its sensor (the clearance,
    :func:`acousim.trace.world.clearance.check_clearance`; an emitter inside a closed
    mesh): the sensor's emitter and microphones at its pose (time 0); a rig's
    sonar's on the mount drawn, and with the rig's crosstalk every other sonar's
    emitter, the body placed as :func:`_rig_firing` places it at the sonar's firing
    (still: in motion, another sonar's firing before or after it is tested where the
    body is at the sonar's)."""
    scene = _scene(_scene_path(params, spec))
    pose = _pose(params["pose"])
    array = sample_array(params, spec)
    emitters, mics = [pose.to_world(array.emitter_m)], pose.to_world(array.positions_m)
    if scene.rig is None or not scene.rig.crosstalk:
        return _Ends(0.0, np.array(emitters), mics)
    sonar = next(s for s in scene.rig.sonars if s.name == params["sensor"])
    m = params["mount"]
    body = _body(pose, Mount.degrees(m["position_m"], m["rotation_deg"]))
    emitters += [
        s.mount.place(body).to_world(s.sensor.array.emitter_m)
        for s in scene.rig.sonars
        if s is not sonar
    ]
    return _Ends(float(sonar.firing.times(0.0, 0.0)[0]), np.array(emitters), mics)


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
    return _relative_to(Path(file), Path(spec.source).parent)


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
    sim = scene.simulation
    if spec.quality is not None:  # the spec's (or --quality's) preset for every scene
        sim = sim.with_quality(spec.quality)
    sim = dataclasses.replace(
        sim, seed=params["noise_seed"], snr_db=c.get("snr_db", scene.simulation.snr_db)
    )
    meshes = scene.meshes
    if "reflection_scale" in c:
        s = max(c["reflection_scale"], 0.0)
        meshes = tuple(
            dataclasses.replace(
                m,
                material=_scaled(m.material, s),
                materials={g: _scaled(x, s) for g, x in m.materials.items()},
            )
            for m in meshes
        )
    return dataclasses.replace(scene, environment=env, simulation=sim, meshes=meshes)


def _scaled(material, scale: float):
    """`material` with each reflection coefficient (every value of a frequency table)
    times `scale`, at most 1: a surface returns at most what reaches it."""
    r = material.reflection
    r = tuple(min(v * scale, 1.0) for v in r) if isinstance(r, tuple) else min(r * scale, 1.0)
    return dataclasses.replace(material, reflection=r)


def simulate_sample(spec: DatasetSpec, i: int, n_samples: int | None = None):
    """(recording, parameters, varied scene, pose) of sample i; `n_samples`: the
    recording's length (default: the scene's maximum range in the sample's air).
    A rig's sample is its sonar's firing on the mount drawn (the scene returned: that
    sonar's); with the rig's crosstalk on, as the whole rig fires (:func:`_rig_firing`)."""
    params = sample_parameters(spec, i)
    varied = _varied_scene(params, spec)
    scene = _sonar_alone(varied, params)
    pose = _pose(params["pose"])
    motion = _motion(pose, params["conditions"])
    if varied.rig is not None and varied.rig.crosstalk:
        return _rig_firing(varied, params, pose, motion, n_samples), params, scene, pose
    sim = Simulator(scene, threads=1)
    return sim.simulate_pose(pose, 0, n_samples=n_samples, motion=motion), params, scene, pose


def _sonar_alone(scene, params: dict):
    """A rig's scene as the sample's sonar alone on its drawn mount (no crosstalk);
    any other scene as it is."""
    if scene.rig is None:
        return scene

    m = params["mount"]
    return sonar_scene(scene, params["sensor"], Mount.degrees(m["position_m"], m["rotation_deg"]))


def _rig_firing(scene, params: dict, pose: Pose, motion, n_samples: int | None):
    """The sample's sonar k firing from `pose` (moving as `motion`, its own trajectory;
    None: still) as the whole rig fires, every call of the others that reaches its
    window in the recording (:class:`acousim.rig.RigSimulator`):

    1. sonar k on the mount drawn; the body placed so that k is at `pose` at k's
       first firing t_k (in motion: the body's velocity the sonar's less its turn
       times the lever arm, so that k moves at t_k as `motion` says);
    2. each other sonar's firings of its schedule from the longest path's time (and
       the call's) before t_k to the end of k's window; k's at t_k only;
    3. firing t_k simulated, `n_samples` long.
    """
    rig = scene.rig
    names = [s.name for s in rig.sonars]
    k = names.index(params["sensor"])
    m = params["mount"]
    mount = Mount.degrees(m["position_m"], m["rotation_deg"])
    t_k = float(rig.sonars[k].firing.times(0.0, 0.0)[0])
    body = _body(pose, mount, t_k)
    trajectory = None
    if motion is not None:
        w = motion.angular_velocity(pose.time_s)
        lever = body.rotation @ np.asarray(mount.position_m)
        v = motion.velocity(pose.time_s) - np.cross(w, lever)
        trajectory = Trajectory.constant(body, v, w)
    sensor = rig.sonars[k].sensor
    n = scene.n_samples() if n_samples is None else n_samples
    window = n / sensor.sample_rate_hz
    reach = 2 * scene.simulation.max_range_m / scene.environment.speed_of_sound_m_s
    sonars = []
    for j, s in enumerate(rig.sonars):
        lead = reach + s.sensor.call.duration_s
        times = [t_k] if j == k else _firings_within(s.firing, t_k - lead, t_k + window)
        if times:  # a sonar silent near t_k is left out
            firing = Firing(times_s=tuple(times))
            sonars.append(dataclasses.replace(s, mount=mount if j == k else s.mount, firing=firing))
    placed = dataclasses.replace(rig, sonars=tuple(sonars), poses=(body,), motion=trajectory)
    firing_sim = RigSimulator(dataclasses.replace(scene, rig=placed), threads=1)
    (i,) = [x.index for x in firing_sim.measurements if sonars[x.sonar].name == names[k]]
    return firing_sim.simulate(i, n_samples=n)


def _body(pose: Pose, mount: Mount, t_s: float = 0.0) -> Pose:
    """The body's pose (at time `t_s`) that puts a sonar on `mount` at `pose`."""
    R = pose.rotation @ mount.rotation.T  # the body's rotation: the sonar's less its mount's
    yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX")
    return Pose(pose.position_m - R @ mount.position_m, yaw, pitch, roll, time_s=t_s)


def _firings_within(firing: Firing, start_s: float, end_s: float) -> list[float]:
    """The times (s) of `firing`'s schedule (its rate from its offset, both ways; or
    its explicit times) strictly between `start_s` and `end_s`."""
    if firing.times_s is not None:
        return [t for t in firing.times_s if start_s < t < end_s]
    period = 1.0 / firing.rate_hz
    first = int(np.ceil((start_s - firing.offset_s) / period))
    times = firing.offset_s + period * np.arange(first, first + int((end_s - start_s) / period) + 2)
    return [float(t) for t in times if start_s < t < end_s]


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
