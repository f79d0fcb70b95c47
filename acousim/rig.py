"""Simulating a rig: every firing of every sonar, and the crosstalk between them.

``RigSimulator(scene).run()`` gives one recording per firing (:class:`RigRun`, in
time order).  A measurement of sonar k records from its own emission for its window
(its own call's maximum range).  The world is prepared once (one tracer shared by
every pair of sonars, which shoots a call's rays once for every sonar that traces
it: :mod:`acousim.trace.rays.emission`); each pair (emitter j, microphones of k) is a
:class:`~acousim.simulator.Simulator` whose array holds j's emitter and k's
microphones in j's frame, so a call of j heard by k goes down the same stages as a
sonar hearing itself (specular, diffuse, diffraction, the body's motion during the
emission and the reception: a bistatic path from emitter j to the microphones of
k), with j's call, emitter and air response, k's sample rate and microphone
directivity.

Crosstalk (``Rig.crosstalk``): every firing f of any sonar (another sonar's, or k's
own earlier one) that can reach k's window, emitted at t_f with k recording from
t_k, is traced from its own emission and its echoes are delayed by t_f - t_k in k's
recording (a call emitted before t_k contributes its part after t_k).  The ground
truth of each recording names the emitter of every path (``truth.emitter``) and its
metadata lists the firings heard (``metadata["crosstalk"]``).  ``Rig.earlier_calls``
false leaves out the calls emitted before t_k (an approximation: cheaper).

A scene without a rig is a rig of one: its recordings are those of
:class:`~acousim.simulator.Simulator` (byte for byte).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable

import numpy as np

import processing as P
from acousim.core.echoes import Echoes
from acousim.scene.model import Scene
from acousim.scene.pose import Pose
from acousim.scene.rig import Measurement, Rig
from acousim.simulator import Heard, Simulator, check_processes
from acousim.synth.doppler import plan_doppler
from acousim.synth.options import Capture
from acousim.synth.signal_model import simulate
from acousim.trace.lidar import scan
from acousim.trace.seen import apparent
from acousim.trace.tracer import Tracer
from processing.base import interrupt
from processing.base.errors import InputError

__all__ = ["RigSimulator", "RigRun", "LidarScan", "REACH_MARGIN_M"]

#: a crosstalk call emitted during a window is traced this much beyond the longest
#: path it can take within it (m; see :meth:`RigSimulator._reach`)
REACH_MARGIN_M = 0.1

#: firings prepared ahead of the one rendering (:meth:`RigSimulator.run`)
AHEAD = 2


@dataclasses.dataclass(frozen=True)
class LidarScan:
    """One LiDAR scan of a rig: the LiDAR (index into ``Rig.lidars``, its name), the
    body's pose index it starts at and the point cloud (LiDAR frame)."""

    lidar: int
    name: str
    pose_index: int
    cloud: P.PointCloud


@dataclasses.dataclass(frozen=True)
class RigRun:
    """A rig's simulation: a recording per firing (time order; ``metadata["sensor"]``
    names the sonar) and the LiDARs' scans."""

    recordings: tuple[P.Recording, ...]
    measurements: tuple[Measurement, ...]
    scans: tuple[LidarScan, ...] = ()

    def of(self, name: str) -> list[P.Recording]:
        """The recordings of the sonar called `name` (none: it never fired); an
        InputError listing the rig's sonars when the rig has none of that name."""
        listed = [
            n
            for r in self.recordings
            for n in (*r.metadata.get("rig", ()), r.metadata.get("sensor"))
        ]
        names = [n for n in dict.fromkeys(listed) if n is not None]
        if name not in names:
            raise InputError(
                f"is not a sonar of the rig ({', '.join(map(str, names)) or 'no recordings'})",
                key="RigRun.of.name",
                value=name,
            )
        return [r for r in self.recordings if r.metadata.get("sensor") == name]


@dataclasses.dataclass(frozen=True, eq=False)
class _Heard:
    """A firing's paths heard in another's recording: the pair that hears them, the
    echoes (delays from the recording's start), their Doppler factors (M, N; None:
    static) and their ground truth."""

    pair: Simulator
    echoes: Echoes
    rate: np.ndarray | None
    truth: P.GroundTruth

    @property
    def echo(self) -> np.ndarray:
        """(N,) which paths are echoes (not the direct path)."""
        return self.echoes.order > 0


@dataclasses.dataclass(frozen=True, eq=False)
class _Firing:
    """A firing's recording but its render (:meth:`RigSimulator._prepare`): the
    measurement, its sonar's own simulator, the calls heard (each with the firing
    that emitted it) and whether each renders in the own pass, the own call
    prepared and the rig's other LiDARs' scans."""

    measurement: Measurement
    own: Simulator
    parts: tuple[tuple[Measurement, _Heard], ...]
    joins: tuple[bool, ...]
    prepared: object  # acousim.simulator._Prepared
    other_lidars: tuple


class _Pair(Simulator):
    """The emitter of one sonar heard by the microphones of another (j's frame), whose
    ports face `axis` (k's axis in j's frame, (3,))."""

    def __init__(self, scene: Scene, axis: np.ndarray, *, tracer) -> None:
        super().__init__(scene, tracer=tracer)
        self.axis = axis

    def mic_axis(self, pose: Pose) -> np.ndarray:
        return pose.rotation @ self.axis


class RigSimulator:
    """Simulates a scene's rig (:attr:`Scene.rig`); the world prepared once."""

    def __init__(self, scene: Scene, threads: int = 2) -> None:
        if scene.rig is not None and not isinstance(scene.rig, Rig):
            raise InputError("must be None or an acousim.scene.rig.Rig", key="Scene.rig")
        self.scene = scene
        self.rig: Rig | None = scene.rig
        self.single = Simulator(scene, threads) if self.rig is None else None
        if self.rig is None:
            return
        self.measurements = tuple(self.rig.measurements())
        first = self._pair_scene(0, 0)
        self.tracer = Simulator(first, threads).tracer
        if self.rig.crosstalk and isinstance(self.tracer, Tracer):
            # a call is traced for each sonar that hears it: its rays shot once
            self.tracer.share_emissions()
        self._pairs: dict[tuple[int, int], Simulator] = {}

    def _pair_scene(self, j: int, k: int) -> Scene:
        """The scene of sonar j's call heard by sonar k (j's poses and motion)."""
        rig = self.rig
        emitting, hearing = rig.sonars[j].sensor, rig.sonars[k].sensor
        poses = tuple(m.pose for m in self.measurements if m.sonar == j) or (
            rig.sonars[j].mount.place(rig.poses[0]),
        )
        try:
            sensor = dataclasses.replace(
                emitting,
                array=rig.pair_array(j, k),
                sample_rate_hz=hearing.sample_rate_hz,
                mic_radius_m=hearing.mic_radius_m,
                poses=poses,
                rate_hz=None,
                motion=rig.sonar_motion(j),
                # another sonar's call reaching k straight is crosstalk (``Rig.crosstalk``),
                # not k's own emitter-to-microphone leakage (``direct_path``)
                direct_path=True if j != k else emitting.direct_path,
                # a sonar's own recordings carry the rig's first LiDAR's scan
                lidar=rig.lidar_on(k) if j == k else None,
            )
        except InputError as exc:
            raise InputError(
                f"sonar {rig.sonars[k].name!r} cannot hear sonar {rig.sonars[j].name!r}: "
                f"{exc.reason}",
                key="rig.sonars",
            ) from None
        return dataclasses.replace(self.scene, sensor=sensor, rig=None)

    def pair(self, j: int, k: int) -> Simulator:
        """The simulator of sonar j's call heard by sonar k (made once)."""
        if (j, k) not in self._pairs:
            scene = self._pair_scene(j, k)
            if j == k:
                self._pairs[j, k] = Simulator(scene, tracer=self.tracer)
            else:
                self._pairs[j, k] = _Pair(scene, self.rig.pair_axis(j, k), tracer=self.tracer)
        return self._pairs[j, k]

    def run(
        self,
        indices: Iterable[int] | None = None,
        progress: Callable[[int, int], None] | None = None,
        *,
        processes: int | None = None,
    ) -> RigRun:
        """The recordings of the rig's firings (all, or the given indices into
        :attr:`measurements`) and the LiDARs' scans.  `processes`: as
        :meth:`Simulator.run`'s (None: two processes, this one and a forked worker,
        where the scene allows; 1: this one, the next firings prepared in threads);
        the same recordings either way."""
        if self.rig is None:
            recs = self.single.run(indices, progress, processes=processes)
            return RigRun(tuple(recs), ())
        idx = list(range(len(self.measurements))) if indices is None else list(indices)
        for i in idx:
            if not 0 <= i < len(self.measurements):
                raise InputError(
                    f"measurement index {i} out of range: the rig fires "
                    f"{len(self.measurements)} time(s)"
                )
        check_processes(processes)
        if len(idx) == 1:  # nothing to overlap: no thread started
            out = [self.simulate(idx[0])]
            if progress:
                progress(1, 1)
        elif processes != 1 and self.pair(0, 0)._can_share():
            out = self._shared(idx, progress, always=processes == 2)
        else:
            out = self._threaded(idx, progress)
        done = tuple(self.measurements[i] for i in idx)
        times = [m.time_s for m in done]
        scans = self.lidar_scans(min(times), max(times)) if done else ()
        return RigRun(tuple(out), done, scans)

    def _shared(self, idx: list[int], progress, *, always: bool) -> list[P.Recording]:
        """:meth:`run`'s firings `idx` made in this process and a forked one, each
        taking the next firing not yet taken, when worth a fork
        (:func:`acousim.core.forked.shared_if_worth_it`: the first firing made here
        and timed; the world built here before the fork; a call heard by sonars in
        both processes is traced in each), else here in threads (:meth:`_threaded`)."""
        from acousim.core.forked import shared_if_worth_it

        caster = self.tracer.caster
        return shared_if_worth_it(
            lambda k: self.simulate(idx[k]),
            len(idx),
            alone=lambda ks, later: self._threaded([idx[k] for k in ks], later),
            always=always,
            before_fork=None if caster is None else caster.commit,
            progress=progress,
        )

    def _threaded(self, idx: list[int], progress) -> list[P.Recording]:
        """:meth:`run`'s firings `idx` in this process: the next :data:`AHEAD`
        firings prepared in two threads (their own calls and the calls they hear:
        traces, kinematics, scans; Embree and the compiled kernels release the GIL)
        while this one renders: the same bytes as one firing after the other (every
        trace as it would be alone)."""
        from concurrent.futures import ThreadPoolExecutor

        out = []
        pool = ThreadPoolExecutor(2)
        try:
            ahead = [self._prepare(i, pool=pool) for i in idx[:AHEAD]]
            for n in range(len(idx)):
                interrupt.check()  # Ctrl-C (when the command line records it)
                firing = ahead.pop(0)()
                if n + AHEAD < len(idx):
                    ahead.append(self._prepare(idx[n + AHEAD], pool=pool))
                out.append(self._record(firing))
                if progress:
                    progress(n + 1, len(idx))
        finally:  # stopped (Ctrl-C, an error): the work not started is dropped
            pool.shutdown(wait=True, cancel_futures=True)
        return out

    def simulate(self, i: int, *, n_samples: int | None = None) -> P.Recording:
        """The recording of measurement `i` (`n_samples` long; None: its scene's
        length): sonar k's own call from its emission, and (crosstalk) every other
        firing that reaches its window.  In motion, the
        crosstalk of a sonar with k's call, response and render options is rendered
        in the same pass as k's own echoes (:meth:`Simulator.simulate_pose`
        ``joined``); any other separately, and added."""
        return self._record(self._prepare(i, n_samples)())

    def _prepare(self, i: int, n_samples: int | None = None, pool=None) -> Callable[[], _Firing]:
        """Everything of measurement `i`'s recording but its render (the traces, the
        kinematics, the ground truth, the LiDARs' scans), as a call that returns it:
        with a `pool` (a ``concurrent.futures`` executor) its parts are worked out
        there meanwhile (:meth:`run`: the next firing prepared while this one
        renders), without one here and now."""
        m = self.measurements[i]
        k = m.sonar
        own = self.pair(k, k)
        motion = self.rig.sonar_motion(k)
        n = own.scene.n_samples() if n_samples is None else int(n_samples)
        reaching = self._reaching(m, n) if self.rig.crosstalk else []
        submit = pool.submit if pool is not None else _Done.of
        own_part = submit(self._own, m, own, motion, n)
        heard = [(f, submit(self._heard_from, f, m, n)) for f in reaching]

        def firing() -> _Firing:
            prep, others = own_part.result()
            parts = [(f, part.result()) for f, part in heard]
            parts = [(f, part) for f, part in parts if part is not None]
            moving = own.in_motion(motion)
            joins = tuple(moving and self._joins(own, p) for _, p in parts)
            return _Firing(m, own, tuple(parts), joins, prep, others)

        return firing

    def _own(self, m: Measurement, own: Simulator, motion, n_samples: int):
        """Measurement `m`'s own call prepared (:meth:`Simulator._prepare`) and the
        rig's other LiDARs' scans started at this firing."""
        k = m.sonar
        with own._naming_the_pose(m.index):
            prep = own._prepare(m.pose, m.index, n_samples, motion)
        others = tuple(
            own.lidar_scan(m.pose, m.index, motion, lidar=self.rig.lidar_on(k, n), n=n)
            for n in range(1, len(self.rig.lidars))
        )
        return prep, others

    def _record(self, fp: _Firing) -> P.Recording:
        """The recording of a prepared firing: rendered, its crosstalk added."""
        m, own, parts, joins = fp.measurement, fp.own, fp.parts, fp.joins
        # a call's echoes join k's; its direct path, far stronger, is rendered apart
        # (the renderer's sets are compressed per group, direct path and echoes, to a
        # tolerance of the group's energy: k's own direct path would set it)
        joined = tuple(
            (p.echoes.select(p.echo), p.rate[:, p.echo]) for (_, p), j in zip(parts, joins) if j
        )
        with own._naming_the_pose(m.index):
            rec = own._record(fp.prepared, m.index, None, joined)
        names = [self.rig.sonars[m.sonar].name] * len(rec.truth)
        truths, heard_from, samples = [rec.truth], [], rec.samples
        for (f, part), j in zip(parts, joins):
            alone = ~part.echo if j else np.ones(part.echo.size, bool)
            if alone.any():
                samples = samples + self._rendered(part, samples.shape[1], alone)
            truths.append(part.truth)
            names += [self.rig.sonars[f.sonar].name] * len(part.truth)
            heard_from.append(
                {
                    "sensor": self.rig.sonars[f.sonar].name,
                    "measurement": f.index,
                    "emission_time_s": f.time_s,
                    "delay_s": f.time_s - m.time_s,
                    "n_paths": len(part.truth),
                }
            )
        meta = self._metadata(rec.metadata, m, heard_from)
        truth = _joined(truths, names)
        return dataclasses.replace(
            rec, samples=samples, truth=truth, metadata=meta, other_lidars=fp.other_lidars
        )

    def _metadata(self, own: dict, m: Measurement, heard_from: list[dict]) -> dict:
        """A firing's recording's metadata: its sonar's (`own`), the sonar's name and
        mount, the emission time, the body's pose, the rig's sonars and the calls
        heard (`heard_from`)."""
        sonar = self.rig.sonars[m.sonar]
        meta = {
            **own,
            "sensor": sonar.name,
            "mount": sonar.mount.to_dict(),
            "emission_time_s": m.time_s,
            "body_pose": self.rig.body_pose(m.time_s).to_dict(),
            "rig": [s.name for s in self.rig.sonars],
            "crosstalk": heard_from,
        }
        if self.rig.crosstalk and not self.rig.earlier_calls:  # the approximation, named
            meta["earlier_calls"] = False
        return meta

    def _reaching(self, m: Measurement, n_samples: int) -> list[Measurement]:
        """The other firings whose call or echoes may reach measurement `m`'s window
        of `n_samples`: emitted before its end and no longer ago than the longest path
        (twice the range) and the call (``Rig.earlier_calls`` false: not before `m`'s
        emission)."""
        window = n_samples / self.rig.sonars[m.sonar].sensor.sample_rate_hz
        c = self.scene.environment.speed_of_sound_m_s
        longest = 2 * self.scene.simulation.max_range_m / c
        out = []
        for f in self.measurements:
            if f.index == m.index:
                continue
            call = self.rig.sonars[f.sonar].sensor.call.duration_s
            if not self.rig.earlier_calls and f.time_s < m.time_s:
                continue
            if m.time_s - (longest + call) < f.time_s < m.time_s + window:
                out.append(f)
        return out

    def _crosstalk(self, f: Measurement, m: Measurement, n_samples: int):
        """Firing `f` heard in measurement `m`'s recording of `n_samples` samples: the
        signal (M, T) rendered alone and the ground truth of the paths that reach it
        (None: none)."""
        part = self._heard_from(f, m, n_samples)
        return None if part is None else (self._rendered(part, n_samples), part.truth)

    def _heard_from(self, f: Measurement, m: Measurement, n_samples: int) -> _Heard | None:
        """Firing `f`'s paths that reach measurement `m`'s recording of `n_samples`
        samples (None: none)."""
        k, j = m.sonar, f.sonar
        pair = self.pair(j, k)
        fs = self.rig.sonars[k].sensor.sample_rate_hz
        call = self.rig.sonars[j].sensor.call
        lead = m.time_s - f.time_s  # how long before k's emission j fired (s)
        n_from_f = int(np.ceil((lead + n_samples / fs) * fs))
        heard = pair.heard(
            f.pose,
            self.rig.sonar_motion(j),
            n_from_f,
            max_path_m=self._reach(f, n_from_f / fs),
            min_path_m=self._short_of(f, lead - call.duration_s),
        )
        echoes = heard.echoes
        delay = echoes.delay_s - lead
        keep = np.any(
            (delay < n_samples / fs) & (delay + call.duration_s > 0) & (echoes.gain != 0), axis=0
        )
        if not keep.any():
            return None
        echoes = dataclasses.replace(echoes.select(keep), delay_s=delay[:, keep])
        rate = None if heard.rate is None else heard.rate[:, keep]
        rows = np.flatnonzero(keep) if heard.rows is None else heard.rows[keep]
        seen = self._seen_by(heard.seen, rows, j, k, lead, m.pose)
        return _Heard(pair, echoes, rate, _truth(heard, rows, m.pose, seen))

    def _seen_by(self, seen: dict, rows: np.ndarray, j: int, k: int, lead: float, pose: Pose):
        """What sonar k sees of the paths `rows` of a call of sonar j emitted `lead`
        seconds before k's (``seen``: the pair's ground truth fields, in j's frame and
        from j's emission): the delays from k's emission, the arrival directions in
        k's frame (both sonars ride one body: j's frame turned by the mounts), the
        apparent positions where k's image puts them (k's array centre plus the
        direction times ``c delay / 2``, through k's `pose` in the world) and the
        chain fields as they are."""
        out = {name: v[rows] for name, v in seen.items() if isinstance(v, np.ndarray)}
        out["object_names"] = seen["object_names"]
        sonars = self.rig.sonars
        turn = sonars[k].mount.rotation.T @ sonars[j].mount.rotation  # j's frame -> k's
        delay = out["delay_s"] - lead
        arrival = out["arrival_sensor"] @ turn.T
        centre = sonars[k].sensor.array.positions_m.mean(axis=0)
        app = apparent(delay, arrival, centre, self.scene.environment.speed_of_sound_m_s)
        out.update(
            delay_s=delay,
            arrival_sensor=arrival,
            apparent_position_sensor_m=app,
            apparent_position_world_m=pose.to_world(app),
        )
        return out

    @staticmethod
    def _joins(own: Simulator, part: _Heard) -> bool:
        """Whether `part` renders as `own`'s echoes do (the same call, sample rate,
        response and options; in motion)."""
        a, b = own.scene.sensor, part.pair.scene.sensor
        return (
            part.rate is not None
            and a.call == b.call
            and a.sample_rate_hz == b.sample_rate_hz
            and own.response == part.pair.response
            and own.options == part.pair.options
        )

    @staticmethod
    def _rendered(part: _Heard, n_samples: int, paths: np.ndarray | None = None) -> np.ndarray:
        """`part`'s signal (M, `n_samples`) rendered alone, noise-free (its `paths`,
        a mask (N,); None: all)."""
        pair = part.pair
        sensor = pair.scene.sensor
        fs, call = sensor.sample_rate_hz, sensor.call
        echoes, rate = part.echoes, part.rate
        if paths is not None:
            echoes, rate = echoes.select(paths), None if rate is None else rate[:, paths]
        # rendered into a window that starts `pre` samples early (a call emitted before
        # k's emission contributes its tail), the samples before k's emission dropped
        pre = int(np.ceil(call.duration_s * fs)) + 1
        echoes = dataclasses.replace(echoes, delay_s=echoes.delay_s + pre / fs)
        if rate is not None:  # planned with the pair's templates, kept from call to call
            rate = plan_doppler(
                echoes,
                rate,
                call,
                fs,
                n_samples + pre,
                options=pair.options,
                response=pair.response,
                cache=pair.doppler_cache,
            )
        rec = simulate(
            echoes,
            Capture(pair.array, call, fs, n_samples + pre, pair.c),
            options=pair.options,
            response=pair.response,
            doppler=rate,
        )
        return rec.samples[:, pre:]

    def _speed(self, f: Measurement) -> float | None:
        """How fast a path's length may change during firing `f`'s measurement (m/s):
        twice what the microphones can move (the body's speed, its turn carrying
        the farthest mount); None when reflectors move (no bound)."""
        if any(p.moving for p in self.scene.points) or any(m.moving for m in self.scene.meshes):
            return None
        if self.rig.motion is None:
            return 0.0
        lever = max(np.linalg.norm(s.mount.position_m) for s in self.rig.sonars) + 0.5
        v = np.linalg.norm(self.rig.motion.velocity(f.time_s))
        w = np.linalg.norm(self.rig.motion.angular_velocity(f.time_s))
        return float(2 * (v + w * lever))

    def _short_of(self, f: Measurement, gone_s: float) -> float | None:
        """How long a path of firing `f` must be (m) for its call to end later than
        `gone_s` after the emission (m's window starts then, less the call): c less
        :meth:`_speed` times that, less :data:`REACH_MARGIN_M`; shorter paths are
        heard wholly before the window (and left out before the kinematics).  None:
        no bound (the call is emitted during the window, or reflectors move)."""
        speed = self._speed(f)
        if speed is None or gone_s <= 0:
            return None
        c = self.scene.environment.speed_of_sound_m_s
        short = (c - speed) * gone_s - REACH_MARGIN_M
        return short if short > 0 else None

    def _reach(self, f: Measurement, window_s: float) -> float | None:
        """How long a path of firing `f` may be and still reach a window ending
        `window_s` after its emission (m): c times that, plus what the microphones
        can move meanwhile (twice the body's speed there, its turn carrying the
        farthest mount) and :data:`REACH_MARGIN_M`; None (every path the scene
        traces) when that is not shorter, or when reflectors move."""
        longest = 2 * self.scene.simulation.max_range_m
        speed = self._speed(f)
        if speed is None:
            return None
        c = self.scene.environment.speed_of_sound_m_s
        reach = (c + speed) * window_s + REACH_MARGIN_M
        return reach if reach < longest else None

    def lidar_scans(self, start_s: float = -np.inf, end_s: float = np.inf) -> tuple[LidarScan, ...]:
        """Every LiDAR of the rig scanning from each of the body's poses (those from
        `start_s` to `end_s`, s; a body of one pose: that one), in the LiDAR's frame
        (``to_sensor``: LiDAR -> body).  Each sonar's recordings carry the first
        LiDAR's scan started at their firing, in the sonar's frame."""

        out = []
        seed = self.scene.simulation.seed
        several = len(self.rig.poses) > 1
        for n, lidar in enumerate(self.rig.lidars):
            for i, body in enumerate(self.rig.poses):
                if several and not start_s - 1e-9 <= body.time_s <= end_s + 1e-9:
                    continue
                tracer = self.tracer.tracer_at(body.time_s)
                s = int(np.random.SeedSequence([seed, i, 2 + n]).generate_state(1)[0])
                cloud = scan(
                    tracer.world, tracer.caster, lidar, body, motion=self.rig.motion, seed=s
                )
                out.append(LidarScan(n, lidar.name, i, cloud))
        return tuple(out)


class _Done:
    """A value already computed, as a ``Future`` of it."""

    def __init__(self, value) -> None:
        self.value = value

    def result(self):
        return self.value

    @classmethod
    def of(cls, fn, *args) -> _Done:
        return cls(fn(*args))


def _truth(heard: Heard, rows: np.ndarray, pose: Pose, seen: dict) -> P.GroundTruth:
    """The ground truth of the paths `rows` of `heard`, in the frame of the sonar at
    `pose` (the hearing one), with what it sees of them (`seen`: the GroundTruth
    fields of those rows)."""
    pos = heard.position_m[rows]
    return P.GroundTruth(
        position_world_m=pos,
        position_sensor_m=pose.to_sensor(pos),
        amplitude=heard.level[rows],
        order=heard.order[rows],
        kind=np.array(heard.kinds, dtype=str)[rows],
        velocity_world_m_s=None if heard.velocity_m_s is None else heard.velocity_m_s[rows],
        **seen,
    )


#: the ground truth's per-path fields after the first five (None in some truths)
_OPTIONAL = (
    "velocity_world_m_s",
    "delay_s",
    "arrival_sensor",
    "apparent_position_sensor_m",
    "apparent_position_world_m",
    "first_point_m",
    "last_point_m",
    "object_index",
)


def _joined(truths: list[P.GroundTruth], names: list[str]) -> P.GroundTruth:
    """Ground truths concatenated, each path's emitter named (a field missing from
    one of them: None; the objects are the scene's, the same in each)."""

    def joined(field):
        parts = [getattr(t, field) for t in truths]
        return None if any(p is None for p in parts) else np.concatenate(parts)

    return P.GroundTruth(
        position_world_m=joined("position_world_m"),
        position_sensor_m=joined("position_sensor_m"),
        amplitude=joined("amplitude"),
        order=joined("order"),
        kind=joined("kind"),
        emitter=np.array(names, dtype=str),
        object_names=truths[0].object_names,
        **{field: joined(field) for field in _OPTIONAL},
    )
