"""Dataset spec files (TOML), documented in ``docs/dataset-format.md``.

Every key is declared once (:func:`processing.base.settings.setting`) on the dataclass of
its table: ``[dataset]`` :class:`DatasetOptions`, ``[[scenes]]`` :class:`SceneChoice`
(its ``region`` :class:`Region`), ``[store]`` :class:`StoreOptions`. The
``[randomize]`` keys draw values of scene settings and reuse those settings'
declarations (:data:`RANDOMIZE`): a distribution must lie inside the allowed range,
and normal draws are clipped to it. Adding a key is one ``setting(...)`` line (one
entry of :data:`RANDOMIZE` for a randomized condition). Errors are
:class:`SpecError`, an :class:`processing.base.errors.InputError` naming file, key, value.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, get_args

import processing as P
from acousim.dataset.safety import sha256_file
from acousim.scene import load_scene
from acousim.scene.defaults import Quality
from acousim.scene.model import Environment, Simulation
from acousim.scene.trajectory import RATES
from processing.base.errors import InputError
from processing.base.settings import (
    Setting,
    check,
    read_table,
    refuse_unknown,
    setting,
    settings_of,
    validate,
)

__all__ = [
    "Distribution",
    "Region",
    "MountRange",
    "SceneChoice",
    "StoreOptions",
    "DatasetOptions",
    "DatasetSpec",
    "SpecError",
    "RANDOMIZE",
    "load_spec",
]


ShardFormat = Literal["acousim", "chirp"]


class SpecError(InputError):
    """A spec file that cannot be used; the message names the file, the key and value."""


@dataclass(frozen=True)
class Distribution:
    """uniform(low, high), normal(mean, sigma) or a constant; draws are clipped to
    [lo, hi], the allowed range of the setting drawn."""

    kind: str
    a: float
    b: float = 0.0
    lo: float = -math.inf
    hi: float = math.inf

    def draw(self, rng) -> float:
        if self.kind == "uniform":
            v = float(rng.uniform(self.a, self.b))
        elif self.kind == "normal":
            v = float(rng.normal(self.a, self.b))
        else:
            v = self.a
        return min(max(v, self.lo), self.hi)


def _env(name: str) -> Setting:

    return settings_of(Environment)[name]


def _sim(name: str) -> Setting:

    return settings_of(Simulation)[name]


def _unset_by_default(decl: Setting, doc: str) -> Any:
    """A dataclass field declared as `decl` (its kind, choices and range) but optional,
    None by default (not given: the scene's own value), with `doc`."""
    d = dataclasses.replace(decl, default=None, optional=True, doc=doc)
    return field(default=None, metadata={"setting": d})


def _rate(name: str, unit: str, doc: str) -> Setting:
    """The sensor's speed or turn rate, within the scene's declaration of that rate
    (``acousim.scene.trajectory.RATES``), as one number."""

    decl = RATES[name]
    return dataclasses.replace(decl, kind="float", default=0.0, unit=unit, doc=doc, length=None)


#: the randomized conditions: what each draw must stay within
RANDOMIZE: dict[str, Setting] = {
    "temperature_c": _env("temperature_c"),
    "humidity_percent": _env("humidity_percent"),
    "snr_db": _sim("snr_db"),
    "reflection_scale": Setting("float", 1.0, "", 0, 10, "scales every material's reflection"),
    "mount_jitter_deg": Setting("float", 0.0, "deg", -45, 45, "yaw and pitch of the mounting"),
    "mount_jitter_m": Setting("float", 0.0, "m", -1, 1, "x, y, z of the mounting"),
    "speed_m_s": _rate("velocity_m_s", "m/s", "driving along the sensor's axis"),
    "turn_rate_deg_s": _rate("angular_rate_deg_s", "deg/s", "turning about the vertical"),
}


@dataclass(frozen=True)
class Region:
    """Where random poses are drawn (world frame): [low, high] per axis."""

    x: tuple[float, float] = setting((0.0, 0.0), "m", -1e4, 1e4, "x range", kind="interval")
    y: tuple[float, float] = setting((0.0, 0.0), "m", -1e4, 1e4, "y range", kind="interval")
    z: tuple[float, float] = setting((0.0, 0.0), "m", -1e4, 1e4, "z range", kind="interval")
    yaw_deg: tuple[float, float] = setting(
        (0.0, 0.0), "deg", -360, 360, "yaw range", kind="interval"
    )

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True)
class MountRange:
    """A rig's sonar's mount drawn per sample (body frame): [low, high] per key; a key
    not given keeps the rig's declared value."""

    x: tuple[float, float] = setting((0.0, 0.0), "m", -100, 100, "x range", kind="interval")
    y: tuple[float, float] = setting((0.0, 0.0), "m", -100, 100, "y range", kind="interval")
    z: tuple[float, float] = setting((0.0, 0.0), "m", -100, 100, "z range", kind="interval")
    roll_deg: tuple[float, float] = setting(
        (0.0, 0.0), "deg", -180, 180, "roll range", kind="interval"
    )
    pitch_deg: tuple[float, float] = setting(
        (0.0, 0.0), "deg", -90, 90, "pitch range", kind="interval"
    )
    yaw_deg: tuple[float, float] = setting(
        (0.0, 0.0), "deg", -180, 180, "yaw range", kind="interval"
    )

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True)
class SceneChoice:
    """A scene a sample may use; `region` (x, y, z, yaw_deg: [low, high]) for random
    poses; a rig's scene: its `sensor` whose recordings the samples are, and `mount`
    (:class:`MountRange` keys: [low, high]) its mount drawn per sample."""

    file: Path
    weight: float = setting(1.0, "", 0, 1e6, "relative probability of this scene")
    poses: str = setting("trajectory", choices=("trajectory", "random"), doc="pose source")
    region: dict = field(default_factory=dict)
    clearance_m: float = setting(
        0.2,
        "m",
        0,
        10,
        "random poses: no surface nearer to the position drawn, to the emitter or to "
        "any microphone (a true distance; a closed scene's poses must also see a surface "
        "along +-x, +-y, +-z: inside the room)",
    )
    sensor: str | None = setting(None, kind="str", doc="a rig's scene: the sonar sampled")
    mount: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True)
class StoreOptions:
    """What each sample stores (the ``[store]`` table)."""

    raw: bool = setting(False, doc="the microphone signals (float32)")
    snapshot: bool = setting(True, doc="the STFT snapshot of the kept range bins")
    images: tuple[str, ...] = setting(
        ("das",), kind="strings", choices=tuple(P.METHODS), doc="3D images (DOA methods)"
    )
    labels: bool = setting(True, doc="ray-traced reflectors")
    depth_map: bool = setting(True, doc="distance to the nearest surface per direction")
    step_deg: float = setting(4.0, "deg", 0.1, 45, "image grid step")
    azimuth_deg: tuple[float, float] = setting(
        (-90.0, 90.0), "deg", -90, 90, "image azimuths", kind="interval"
    )
    elevation_deg: tuple[float, float] = setting(
        (-30.0, 30.0), "deg", -90, 90, "image elevations", kind="interval"
    )
    energy_fraction: float = setting(
        P.ProcessingSettings.energy_fraction, "", 0, 1, "range-bin gate"
    )
    min_range_m: float = setting(0.25, "m", 0, 100, "the image's first range bin")
    max_range_m: float | None = setting(
        None, "m", 0, 1e4, "the image's last range bin; unset: the scenes' largest", kind="float"
    )
    range_step_m: float = setting(
        0.006, "m", 1e-4, 10, "range-bin spacing, the same in any air (the image's R)"
    )
    max_bins: int = setting(256, "", 1, 1_000_000, "at most this many range bins")
    floor_db: float = setting(-60.0, "dB", -300, -1, "image floor; gated range bins hold it")
    max_peaks: int = setting(32, "", 0, 100_000, "image peaks stored (the strongest)")
    peak_threshold_db: float = setting(
        -20.0, "dB", -300, 0, "image peaks at least this level (dB re the maximum)"
    )

    def __post_init__(self) -> None:
        validate(self)
        lo, hi = self.min_range_m, self.max_range_m
        if hi is not None and hi < lo:
            raise InputError(f"below min_range_m = {lo:g}", key="store.max_range_m", value=hi)


@dataclass(frozen=True)
class DatasetOptions:
    """The ``[dataset]`` table."""

    name: str = setting("dataset", doc="dataset name (default: the spec's file name)")
    samples: int = setting(100, "", 1, 10**9, "total samples")
    shard_size: int = setting(64, "", 1, 10**6, "samples per HDF5 shard")
    seed: int = setting(0, "", 0, 2**63 - 1, "sample i draws from SeedSequence([seed, i])")
    compression: str = setting("gzip", choices=("gzip", "lzf", "none"), doc="HDF5 filter")
    format: ShardFormat = setting(
        "acousim",
        choices=get_args(ShardFormat),
        doc="shards: acousim (images, snapshots, labels) or chirp (CHIRP files: the "
        "recordings, ground truth and LiDAR scans; [store] does not apply)",
    )
    #: every scene's ``simulation.quality`` (the scene's declaration); its explicitly
    #: given [simulation] settings still apply
    quality: Quality | None = _unset_by_default(
        _sim("quality"), "every scene's simulation.quality; unset: each scene file's"
    )

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True)
class DatasetSpec:
    name: str
    samples: int
    shard_size: int
    seed: int
    scenes: tuple[SceneChoice, ...]
    randomize: dict[str, Distribution]
    store: StoreOptions
    source: str
    sha256: str
    compression: str | None = "gzip"
    format: ShardFormat = "acousim"
    #: every scene's quality preset (``[dataset] quality``, ``--quality``); None: each
    #: scene file's own
    quality: Quality | None = None
    #: every file the samples depend on -> its sha256: the spec (under its file name),
    #: each scene file and the meshes, coordinate files and trajectories it reads; the
    #: paths relative to the spec's folder, '/' separated
    inputs: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        DatasetOptions(
            self.name,
            self.samples,
            self.shard_size,
            self.seed,
            self.compression or "none",
            self.format,
            self.quality,
        )
        if not self.scenes:
            raise SpecError("needs at least one [[scenes]] table", file=self.source, key="scenes")

    @property
    def n_shards(self) -> int:
        return -(-self.samples // self.shard_size)


def _fail(exc: InputError) -> SpecError:
    return SpecError(exc.reason, file=exc.file, key=exc.key, value=exc.value)


def _table(src: str, data: dict, key: str) -> dict:
    v = data.get(key, {})
    if not isinstance(v, dict):
        raise SpecError("must be a table", file=src, key=key, value=v)
    return v


def _dist(src: str, where: str, v: Any, decl: Setting) -> Distribution:
    if not isinstance(v, dict):
        x = check(decl, v, where, src)
        return Distribution("constant", x, lo=decl.lo, hi=decl.hi)
    kind = v.get("dist", "uniform")
    check(Setting("str", choices=("uniform", "normal")), kind, f"{where}.dist", src)
    if kind == "uniform":
        allowed = {"dist", "range"}
        bounds = dataclasses.replace(decl, kind="interval")
        if "range" not in v:
            raise SpecError("missing ([low, high])", file=src, key=f"{where}.range")
        lo, hi = check(bounds, v["range"], f"{where}.range", src)
        out = Distribution("uniform", lo, hi, decl.lo, decl.hi)
    else:
        allowed = {"dist", "mean", "sigma"}
        mean = check(decl, v.get("mean", 0.0), f"{where}.mean", src)
        span = decl.hi - decl.lo if math.isfinite(decl.hi - decl.lo) else 1e6
        if "sigma" not in v:
            raise SpecError(
                "missing (the normal's standard deviation)", file=src, key=f"{where}.sigma"
            )
        sigma = check(Setting("float", lo=0, hi=span), v["sigma"], f"{where}.sigma", src)
        out = Distribution("normal", mean, sigma, decl.lo, decl.hi)
    refuse_unknown(v, allowed, where=where, file=src)
    return out


def load_spec(path: str | Path) -> DatasetSpec:
    """Read and validate a dataset spec; a :class:`SpecError` names file, key and value."""
    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise SpecError("no such dataset spec", file=src)
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecError(f"not valid TOML ({exc})", file=src) from None
    try:
        return _parse(data, path, src, hashlib.sha256(raw).hexdigest())
    except SpecError:
        raise
    except InputError as exc:
        raise _fail(exc) from None


def _check_rig(scene, sensor: str | None, mount: dict, src: str, where: str) -> None:
    """A rig's scene names its sonar (`sensor`); `sensor` and `mount` only for one."""
    if scene.rig is None:
        for key, given in (("sensor", sensor is not None), ("mount", bool(mount))):
            if given:
                raise SpecError("only for a rig's scene", file=src, key=f"{where}.{key}")
        return
    names = [x.name for x in scene.rig.sonars]
    if sensor not in names:
        raise SpecError(
            f"the scene is a rig of {len(names)} sonar(s) ({', '.join(names)}): name the "
            "one whose recordings are the samples",
            file=src,
            key=f"{where}.sensor",
            value=sensor,
        )


def _parse(data: dict, path: Path, src: str, sha256: str) -> DatasetSpec:
    refuse_unknown(data, ("dataset", "scenes", "randomize", "store"), where="", file=src)
    ds = read_table(DatasetOptions, _table(src, data, "dataset"), where="dataset", file=src)
    opts = DatasetOptions(**{"name": path.stem, **ds})
    items = data.get("scenes", [])
    inputs = {path.name: sha256}
    arrays = []  # each scene's array (a rig's: the sonar sampled)
    if not isinstance(items, list) or not items:
        raise SpecError("needs at least one [[scenes]] table", file=src, key="scenes", value=items)
    scenes = [_scene_choice(s, f"scenes[{i}]", path, inputs, arrays) for i, s in enumerate(items)]
    if sum(s.weight for s in scenes) <= 0:
        raise SpecError("at least one scene needs a positive weight", file=src, key="scenes")
    rnd = _table(src, data, "randomize")
    refuse_unknown(rnd, RANDOMIZE, where="randomize", file=src)
    randomize = {k: _dist(src, f"randomize.{k}", v, RANDOMIZE[k]) for k, v in rnd.items()}
    try:
        store = StoreOptions(
            **read_table(StoreOptions, _table(src, data, "store"), where="store", file=src)
        )
    except InputError as exc:  # a check across keys: the file named too
        raise SpecError(exc.reason, file=src, key=exc.key, value=exc.value) from None
    _check_microphones(arrays, opts.format, store, src)
    return DatasetSpec(
        name=opts.name,
        samples=opts.samples,
        shard_size=opts.shard_size,
        seed=opts.seed,
        scenes=tuple(scenes),
        randomize=randomize,
        store=store,
        source=src,
        sha256=sha256,
        compression=None if opts.compression == "none" else opts.compression,
        format=opts.format,
        quality=opts.quality,
        inputs=inputs,
    )


def _scene_choice(s: Any, where: str, path: Path, inputs: dict, arrays: list) -> SceneChoice:
    """One ``[[scenes]]`` table, its scene loaded and checked now (not in a worker
    halfway through the dataset); the files it reads added to `inputs` (file ->
    sha256), its array to `arrays`."""
    src = str(path)
    choice = read_table(SceneChoice, s, where=where, file=src, extra=("file", "region", "mount"))
    if "file" not in s:
        raise SpecError("missing", file=src, key=f"{where}.file")
    f = _scene_file(path.parent, check(Setting("str"), s["file"], f"{where}.file", src), src, where)
    try:
        scene = load_scene(f)
    except InputError as exc:
        raise SpecError(f"not a usable scene ({exc})", file=src, key=f"{where}.file") from None
    mount = read_table(MountRange, s.get("mount", {}), where=f"{where}.mount", file=src)
    _check_rig(scene, choice.get("sensor"), mount, src, where)
    arrays.append(_array_of(scene, choice.get("sensor")))
    for dep, digest in ((f, scene.file_sha256), *((g, None) for g in scene.files)):
        inputs[_relative_to(dep, path.parent)] = digest or sha256_file(dep)
    region_t = s.get("region", {})
    region = read_table(Region, region_t, where=f"{where}.region", file=src)
    if choice.get("poses", "trajectory") == "random":
        for k in ("x", "y", "z"):
            if k not in region:
                raise SpecError("missing for random poses", file=src, key=f"{where}.region.{k}")
    elif region_t:
        raise SpecError(
            'a region is for poses = "random"; this scene\'s poses are its '
            'trajectory\'s (poses = "trajectory", the default): drop the region or '
            'set poses = "random"',
            file=src,
            key=f"{where}.region",
            value=region_t,
        )
    return SceneChoice(f, region=region, mount=mount, **choice)


def _array_of(scene, sensor: str | None):
    """The array whose recordings a scene's samples are (a rig's: `sensor`'s)."""
    if scene.rig is None:
        return scene.sensor.array
    return next(s.sensor.array for s in scene.rig.sonars if s.name == sensor)


def _check_microphones(arrays: list, shard_format: str, store: StoreOptions, src: str) -> None:
    """``raw`` (M, T) and ``snapshot`` (M, R_kept) have one M per dataset (a batch
    stacks them): scenes whose arrays have different microphone counts are refused
    when the shards store either."""
    counts = [a.positions_m.shape[0] for a in arrays]
    stored = [k for k in ("raw", "snapshot") if getattr(store, k)]
    if len(set(counts)) < 2 or shard_format == "chirp" or not stored:
        return  # CHIRP shards: one array (acousim.dataset.chirp_shards checks it)
    listed = ", ".join(
        f"scenes[{i}]: {a.name} M = {m}" for i, (a, m) in enumerate(zip(arrays, counts))
    )
    raise SpecError(
        f"the scenes' arrays have different microphone counts ({listed}), and "
        f"{' and '.join(stored)} would have a different shape (M, ...) per sample: a batch "
        "cannot stack them. Keep one array per dataset, or store images only "
        "(raw = false, snapshot = false)",
        file=src,
        key="scenes",
    )


def _relative_to(file: Path, folder: Path) -> str:
    """`file` relative to `folder`, normalised, '/' separated."""
    return Path(os.path.relpath(os.path.normpath(file), os.path.normpath(folder))).as_posix()


def _scene_file(folder: Path, name: str, src: str, where: str) -> Path:
    """A spec's scene: a file relative to the spec's folder, else a bundled scene of
    that name (``file = "shoebox"``, as the command line takes it)."""
    from acousim.bundled import bundled_names, find_scene

    f = folder / name
    if f.is_file():
        return f
    bundled = find_scene(name)
    if bundled is None:
        names = ", ".join(bundled_names("scenes"))
        raise SpecError(
            f"scene file not found: {f} (nor a bundled scene: {names})",
            file=src,
            key=f"{where}.file",
            value=name,
        )
    return bundled
