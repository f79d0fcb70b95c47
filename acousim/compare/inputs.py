"""What a comparison is given (:mod:`acousim.compare.comparison`): real recordings read from the
files or names the command line takes, paired with their simulations (a scene's poses
or a file of simulated recordings)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import processing as P
from acousim.rig import RigSimulator
from acousim.scene.pose import Pose
from acousim.simulator import SCENE_MOTION, Simulator
from hardware import decode_frame, read_ticks
from processing.base.errors import InputError
from processing.sensor.rtisdev import sample_recording

__all__ = [
    "load_real_recordings",
    "pair_with_scene",
    "pair_with_rig",
    "pair_with_file",
    "of_sensor",
]


def load_real_recordings(
    source: str | Path,
    *,
    array: str = "ertis_v3d1",
    call: str | None = None,
    speed_of_sound_m_s: float = 343.0,
) -> list[P.Recording]:
    """The real recordings of `source`: ``"rtisdev-sample"`` (the eRTIS sample of the
    rtisdev wheel), raw tick words (``.bin``, decoded with the `array` and `call`
    presets, default ``default_25_50``, at `speed_of_sound_m_s`), a recording file
    (``.h5``, read once) or a CHIRP file (`call`: ``paper`` or a preset, for one that
    does not say it; `speed_of_sound_m_s` for one not of ours).
    Raises InputError naming the file or option."""
    source = str(source)
    if source == "rtisdev-sample" or source.endswith(".bin"):
        path = sample_recording() if source == "rtisdev-sample" else Path(source)
        raw = read_ticks(path)  # an InputError naming the file and its size
        try:
            arr = P.preset(array)
        except ValueError as exc:
            raise InputError(str(exc), key="--array", value=array) from None
        try:
            wf = P.rtis_call(call or "default_25_50")
        except ValueError as exc:
            raise InputError(str(exc), key="--call", value=call) from None
        return [
            decode_frame(raw, arr, wf, {"source": str(path)}, speed_of_sound_m_s=speed_of_sound_m_s)
        ]
    try:
        if P.is_chirp(source):
            wf = None if call is None else P.named_call(call)
            return P.read_chirp(source, call=wf, speed_of_sound_m_s=speed_of_sound_m_s)
        return P.load_recordings(source)
    except P.RecordingFileError as exc:
        raise InputError(str(exc)) from None


def of_sensor(recs: Sequence[P.Recording], name: str | None, what: str) -> list[P.Recording]:
    """The recordings of a rig's sonar `name` (``metadata["sensor"]``) among `recs`
    (`what`: the file, for the error); all of them when `name` is None or none of
    them names a sonar (one sensor's file).  A rig's file without `name`, or with a
    name none of its recordings has: InputError naming ``--sensor`` and the sonars."""
    names = [r.metadata.get("sensor") for r in recs]
    there = list(dict.fromkeys(n for n in names if n is not None))
    if not there:
        return list(recs)
    if name not in there:
        raise InputError(
            f"{what} holds the recordings of a rig's sonars ({', '.join(there)}): "
            "name the one to take",
            key="--sensor",
            value=name,
        )
    return [r for r, n in zip(recs, names) if n == name]


def _pick(recs: Sequence[P.Recording], i: int, key: str, what: str) -> P.Recording:
    if not 0 <= i < len(recs):
        raise InputError(f"{what} holds {len(recs)} recording(s)", key=key, value=i)
    return recs[i]


def pair_with_scene(
    reals: Sequence[P.Recording],
    scene,
    *,
    every: bool = False,
    index: int = 0,
    pose: int = 0,
    recorded: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> list[tuple[P.Recording, P.Recording]]:
    """(real, simulated) pairs: real recording `index` with the scene simulated at
    `pose`, or with `every`, real recording i with pose i for every i; with
    `recorded`, each at the pose its own metadata holds (a CHIRP file's odometry),
    frozen.  Each simulation has its real partner's length.  Raises InputError naming
    ``--index``, ``--pose`` or the scene file (a scene the simulator refuses: an
    unreadable mesh). `progress(done, total)` after each simulated pose."""

    chosen = list(reals) if every else [_pick(reals, index, "--index", "the real file")]
    if recorded:
        poses = [r.provenance.pose for r in chosen]
        bare = [i for i, p in enumerate(poses) if p is None]
        if bare:
            raise InputError("has no pose to simulate at", key="real recording", value=bare[0])
        first = 0 if every else index
        targets = [(_recorded_pose(p), None, first + i) for i, p in enumerate(poses)]
    else:
        poses = list(range(len(reals))) if every else [pose]
        n = len(scene.sensor.poses)
        bad = [q for q in poses if not 0 <= q < n]
        if bad:
            raise InputError(f"the scene has {n} pose(s)", key="--pose", value=bad[0])
        targets = [(scene.sensor.poses[q], SCENE_MOTION, q) for q in poses]
    try:
        simulator = Simulator(scene)
        sims = []
        for r, (p, m, q) in zip(chosen, targets):
            sims.append(simulator.simulate_pose(p, q, n_samples=r.n_samples, motion=m))
            if progress:
                progress(len(sims), len(targets))
    except ValueError as exc:
        raise InputError(str(exc), file=scene.source) from None
    return list(zip(chosen, sims))


def pair_with_rig(
    reals: Sequence[P.Recording],
    scene,
    sensor: str,
    *,
    every: bool = False,
    index: int = 0,
    pose: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> list[tuple[P.Recording, P.Recording]]:
    """(real, simulated) pairs of a rig's sonar `sensor` with the rig's crosstalk: its
    firing `pose` (its i-th, in time order; with `every`, firing i for real recording
    i) simulated by the whole rig (:class:`~acousim.rig.RigSimulator`: the other
    sonars' calls that reach its window are in it), each the length of its real
    partner.  Otherwise as :func:`pair_with_scene`."""
    chosen = list(reals) if every else [_pick(reals, index, "--index", "the real file")]
    try:
        rig = RigSimulator(scene)
        firings = [m.index for m in rig.measurements if rig.rig.sonars[m.sonar].name == sensor]
        wanted = list(range(len(chosen))) if every else [pose]
        bad = [q for q in wanted if not 0 <= q < len(firings)]
        if bad:
            raise InputError(
                f"sonar {sensor!r} fires {len(firings)} time(s)", key="--pose", value=bad[0]
            )
        sims = []
        for r, q in zip(chosen, wanted):
            sims.append(rig.simulate(firings[q], n_samples=r.n_samples))
            if progress:
                progress(len(sims), len(chosen))
    except InputError:
        raise
    except ValueError as exc:
        raise InputError(str(exc), file=scene.source) from None
    return list(zip(chosen, sims))


def _recorded_pose(p: P.SensorPose):
    """A recording's pose (its provenance) as a :class:`~acousim.scene.pose.Pose`."""

    return Pose(p.position_m, p.yaw_rad, p.pitch_rad, p.roll_rad, time_s=p.time_s)


def pair_with_file(
    reals: Sequence[P.Recording],
    sims: Sequence[P.Recording],
    *,
    every: bool = False,
    index: int = 0,
    sim_index: int = 0,
) -> list[tuple[P.Recording, P.Recording]]:
    """(real, simulated) pairs from two files: recording `index` with simulated
    recording `sim_index`, or with `every`, recording i with recording i for every i
    both files hold.  Raises InputError naming ``--index`` or ``--sim-index``."""
    if every:
        return list(zip(reals, sims))
    return [
        (
            _pick(reals, index, "--index", "the real file"),
            _pick(sims, sim_index, "--sim-index", "the --sim file"),
        )
    ]
