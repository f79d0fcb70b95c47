"""Scene files to recordings: trace every pose, render, add noise.

``Simulator(scene).run()`` returns one Recording per pose, each carrying what is
needed to redo or compare it: the scene file's hash, the package version, the seed,
the pose, and the ground truth (paths: position, amplitude at the array centre,
order and kind).

One pose goes down the stages once: trace (:mod:`acousim.trace`: the paths at the
pose of the start of the emission) -> kinematics (static: delays and gains at the
microphones; in motion, :mod:`acousim.kinematics`: reception times and Doppler
factors per path and microphone) -> render (:mod:`acousim.synth`) -> record (a
:class:`processing.Recording`).  :meth:`Simulator.run` makes several poses in two
processes (this one and a forked worker, :mod:`acousim.core.forked`) when they are
worth a fork, else in this one with threads; the same bytes either way.

A scene with motion (a continuous trajectory, a pose with a velocity or an angular
rate, moving point reflectors or meshes) is rendered with the exact kinematics of
:mod:`acousim.kinematics` (retarded time per path and microphone, Doppler); its
recordings also store the motion (``metadata["motion"]``: the pose at the start of
the emission, the velocity and the angular velocity) and the velocity of each path
(``rec.truth.velocity_world_m_s``).  A scene without motion takes
the static path unchanged.

Process-wide policy (BLAS threads, the allocator) is not set here: the entry point
calls :func:`acousim.process.configure`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import logging
import time
from collections.abc import Callable, Iterable
from importlib.metadata import PackageNotFoundError, version

import numpy as np

import processing as P
from acousim.core.echoes import Echoes
from acousim.kinematics import TABLE_STEP_S, SensorKinematics, arrivals
from acousim.kinematics.seen import seen_moving
from acousim.scene.lidar import Lidar
from acousim.scene.model import Diffraction, Scene, Simulation
from acousim.scene.pose import Pose
from acousim.synth.doppler import DopplerCache, DopplerPlan, plan_doppler
from acousim.synth.options import Capture, Noise, RenderOptions
from acousim.synth.response import PathResponse, mic_directivity
from acousim.synth.signal_model import in_window, simulate
from acousim.trace.direct import MIN_POINT_DISTANCE_M, check_points_clear
from acousim.trace.lidar import scan
from acousim.trace.motion.measurement import InMotion, paths_in_motion, tracer_for
from acousim.trace.paths import PathKind, TracedPaths, kind_names, reaching
from acousim.trace.seen import chain_fields, seen_static
from acousim.trace.tracer import Tracer
from processing.base import interrupt
from processing.base.errors import InputError
from processing.base.settings import settings_of

__all__ = ["Simulator", "Heard", "package_version", "MIN_POINT_DISTANCE_M"]


log = logging.getLogger(__name__)

#: `simulate_pose(motion=SCENE_MOTION)`: the scene's own motion
SCENE_MOTION = "scene"


#: poses :meth:`Simulator.run` keeps queued for its preparing thread (1: the next
#: one alone)
PREPARE_AHEAD = 2


@functools.lru_cache(maxsize=1)  # looked up once: 1.4 ms per recording otherwise
def package_version() -> str:
    try:
        return version("acousim")
    except PackageNotFoundError:  # pragma: no cover
        return "unknown"


def _on(trajectory, pose: Pose) -> bool:
    """Whether `pose` is where `trajectory` is at ``pose.time_s``."""
    t = pose.time_s
    # (np.allclose with rtol=0, a fifth of its time)
    return bool(
        np.abs(trajectory.position(t) - pose.position_m).max() <= 1e-9
        and np.abs(trajectory.rotation(t) - pose.rotation).max() <= 1e-9
    )


@dataclasses.dataclass(frozen=True, eq=False)
class Heard:
    """The paths of one measurement at the microphones: the kinematics stage's result
    (static: :meth:`TracedPaths.echoes`; in motion: :func:`acousim.kinematics.arrivals`),
    what the recording and its ground truth are made of.  N paths, M microphones."""

    echoes: Echoes
    """delays (from the start of the emission) and gains (M, N), the microphones'
    directivity applied."""
    position_m: np.ndarray
    """(N, 3) where each path comes from (world frame, at the start of the emission)."""
    kind_codes: np.ndarray
    """(N,) int, the paths' :class:`~acousim.trace.paths.PathKind` codes (their names:
    :attr:`kinds`, :meth:`kind_array`)."""
    order: np.ndarray
    """(N,) reflections."""
    level: np.ndarray
    """(N,) magnitude of each path's gain at the array's centre."""
    rays: int
    """rays the trace shot."""
    velocity_m_s: np.ndarray | None = None
    """(N, 3) velocity of each path's last point (in motion; None: static)."""
    rate: np.ndarray | None = None
    """(M, N) Doppler factors (in motion; None: static)."""
    rows: np.ndarray | None = None
    """(N',) int: the path (row of `position_m`, ...) of each echo, in motion where
    only those that reach the window are kept (None: every path, in order)."""
    seen: dict = dataclasses.field(default_factory=dict)
    """what the sensor sees of each path and its chain, as :class:`processing.GroundTruth`
    keywords (delay and arrival at the array centre, apparent positions, first and
    last points, objects: :mod:`acousim.trace.seen`, :mod:`acousim.kinematics.seen`)."""

    @property
    def kinds(self) -> list[str]:
        """(N,) the path kinds' names."""
        return kind_names(self.kind_codes)

    def kind_array(self) -> np.ndarray:
        """(N,) str, the path kinds' names as an array (from the codes: a list of
        thousands of strings takes a hundred times longer to convert)."""
        return _KIND_NAMES[self.kind_codes]


@dataclasses.dataclass(frozen=True)
class _Prepared:
    """A recording but its samples (:meth:`Simulator._prepare`)."""

    echoes: Echoes
    n_samples: int
    metadata: dict
    truth: P.GroundTruth
    #: a measurement in motion: the Doppler factor (M, N) of each echo (None: static)
    rate: np.ndarray | None = None
    #: a measurement in motion: its render planned (:meth:`Simulator._planned`)
    plan: DopplerPlan | None = None
    #: the LiDAR's scan at the pose (a scene with ``sensor.lidar``)
    lidar: P.PointCloud | None = None


class Simulator:
    """Simulates a scene; the ray-tracing scene is built once and reused for every pose.

    `tracer`: another simulator's (:attr:`tracer`) to share its world, prepared once
    (the sensors of a rig, :mod:`acousim.rig`)."""

    def __init__(self, scene: Scene, threads: int = 2, *, tracer=None) -> None:
        if scene.rig is not None:
            raise InputError(
                f"scene {scene.name!r} is a rig of {len(scene.rig.sonars)} sonar(s): "
                "simulate it with acousim.RigSimulator (acousim simulate)",
                key="Scene.rig",
            )
        self.scene = scene
        #: the sensor's array: its emitter and microphones, sensor frame
        self.array = scene.sensor.array
        # moving point reflectors are placed per emission instant (paths_in_motion)
        self.moving_points = tuple(p for p in scene.points if p.moving)
        #: meshes that move: the world is rebuilt per emission instant (a scene
        #: without them keeps its one world)
        self.moving_meshes = any(m.moving for m in scene.meshes)
        self.tracer = tracer if tracer is not None else tracer_for(scene, threads)
        env = scene.environment
        self.c = env.speed_of_sound_m_s
        self.response = PathResponse(
            speed_of_sound_m_s=self.c,
            absorption=scene.simulation.absorption,
            temperature_c=env.temperature_c,
            humidity_percent=env.humidity_percent,
            pressure_kpa=env.pressure_kpa,
            emitter_radius_m=scene.sensor.emitter_radius_m,
            materials=self.tracer.world.spectra if self.tracer.world is not None else None,
        )
        sim = scene.simulation
        self.options = RenderOptions(
            interpolator=sim.fractional_delay,
            rate=sim.render_rate,
            domain=sim.render_domain,
            band_floor_db=sim.render_band_db,
            compress_tolerance=sim.render_tolerance,
        )
        #: the Doppler renderer's templates and spectra, reused from pose to pose
        self.doppler_cache = DopplerCache()
        #: seconds the last pose made in one thread took (:meth:`_made`; None: none
        #: yet), what :meth:`_shared` expects of the next
        self._pace_s: float | None = None

    def paths(self, pose: Pose) -> TracedPaths:
        return self.tracer.trace(pose, self._traced_array)

    @property
    def _traced_array(self):
        """The array the tracer is asked for (None: the scene's sensor's, its cache
        keyed by the pose alone)."""
        return None if self.array is self.tracer.scene.sensor.array else self.array

    def simulate_pose(
        self,
        pose: Pose,
        index: int = 0,
        seed: int | None = None,
        n_samples: int | None = None,
        motion=SCENE_MOTION,
        *,
        joined: tuple[tuple[Echoes, np.ndarray], ...] = (),
    ) -> P.Recording:
        """One recording at `pose`; the noise seed is derived from (scene seed, index).

        `n_samples` overrides the length the scene's maximum range implies (to match a
        real recording).  `motion`: the sensor's
        :class:`~acousim.scene.trajectory.Trajectory` during the measurement (`pose`
        is where it is at the start of the emission, at ``pose.time_s``), None for a
        frozen pose; by default the scene's (if `pose` lies on it: a pose elsewhere
        is frozen).  `joined`: the echoes of other calls (each: echoes (M, N'),
        delays from this recording's start, and their Doppler factors (M, N')) in
        its window, rendered in the same pass as its own with its call, response and
        options (a rig's crosstalk, :mod:`acousim.rig`; a measurement in motion
        only); the noise's level refers to its own echoes alone.
        """
        with self._naming_the_pose(index):
            prep = self._prepare(pose, index, n_samples, motion)
            return self._record(prep, index, seed, joined)

    @contextlib.contextmanager
    def _naming_the_pose(self, index: int):
        """An InputError of one pose's work that names no file gets the scene's file
        (else its name) and the pose index: "room.toml: pose 12: the sensor ..."."""
        try:
            yield
        except InputError as exc:
            if exc.file is not None:
                raise
            where = "" if self.scene.source else f"scene {self.scene.name!r}: "
            raise InputError(
                f"{where}pose {index}: {exc.reason}",
                file=self.scene.source,
                key=exc.key,
                value=exc.value,
            ) from None

    def motion_at(self, pose: Pose, motion=SCENE_MOTION):
        """The trajectory of a measurement starting at `pose`: `motion`, or by default
        the scene's if `pose` lies on it (else None: frozen)."""
        if isinstance(motion, str) and motion == SCENE_MOTION:
            motion = self.scene.sensor.motion
            if motion is not None and not _on(motion, pose):
                log.debug("pose %s is not on the scene's trajectory: frozen", pose.to_dict())
                motion = None
        return motion

    def in_motion(self, motion) -> bool:
        """Whether a measurement along `motion` (None: frozen) takes the kinematics of
        motion (the sensor, a point reflector or a mesh moves)."""
        return motion is not None or bool(self.moving_points) or self.moving_meshes

    def _prepare(self, pose: Pose, index: int, n_samples: int | None, motion) -> _Prepared:
        """Everything of a recording but its samples: the paths traced and heard at the
        microphones (:meth:`heard`), the metadata, the ground truth and the LiDAR's
        scan.  :meth:`run` prepares the next pose in a thread while the current one
        renders."""
        motion = self.motion_at(pose, motion)
        array = self.array
        ends = pose.to_world(np.vstack([array.emitter_m, array.positions_m]))
        check_points_clear(self.scene.points, pose.time_s, ends, str(pose.to_dict()))
        scene = self.scene
        scene.check_memory(1, n_samples)  # an InputError with the estimate, before allocating
        n = n_samples or scene.n_samples()
        heard = self.heard(pose, motion, n)
        meta = {**_metadata(scene, pose, index), "rays": heard.rays}
        if heard.rate is not None:
            meta["motion"] = _motion(pose, motion, heard.rate)
        truth = P.GroundTruth(
            position_world_m=heard.position_m,
            position_sensor_m=pose.to_sensor(heard.position_m),
            amplitude=heard.level,
            order=heard.order,
            kind=heard.kind_array(),
            velocity_world_m_s=heard.velocity_m_s,
            **heard.seen,
        )
        lidar = self.lidar_scan(pose, index, motion)
        return _Prepared(heard.echoes, n, meta, truth, rate=heard.rate, lidar=lidar)

    def heard(
        self,
        pose: Pose,
        motion,
        n_samples: int,
        *,
        max_path_m: float | None = None,
        min_path_m: float | None = None,
        seen: bool = True,
    ) -> Heard:
        """The paths of a measurement starting at `pose` heard at the microphones
        (along `motion`, a trajectory or None; a recording of `n_samples`), down the
        stages:

        1. trace: the paths at the pose of the start of the emission (moving meshes
           and point reflectors placed where they are then: :meth:`moving_paths`);
        2. kinematics: static, the delays and gains at the microphones; in motion,
           per path and microphone the reception times of the call's first, middle
           and last sample for the moving emitter, reflector and microphone
           (:func:`acousim.kinematics.arrivals`): the echoes and their Doppler
           factors, those that reach the window kept;
        3. the microphones' directivity (:func:`acousim.synth.response.mic_directivity`).
        Rendering (:meth:`_planned`, :meth:`_record`) follows.

        `max_path_m`: only the paths up to that length are traced (m; None: the
        scene's).  `min_path_m`: the paths shorter than that at every microphone
        at the start of the emission are left out before the kinematics (m; a call
        heard late in another sonar's window, :mod:`acousim.rig`: the echoes then
        are those of the other paths, ``rows`` naming them).  `seen`: False leaves
        out what the sensor sees of each path (``seen`` empty); with `min_path_m`
        in motion, NaN for the paths left out.
        """
        if self.in_motion(motion):
            return self._heard_moving(pose, motion, n_samples, max_path_m, min_path_m, seen)
        mics = pose.to_world(self.array.positions_m)
        paths, rays = self.tracer.traced(
            pose, self._traced_array, max_path_m, min_path_m, self.scene.sensor.direct_path
        )
        receiver = mics.mean(axis=0)
        level = paths.level_at(receiver)  # magnitudes: diffraction paths are signed
        rows = None if min_path_m is None else reaching(paths, mics, min_path_m)
        heard = paths if rows is None else paths.select(rows)
        echoes = heard.echoes(mics, pose.rotation[:, 0], self.c)
        what = {}
        if seen:
            centre = self.array.positions_m.mean(axis=0)
            what = {
                **seen_static(paths, pose, centre, self.c).fields(),
                **self._chains(paths, pose, receiver),
            }
        return Heard(
            self._mic_directivity(echoes, heard.anchor_m, mics, pose),
            paths.position_m,
            paths.kind,
            paths.order,
            level,
            rays,
            rows=rows,
            seen=what,
        )

    def _heard_moving(
        self, pose: Pose, motion, n_samples: int, max_path_m, min_path_m=None, seen=True
    ) -> Heard:
        """:meth:`heard` in motion."""
        m = self._in_motion(pose, max_path_m, min_path_m)
        sensor = self.scene.sensor
        mics = pose.to_world(self.array.positions_m)
        receiver = mics.mean(axis=0)
        level = m.moving.level_at(receiver)  # magnitudes, as TracedPaths.level_at
        moving, interactions = m.moving, m.interactions
        rows = np.arange(len(moving))
        if min_path_m is not None:
            rows = reaching(moving, mics, min_path_m)
            moving, interactions = moving.select(rows), interactions[rows]
        kin = SensorKinematics(
            motion, pose, self.array, n_samples / sensor.sample_rate_hz, TABLE_STEP_S
        )
        arr = arrivals(moving, kin, sensor.call.duration_s, self.c, pose.rotation[:, 0])
        echoes = arr.echoes
        if interactions.shape[1]:  # material tables
            echoes = dataclasses.replace(echoes, interactions=interactions)
        echoes = self._mic_directivity(echoes, moving.anchor_m, mics, pose)
        what = {}
        if seen:
            centre = self.array.positions_m.mean(axis=0)
            guess = arr.echoes.delay_s.mean(axis=0)  # the centre's, within a microsecond
            points = (m.position_m[len(m.traced) :], m.points)
            sees = seen_moving(moving, kin, motion, pose, centre, self.c, guess, arr).fields()
            if rows.size != len(m.moving):  # of the paths left out: NaN
                sees = {k: _scattered(v, rows, len(m.moving)) for k, v in sees.items()}
            what = {**sees, **self._chains(m.traced, pose, receiver, points)}
        keep = in_window(echoes, n_samples, sensor.sample_rate_hz)
        rate = arr.rate
        if not keep.all():  # (every path heard: the arrays as they are)
            echoes, rate, rows = echoes.select(keep), rate[:, keep], rows[keep]
        return Heard(
            echoes,
            m.position_m,
            m.kind_codes,
            m.moving.order,
            level,
            m.rays,
            velocity_m_s=m.velocity_m_s,
            rate=rate,
            rows=rows,
            seen=what,
        )

    def _chains(self, paths: TracedPaths, pose: Pose, receiver: np.ndarray, points=None) -> dict:
        """The ground truth's chain fields (:func:`acousim.trace.seen.chain_fields`) in
        the world of the emission instant."""
        emitter = pose.to_world(self.array.emitter_m)
        tracer = self.tracer.tracer_at(pose.time_s)
        return chain_fields(tracer, self.scene, paths, emitter, receiver, points)

    def _mic_directivity(self, echoes: Echoes, anchor_m, mics, pose: Pose) -> Echoes:
        """`echoes` with the microphones' directivity (the sensor's ``mic_radius_m``;
        0: omni, as they are), the ports facing the sensor's axis."""
        sensor = self.scene.sensor
        if sensor.mic_radius_m <= 0:
            return echoes
        return mic_directivity(
            echoes,
            anchor_m=anchor_m,
            mics_m=mics,
            axis=self.mic_axis(pose),
            radius_m=sensor.mic_radius_m,
            frequency_hz=float(np.mean(sensor.call.band_hz)),
            speed_of_sound_m_s=self.c,
        )

    def mic_axis(self, pose: Pose) -> np.ndarray:
        """The direction (3,) the microphones face, world frame: the sensor's axis."""
        return pose.rotation[:, 0]

    def _planned(self, prep: _Prepared) -> _Prepared:
        """`prep` with the render of its echoes in motion planned (time-scaled calls at
        fractional delays: :func:`~acousim.synth.doppler.plan_doppler`); a static
        or already planned one as it is."""
        if prep.rate is None or prep.plan is not None:
            return prep
        sensor = self.scene.sensor
        plan = plan_doppler(
            prep.echoes,
            prep.rate,
            sensor.call,
            sensor.sample_rate_hz,
            prep.n_samples,
            options=self.options,
            response=self.response,
            cache=self.doppler_cache,
        )
        return dataclasses.replace(prep, plan=plan)

    def lidar_scan(
        self, pose: Pose, index: int = 0, motion=None, *, lidar: Lidar | None = None, n: int = 0
    ) -> P.PointCloud | None:
        """The scene's LiDAR (``sensor.lidar``; or `lidar`, a rig's LiDAR `n` mounted
        on the sensor) scanning from `pose` (None: the scene has none); `motion`: the
        sensor's trajectory during the scan (None: still); range noise seeded by
        (scene seed, `index`, and `n` for a rig's LiDARs after the first)."""
        lidar = self.scene.sensor.lidar if lidar is None else lidar
        if lidar is None:
            return None

        tracer = self.tracer.tracer_at(pose.time_s)
        entropy = [self.scene.simulation.seed, index, 1] + ([n] if n else [])
        seed = int(np.random.SeedSequence(entropy).generate_state(1)[0])
        return scan(tracer.world, tracer.caster, lidar, pose, motion=motion, seed=seed)

    def moving_paths(self, pose: Pose):
        """The paths of a measurement in motion starting at `pose`:
        :class:`~acousim.trace.motion.following.MovingPaths`, and for the ground truth the
        positions (N, 3) at the start of the emission, the kind names and the velocities
        (N, 3) of the reflecting points
        (:func:`acousim.trace.motion.measurement.paths_in_motion`)."""
        m = self._in_motion(pose)
        return m.moving, m.position_m, m.kinds, m.velocity_m_s

    def _in_motion(self, pose: Pose, max_path_m=None, min_path_m=None) -> InMotion:
        array, direct = self._traced_array, self.scene.sensor.direct_path
        return paths_in_motion(
            self.tracer,
            pose,
            array,
            traced=self.tracer.traced(pose, array, max_path_m, min_path_m, direct),
            points=self.scene.points,
            speed_of_sound_m_s=self.c,
            reach_m=2 * self.scene.simulation.max_range_m,
        )

    def _record(self, prep: _Prepared, index: int, seed: int | None, joined=()) -> P.Recording:
        """Render the prepared echoes with the scene's noise (seeded per pose index)
        into a Recording carrying its metadata and ground truth; `joined`: other
        calls' echoes and Doppler factors rendered with them (:meth:`simulate_pose`)."""
        scene = self.scene
        sensor = scene.sensor
        own, meta = prep.echoes, prep.metadata
        if joined:
            if prep.rate is None or any(r is None for _, r in joined):
                raise ValueError("joined echoes are rendered with a measurement in motion only")
            prep = dataclasses.replace(
                prep,
                echoes=Echoes.concatenate([own, *(e for e, _ in joined)]),
                rate=np.concatenate([prep.rate, *(r for _, r in joined)], axis=1),
                plan=None,
            )
            meta = {**meta, "n_paths": own.n_paths}
        prep = self._planned(prep)
        base = scene.simulation.seed if seed is None else seed
        if seed is not None and "simulation" in meta:  # the seed given for this recording
            meta = {**meta, "simulation": {**meta["simulation"], "seed": base}}
        noise_seed = int(np.random.SeedSequence([base, index]).generate_state(1)[0])
        rec = simulate(
            prep.echoes,
            Capture(sensor.array, sensor.call, sensor.sample_rate_hz, prep.n_samples, self.c),
            noise=Noise(scene.simulation.snr_db, noise_seed, "echoes"),
            options=self.options,
            response=self.response,
            metadata=meta,
            doppler=prep.plan,
            noise_echoes=own,
        )
        return rec.with_truth(prep.truth, prep.lidar)  # its samples not checked again

    def _one(self, i: int, progress: Callable[[int, int], None] | None) -> P.Recording:
        """:meth:`run` of pose `i` alone, in this thread (what its threads would do)."""
        interrupt.check()
        rec = self._made(i)
        if progress:
            progress(1, 1)
        return rec

    def _made(self, i: int) -> P.Recording:
        """The recording of the scene's pose `i`, its stages one after the other here
        (its time kept as the poses' pace: :meth:`_shared`)."""
        t = time.perf_counter()
        with self._naming_the_pose(i):
            prep = self._prepare(self.scene.sensor.poses[i], i, None, SCENE_MOTION)
        rec = self._record(self._planned(prep), i, None)
        self._pace_s = time.perf_counter() - t
        return rec

    def run(
        self,
        poses: Iterable[int] | None = None,
        progress: Callable[[int, int], None] | None = None,
        *,
        processes: int | None = None,
    ) -> list[P.Recording]:
        """Recordings for the scene's poses (all, or the given indices), in order.

        `processes`: None (the default) makes them in two processes when it can (this
        one and a forked worker, each taking the next pose not yet taken: the two
        cores' whole work, :meth:`_shared`): on Linux with two CPUs or more, for a
        scene whose meshes stand still, from a process that may have children;
        else, or with 1, in this process, the next poses prepared in threads while
        one renders (:meth:`_pipelined`).  The same recordings, bit for bit, either
        way: a pose's work depends on the pose alone."""
        all_poses = self.scene.sensor.poses
        idx = list(range(len(all_poses))) if poses is None else list(poses)
        for i in idx:
            if not 0 <= i < len(all_poses):
                raise InputError(
                    f"pose index {i} out of range: the scene has {len(all_poses)} pose(s)"
                )
        check_processes(processes)
        self.scene.check_memory(len(idx))  # every recording is kept: refuse before starting
        if len(idx) == 1:  # nothing to overlap: no threads started (a scene's one pose)
            return [self._one(idx[0], progress)]
        if processes != 1 and self._can_share():
            return self._shared(idx, progress, always=processes == 2)
        return self._pipelined(idx, progress)

    def _can_share(self) -> bool:
        """Whether :meth:`run` may fork a worker: one world, built once (moving meshes
        rebuild theirs, with Embree's threads, which a forked child lacks), and a
        process and machine that allow it (:func:`acousim.core.forked.can_fork`)."""
        from acousim.core.forked import can_fork

        return isinstance(self.tracer, Tracer) and not self.moving_meshes and can_fork()

    def _shared(
        self, idx: list[int], progress: Callable[[int, int], None] | None, *, always: bool
    ) -> list[P.Recording]:
        """:meth:`run` of the poses `idx` in this process and a forked one
        (:func:`acousim.core.forked.shared_by_two_processes`):

        1. the poses' pace: the time of the last pose made in one thread here (a
           simulator's first pose is made here first, and timed; its time counts
           the kernels' first loading, so a first run may fork where later ones
           would not); if the poses would take less than
           :data:`acousim.core.forked.SHARED_FROM_S` at
           that pace (unless `always`), they are made here (:meth:`_pipelined`): a
           fork costs more than it saves on a short run;
        2. the world's acceleration structure is built here, if not yet (the child
           only queries it: :meth:`~acousim.trace.world.embree.RayCaster.commit`);
        3. the worker is forked: it has this simulator as it is, its caches and
           compiled kernels with it, nothing to start;
        4. each process takes the next pose nobody has taken and makes its
           recording down the stages in one thread (the caster's queries split over
           its own threads); the worker's recordings come back through a socket;
        5. Ctrl-C is honoured here between poses; the worker ignores it and ends
           with the run.

        Both cores stay busy (the threads of :meth:`_pipelined` wait on each other's
        interpreter lock): docs/physics.md, "Where a measurement's time goes"."""
        from acousim.core.forked import shared_if_worth_it

        caster = self.tracer.caster
        return shared_if_worth_it(
            lambda k: self._made(idx[k]),
            len(idx),
            alone=lambda ks, later: self._pipelined([idx[k] for k in ks], later),
            pace_s=self._pace_s,
            always=always,
            before_fork=None if caster is None else caster.commit,
            progress=progress,
        )

    def _pipelined(
        self, idx: list[int], progress: Callable[[int, int], None] | None
    ) -> list[P.Recording]:
        """:meth:`run` of the poses `idx` in threads: the next poses prepared (trace,
        echoes, in motion the arrival times) while the current one is rendered
        (Embree, numpy's large operations, the FFTs and the compiled impulse sums
        release the GIL), :data:`PREPARE_AHEAD` of them queued so that a pose quicker
        to prepare than to render leaves the preparing thread no time idle; in
        motion the preparing thread also plans the render, unless the rendering
        thread is already waiting for it (then that one plans: the two threads share
        the work whichever is the slower; the same bytes either way).  The pose
        after those is traced meanwhile in a third thread (the tracer's cache hands
        its paths to the preparing one), unless meshes move (their tracer keeps one
        instant)."""
        import threading
        from collections import deque
        from concurrent.futures import Future, ThreadPoolExecutor

        all_poses = self.scene.sensor.poses
        waiting = threading.Event()
        traced: dict[int, Future] = {}

        def prepare(i: int) -> _Prepared:
            with self._naming_the_pose(i):
                if i in traced:
                    traced.pop(i).result()  # traced ahead (cached), or its error raised here
                prep = self._prepare(all_poses[i], i, None, SCENE_MOTION)
            return prep if waiting.is_set() else self._planned(prep)

        out: list[P.Recording] = []
        with ThreadPoolExecutor(1) as pool, ThreadPoolExecutor(1) as tracing:

            def submit(k: int) -> None:  # pose k prepared, the one after it traced
                if k < len(idx):
                    ahead.append(pool.submit(prepare, idx[k]))
                if k + 1 < len(idx) and not self.moving_meshes:
                    j = idx[k + 1]
                    traced[j] = tracing.submit(self.tracer.trace, all_poses[j], self._traced_array)

            ahead: deque[Future] = deque()
            for k in range(PREPARE_AHEAD):
                submit(k)
            try:
                for k, i in enumerate(idx):
                    interrupt.check()  # Ctrl-C (when the command line records it): stop here
                    waiting.set()
                    prep = ahead.popleft().result()
                    waiting.clear()
                    submit(k + PREPARE_AHEAD)
                    out.append(self._record(prep, i, None))
                    if progress:
                        progress(k + 1, len(idx))
            finally:
                for job in ahead:  # an error or Ctrl-C: the poses not begun not prepared
                    job.cancel()
        return out


#: the names of the path kinds by code (:class:`~acousim.trace.paths.PathKind`)
_KIND_NAMES = np.array([k.name for k in PathKind])


def check_processes(processes: int | None) -> None:
    """A run's `processes` (None: automatic, 1 or 2), or an InputError naming it."""
    if processes not in (None, 1, 2):
        raise InputError("must be None (automatic), 1 or 2", key="processes", value=processes)


def _scattered(values: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """`values` (R, ...) of the rows `rows` (R,) of n, the other rows NaN: (n, ...)."""
    out = np.full((n, *values.shape[1:]), np.nan)
    out[rows] = values
    return out


def _motion(pose: Pose, motion, rate: np.ndarray) -> dict:
    """A recording in motion's metadata ``motion``: the pose at the start of the
    emission, the velocity (m/s) and angular velocity (deg/s) there (a frozen pose:
    zero) and the range of the Doppler factors `rate` (M, N)."""
    t = pose.time_s
    velocity = np.zeros(3) if motion is None else motion.velocity(t)
    turn = np.zeros(3) if motion is None else motion.angular_velocity(t)
    return {
        "emission_pose": pose.to_dict(),
        "velocity_m_s": velocity.tolist(),
        "angular_velocity_deg_s": np.rad2deg(turn).tolist(),
        "doppler_min": float(rate.min()) if rate.size else 1.0,
        "doppler_max": float(rate.max()) if rate.size else 1.0,
    }


def _metadata(scene: Scene, pose: Pose, index: int) -> dict:
    """A simulated recording's metadata: where it came from and the pose."""
    return {
        "scene": scene.name,
        "scene_file": str(scene.source) if scene.source else None,
        "scene_sha256": scene.file_sha256,
        "max_range_m": float(scene.simulation.max_range_m),
        "acousim_version": package_version(),
        "pose": pose.to_dict(),
        "pose_index": index,
        "quality": scene.simulation.quality,
        "simulation": simulation_settings(scene.simulation),
    }


#: declared settings of ``[simulation]`` a recording's metadata leaves out of its
#: ``simulation``: the memory guard (it changes no sample and comes from the
#: environment) and the quality (its own key)
_NOT_RECORDED = ("max_memory_gb", "quality")


def simulation_settings(sim: Simulation) -> dict:
    """The ``[simulation]`` settings a recording was made with, as the scene file names
    them (the quality preset applied; ``diffraction`` as its table): every declared
    setting but those of :data:`_NOT_RECORDED`."""
    out = {k: getattr(sim, k) for k in settings_of(Simulation) if k not in _NOT_RECORDED}
    out["diffraction"] = {k: getattr(sim.diffraction, k) for k in settings_of(Diffraction)}
    return out
