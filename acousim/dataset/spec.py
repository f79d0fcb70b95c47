"""Dataset spec files (TOML), documented in ``docs/dataset-format.md``."""

from __future__ import annotations

import difflib
import hashlib
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import processing as P

__all__ = ["Distribution", "SceneChoice", "StoreOptions", "DatasetSpec", "SpecError", "load_spec"]


class SpecError(ValueError):
    """A spec file that cannot be used; the message names the file, the key and value."""


@dataclass(frozen=True)
class Distribution:
    """uniform(low, high), normal(mean, sigma) or a constant."""

    kind: str
    a: float
    b: float = 0.0

    def draw(self, rng) -> float:
        if self.kind == "uniform":
            return float(rng.uniform(self.a, self.b))
        if self.kind == "normal":
            return float(rng.normal(self.a, self.b))
        return self.a


@dataclass(frozen=True)
class SceneChoice:
    file: Path
    weight: float = 1.0
    poses: str = "trajectory"  # or "random"
    region: dict = field(default_factory=dict)  # x, y, z, yaw_deg: [low, high]
    clearance_m: float = 0.2


@dataclass(frozen=True)
class StoreOptions:
    raw: bool = False
    snapshot: bool = True
    images: tuple[str, ...] = ("das",)
    labels: bool = True
    depth_map: bool = True
    step_deg: float = 4.0
    azimuth_deg: tuple[float, float] = (-90.0, 90.0)
    elevation_deg: tuple[float, float] = (-30.0, 30.0)
    energy_fraction: float = 1e-3
    min_range_m: float = 0.25
    max_bins: int = 256


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

    @property
    def n_shards(self) -> int:
        return -(-self.samples // self.shard_size)


KEYS = {
    "": {"dataset", "scenes", "randomize", "store"},
    "dataset": {"name", "samples", "shard_size", "seed", "compression"},
    "scenes": {"file", "weight", "poses", "region", "clearance_m"},
    "randomize": {
        "temperature_c",
        "humidity_percent",
        "snr_db",
        "reflection_scale",
        "mount_jitter_deg",
        "mount_jitter_m",
        "speed_m_s",
        "turn_rate_deg_s",
    },
    "store": {
        "raw",
        "snapshot",
        "images",
        "labels",
        "depth_map",
        "step_deg",
        "azimuth_deg",
        "elevation_deg",
        "energy_fraction",
        "min_range_m",
        "max_bins",
    },
}


def _unknown(src: str, where: str, table: dict, section: str) -> None:
    for k in table:
        if k not in KEYS[section]:
            close = difflib.get_close_matches(k, sorted(KEYS[section]), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise SpecError(f"{src}: [{where}{'.' if where else ''}{k}] unknown key {k!r}{hint}")


def _num(src, where, v, lo=-math.inf, hi=math.inf, integer=False):
    if (
        isinstance(v, bool)
        or not isinstance(v, int | float)
        or not lo <= v <= hi
        or (integer and not float(v).is_integer())
    ):
        kind = "a whole number" if integer else "a number"
        raise SpecError(f"{src}: [{where}] must be {kind} in [{lo}, {hi}], got {v!r}")
    return int(v) if integer else float(v)


def _dist(src: str, where: str, v) -> Distribution:
    if isinstance(v, int | float) and not isinstance(v, bool):
        return Distribution("constant", float(v))
    if not isinstance(v, dict):
        raise SpecError(f"{src}: [{where}] must be a number or a table, got {v!r}")
    kind = v.get("dist", "uniform")
    if kind == "uniform":
        lo, hi = v.get("range", [None, None])
        lo, hi = _num(src, f"{where}.range", lo), _num(src, f"{where}.range", hi)
        if hi < lo:
            raise SpecError(f"{src}: [{where}.range] low {lo} above high {hi}")
        return Distribution("uniform", lo, hi)
    if kind == "normal":
        return Distribution(
            "normal",
            _num(src, f"{where}.mean", v.get("mean", 0.0)),
            _num(src, f"{where}.sigma", v.get("sigma", 1.0), 0),
        )
    raise SpecError(f"{src}: [{where}.dist] {kind!r} is not 'uniform' or 'normal'")


def load_spec(path: str | Path) -> DatasetSpec:
    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise SpecError(f"{src}: no such dataset spec")
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecError(f"{src}: not valid TOML ({exc})") from None
    _unknown(src, "", data, "")
    ds = data.get("dataset", {})
    _unknown(src, "dataset", ds, "dataset")
    scenes = []
    items = data.get("scenes", [])
    if not isinstance(items, list) or not items:
        raise SpecError(f"{src}: [scenes] needs at least one [[scenes]] table")
    for i, s in enumerate(items):
        where = f"scenes[{i}]"
        _unknown(src, where, s, "scenes")
        if "file" not in s:
            raise SpecError(f"{src}: [{where}.file] missing")
        f = path.parent / s["file"]
        if not f.is_file():
            raise SpecError(f"{src}: [{where}.file] scene file not found: {f}")
        poses = s.get("poses", "trajectory")
        if poses not in ("trajectory", "random"):
            raise SpecError(f"{src}: [{where}.poses] {poses!r} is not 'trajectory' or 'random'")
        region = s.get("region", {})
        if poses == "random":
            for k in ("x", "y", "z"):
                if k not in region:
                    raise SpecError(f"{src}: [{where}.region.{k}] missing for random poses")
        scenes.append(
            SceneChoice(
                f,
                _num(src, f"{where}.weight", s.get("weight", 1.0), 0),
                poses,
                region,
                _num(src, f"{where}.clearance_m", s.get("clearance_m", 0.2), 0),
            )
        )
    rnd = data.get("randomize", {})
    _unknown(src, "randomize", rnd, "randomize")
    st = data.get("store", {})
    _unknown(src, "store", st, "store")
    images = tuple(st.get("images", ["das"]))
    for m in images:
        if m not in P.METHODS:
            raise SpecError(
                f"{src}: [store.images] unknown method {m!r}; choose from {', '.join(P.METHODS)}"
            )
    store = StoreOptions(
        raw=bool(st.get("raw", False)),
        snapshot=bool(st.get("snapshot", True)),
        images=images,
        labels=bool(st.get("labels", True)),
        depth_map=bool(st.get("depth_map", True)),
        step_deg=_num(src, "store.step_deg", st.get("step_deg", 4.0), 0.1, 45),
        azimuth_deg=tuple(st.get("azimuth_deg", (-90.0, 90.0))),
        elevation_deg=tuple(st.get("elevation_deg", (-30.0, 30.0))),
        energy_fraction=_num(src, "store.energy_fraction", st.get("energy_fraction", 1e-3), 0, 1),
        min_range_m=_num(src, "store.min_range_m", st.get("min_range_m", 0.25), 0),
        max_bins=_num(src, "store.max_bins", st.get("max_bins", 256), 1, integer=True),
    )
    comp = ds.get("compression", "gzip")
    if comp not in ("gzip", "lzf", "none"):
        raise SpecError(f"{src}: [dataset.compression] {comp!r} is not gzip, lzf or none")
    return DatasetSpec(
        name=str(ds.get("name", path.stem)),
        samples=_num(src, "dataset.samples", ds.get("samples", 100), 1, integer=True),
        shard_size=_num(src, "dataset.shard_size", ds.get("shard_size", 64), 1, integer=True),
        seed=_num(src, "dataset.seed", ds.get("seed", 0), 0, 2**63 - 1, integer=True),
        scenes=tuple(scenes),
        randomize={k: _dist(src, f"randomize.{k}", v) for k, v in rnd.items()},
        store=store,
        source=src,
        sha256=hashlib.sha256(raw).hexdigest(),
        compression=None if comp == "none" else comp,
    )
