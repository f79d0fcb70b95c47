"""Microphone array geometry and the presets of the sensors we know.

Coordinate frame (the paper's Fig. 1): x points forward (the boresight), y to the
left and z up; the microphones lie in the y-z plane.  A direction is given by its
azimuth (rotation from x towards +y) and elevation (from the x-y plane towards +z)::

    u = (cos(el) cos(az), cos(el) sin(az), sin(el))

Positions are in metres and are centred on the array's centroid (its phase centre)
unless stated otherwise; the emitter sits at the origin by default.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.base.errors import InputError, UnitsWarning, unknown_choice
from processing.base.settings import Setting, check

__all__ = [
    "Array",
    "ura",
    "paper_8x8",
    "urtis_v1",
    "ertis_v3d1",
    "from_coordinates",
    "from_coordinates_file",
    "PRESETS",
    "preset",
    "MAX_EXTENT_M",
]

MAX_EXTENT_M = 10.0
"""Largest coordinate (m, each axis, sensor frame) of a microphone or the emitter:
an array is centimetres across; the bound keeps every computation on its geometry
(centroids, distances squared) free of overflow, checked before any of it."""


@dataclass(frozen=True, eq=False)
class Array:
    """A planar microphone array.

    Attributes
    ----------
    name : str
        Human-readable name (a preset name for presets).
    positions_m : ndarray, shape (M, 3)
        Microphone positions (x, y, z) in metres.
    emitter_m : ndarray, shape (3,)
        Emitter position in metres.
    grid_index : ndarray of int, shape (M, 2), or None
        For a uniform rectangular array (URA): the (row, column) of each microphone,
        rows along z and columns along y, both increasing with the coordinate.
    pitch_m : tuple of float (dz, dy), or None
        URA pitch along z (between rows) and y (between columns), metres.
    channels : ndarray of int, shape (M,)
        The hardware channel that carries each microphone (identity for simulated
        arrays).
    """

    name: str
    positions_m: np.ndarray
    emitter_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    grid_index: np.ndarray | None = None
    pitch_m: tuple[float, float] | None = None
    channels: np.ndarray | None = None

    def __post_init__(self) -> None:
        pos, emitter = _points(self.name, self.positions_m, self.emitter_m)
        channels = np.arange(pos.shape[0]) if self.channels is None else np.asarray(self.channels)
        if channels.shape != (pos.shape[0],) or channels.dtype.kind not in "iu":
            raise InputError(
                f"array {self.name!r}: must be {pos.shape[0]} whole numbers",
                key="channels",
                value=channels.tolist(),
            )
        object.__setattr__(self, "positions_m", pos)
        object.__setattr__(self, "emitter_m", emitter)
        object.__setattr__(self, "channels", channels.astype(int))
        if self.grid_index is not None:
            gi, pitch = _grid(self.name, self.grid_index, self.pitch_m, pos.shape[0])
            object.__setattr__(self, "grid_index", gi)
            object.__setattr__(self, "pitch_m", pitch)

    def __repr__(self) -> str:
        kind = f"URA {self.grid_shape[0]}x{self.grid_shape[1]}" if self.is_ura else "irregular"
        z, y = self.aperture_m()
        return (
            f"Array({self.name!r}, {self.n_mics} mics, {kind}, "
            f"aperture {y * 1e3:.1f} x {z * 1e3:.1f} mm (y x z))"
        )

    @property
    def n_mics(self) -> int:
        """Number of microphones M."""
        return self.positions_m.shape[0]

    @property
    def is_ura(self) -> bool:
        """True when every cell of a rectangular grid holds exactly one microphone."""
        if self.grid_index is None:
            return False
        rows, cols = self.grid_shape
        cells = self.grid_index[:, 0] * cols + self.grid_index[:, 1]
        return len(np.unique(cells)) == rows * cols == self.n_mics

    @property
    def grid_shape(self) -> tuple[int, int]:
        """(rows, columns) of the URA grid."""
        if self.grid_index is None:
            raise InputError(f"array {self.name!r} is not a uniform rectangular array")
        return int(self.grid_index[:, 0].max()) + 1, int(self.grid_index[:, 1].max()) + 1

    def grid_order(self) -> np.ndarray:
        """Microphone indices in row-major grid order (row along z, column along y).

        ``x[..., array.grid_order()]`` reshaped to ``(rows, cols)`` puts a snapshot on
        its grid.  Raises InputError for an array that is not a full URA.
        """
        self.require_ura("grid ordering")
        assert self.grid_index is not None  # a URA's
        rows, cols = self.grid_shape
        cells = self.grid_index[:, 0] * cols + self.grid_index[:, 1]
        return np.argsort(cells, kind="stable")

    def require_ura(self, what: str) -> None:
        """Raise a clear InputError when `what` needs a URA and this array is not one."""
        if not self.is_ura:
            raise InputError(
                f"{what} needs a uniform rectangular array, but array {self.name!r} "
                f"({self.n_mics} microphones) is irregular; use 'das', 'music' or 'capon'"
            )

    def require_mics(self, what: str, n: int = 2) -> None:
        """An InputError naming the array and its count when `what` (imaging: a
        direction needs phase differences) needs at least `n` microphones."""
        if self.n_mics < n:
            raise InputError(
                f"{what} needs at least {n} microphones; this array has {self.n_mics}",
                key="array",
                value=self.name,
            )

    def alias_free_hz(self, speed_of_sound_m_s: float) -> float:
        """Highest frequency without grating lobes over the hemisphere: c / (2 pitch)
        for a URA (the larger pitch).  An irregular (pseudo-random) layout has no
        periodic grating lobes: infinity."""
        if self.is_ura and self.pitch_m is not None:
            return speed_of_sound_m_s / (2 * max(self.pitch_m))
        return float("inf")

    def aperture_m(self) -> tuple[float, float]:
        """Extent (z, y) of the array in metres."""
        p = self.positions_m
        return float(np.ptp(p[:, 2])), float(np.ptp(p[:, 1]))


def _points(name: str, positions, emitter) -> tuple[np.ndarray, np.ndarray]:
    """Microphone positions (M, 3) and emitter (3,) checked: finite, within
    MAX_EXTENT_M, no two microphones at one place (InputError otherwise)."""
    try:
        pos = np.asarray(positions, dtype=float)
        em = np.asarray(emitter, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InputError(f"array {name!r}: not numbers", key="positions_m") from None
    if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] < 1:
        raise InputError(
            f"array {name!r}: must have shape (M, 3)", key="positions_m", value=pos.shape
        )
    for key, v in (("positions_m", pos), ("emitter_m", em)):
        if not np.all(np.isfinite(v)) or np.any(np.abs(v) > MAX_EXTENT_M):
            raise InputError(
                f"array {name!r}: must be finite and within +-{MAX_EXTENT_M:g} m",
                key=key,
                value=v.tolist(),
            )
    _, first, count = np.unique(pos, axis=0, return_index=True, return_counts=True)
    if np.any(count > 1):
        i = int(first[np.argmax(count > 1)])
        raise InputError(
            f"array {name!r}: two microphones at the same position (microphone {i})",
            key="positions_m",
            value=pos[i].tolist(),
        )
    return pos, em


def _grid(name: str, grid_index, pitch_m, n: int) -> tuple[np.ndarray, tuple[float, float]]:
    """A URA's (row, column) per microphone (M, 2), each in [0, M), and its pitch."""
    gi = np.asarray(grid_index)
    if gi.shape != (n, 2) or gi.dtype.kind not in "iu" or pitch_m is None:
        raise InputError(
            f"array {name!r}: grid_index needs shape ({n}, 2) of whole numbers and a pitch_m",
            key="grid_index",
            value=gi.shape,
        )
    if gi.size and (gi.min() < 0 or gi.max() >= n):
        raise InputError(
            f"array {name!r}: grid indices must lie in [0, {n})",
            key="grid_index",
            value=[int(gi.min()), int(gi.max())],
        )
    try:
        pitch = (float(pitch_m[0]), float(pitch_m[1]))
        shown = list(pitch)
    except (TypeError, ValueError, IndexError):
        pitch, shown = (np.nan, np.nan), pitch_m
    if not all(np.isfinite(pitch)) or min(pitch) <= 0 or max(pitch) > MAX_EXTENT_M:
        raise InputError(
            f"array {name!r}: must be two positive finite numbers (dz, dy)",
            key="pitch_m",
            value=shown,
        )
    return gi.astype(int), pitch


def ura(
    n_rows: int,
    n_cols: int,
    pitch_m: float | tuple[float, float],
    *,
    name: str | None = None,
    emitter_m: np.ndarray | None = None,
) -> Array:
    """A uniform rectangular array centred on the origin in the y-z plane.

    Parameters
    ----------
    n_rows, n_cols : int
        Number of rows (along z) and columns (along y).
    pitch_m : float or (dz, dy)
        Element spacing in metres, each in [1e-5, 0.5] (:data:`URA_PITCH_M`: ``ura(4, 4,
        4)`` is refused as millimetres given as metres).

    Bad input raises :class:`processing.InputError` naming the argument and value.
    """
    n_rows = check(URA_SIZE, n_rows, "ura: n_rows")
    n_cols = check(URA_SIZE, n_cols, "ura: n_cols")
    dz, dy = _pitch(pitch_m)
    row, col = (g.ravel() for g in np.meshgrid(np.arange(n_rows), np.arange(n_cols), indexing="ij"))
    pos = np.column_stack(
        [np.zeros(row.size), (col - (n_cols - 1) / 2) * dy, (row - (n_rows - 1) / 2) * dz]
    )
    return Array(
        name=name or f"ura_{n_rows}x{n_cols}",
        positions_m=pos,
        emitter_m=np.zeros(3) if emitter_m is None else emitter_m,
        grid_index=np.column_stack([row, col]),
        pitch_m=(dz, dy),
    )


#: rows or columns of :func:`ura`
URA_SIZE = Setting("int", None, "", 1, 1 << 20, "rows or columns of a URA")
#: the pitch of :func:`ura`, each of (dz, dy): a plausible array, from micromachined
#: (10 um) to large (0.5 m); a pitch in millimetres given as metres is refused
URA_PITCH_M = Setting("float", None, "m", 1e-5, 0.5, "URA element spacing")


def _pitch(pitch_m) -> tuple[float, float]:
    """(dz, dy) of a :func:`ura` pitch (one number or two), each checked against
    :data:`URA_PITCH_M`; one that would be plausible in millimetres says so."""
    try:
        both = (pitch_m, pitch_m) if np.ndim(pitch_m) == 0 else tuple(pitch_m)
    except TypeError:
        both = ()
    if len(both) != 2:
        raise InputError("must be a number or (dz, dy), metres", key="ura: pitch_m", value=pitch_m)
    out = []
    for p in both:
        try:
            out.append(check(URA_PITCH_M, p, "ura: pitch_m"))
        except InputError as exc:
            mm = isinstance(p, int | float | np.number) and 0.5 < p <= 500
            if not mm:
                raise
            raise InputError(
                f"{exc.reason}; metres expected: did you mean {p:g} mm, pitch_m={p * 1e-3:g}?",
                key="ura: pitch_m",
                value=pitch_m,
            ) from None
    return out[0], out[1]


def paper_8x8() -> Array:
    """The simulated array of the paper: 8 x 8 URA, 5 mm pitch, 64 microphones."""
    return ura(8, 8, 5e-3, name="paper_8x8")


def urtis_v1() -> Array:
    """The μRTIS v1: 5 rows x 6 columns at 3.85 mm, 30 of its 32 channels.

    Channels run column by column (5 per column, rows bottom to top) and skip the
    unused channels 15 and 31, as in the sensor's published layout.
    """
    pitch = 3.85e-3
    channels = np.array([c for c in range(32) if c not in (15, 31)])
    col, row = np.divmod(np.arange(30), 5)
    pos = np.column_stack([np.zeros(30), (col - 2.5) * pitch, (row - 2.0) * pitch])
    return Array(
        name="urtis_v1",
        positions_m=pos,
        grid_index=np.column_stack([row, col]),
        pitch_m=(pitch, pitch),
        channels=channels,
    )


def from_coordinates(
    yz_m: np.ndarray,
    *,
    name: str = "custom",
    centre: bool = True,
    emitter_m: np.ndarray | None = None,
    source: str = "coordinates",
) -> Array:
    """Build an array from (y, z) coordinates in metres, one row per channel.

    Rows that are NaN mark unused channels: they are dropped and the remaining rows
    keep their channel numbers.  Coordinates beyond 1 m (:data:`PLAUSIBLE_COORDINATE_M`)
    warn (:class:`processing.UnitsWarning`: millimetres given as metres?).  With
    ``centre`` the positions are shifted so that their centroid is the origin (where
    the emitter is assumed unless given).
    """
    yz = np.asarray(yz_m, dtype=float)
    if yz.ndim != 2 or yz.shape[1] != 2:
        raise InputError(f"{source}: expected an (M, 2) table of (y, z), got shape {yz.shape}")
    used = ~np.isnan(yz).any(axis=1)
    if not used.any():
        raise InputError(f"{source}: every row is NaN, no microphone left")
    yz_used = yz[used]
    if not np.all(np.isfinite(yz_used)):
        raise InputError(f"{source}: coordinates contain inf")
    if np.any(np.abs(yz_used) > MAX_EXTENT_M):  # before the centroid, which would overflow
        raise InputError(
            f"{source}: coordinates beyond +-{MAX_EXTENT_M:g} m (wrong units?)",
            value=float(np.abs(yz_used).max()),
        )
    _warn_millimetres(source, yz_used)
    if centre:
        yz_used = yz_used - yz_used.mean(axis=0)
    pos = np.column_stack([np.zeros(len(yz_used)), yz_used])
    return Array(
        name=name,
        positions_m=pos,
        emitter_m=np.zeros(3) if emitter_m is None else emitter_m,
        channels=np.flatnonzero(used),
    )


#: a microphone coordinate (m) beyond which :func:`from_coordinates` suspects
#: millimetres given as metres: a 4 x 4 URA of the largest plausible pitch
#: (:data:`URA_PITCH_M`, 0.5 m) reaches 0.75 m from its centre
PLAUSIBLE_COORDINATE_M = 1.0


def _warn_millimetres(source: str, yz_m: np.ndarray) -> None:
    """A :class:`processing.UnitsWarning` when coordinates (M, 2) reach beyond
    :data:`PLAUSIBLE_COORDINATE_M`: legal, but more likely millimetres."""
    far = float(np.abs(yz_m).max())
    if far > PLAUSIBLE_COORDINATE_M:
        warnings.warn(
            f"{source}: coordinates reach {far:g} m from the origin: metres expected; "
            f"millimetres given as metres? In metres they would reach {far * 1e-3:g} m",
            UnitsWarning,
            stacklevel=4,  # the caller of from_coordinates (through its keyword check)
        )


def from_coordinates_file(
    path: str | Path,
    *,
    units: str = "mm",
    name: str | None = None,
    variable: str = "mic_pos_final_pos",
) -> Array:
    """Read an array from a coordinates file.

    Supported: ``.mat`` (variable `variable`, an (M, 2) table of (y, z), the form of
    CoSys-Lab's layout files; MATLAB v5 through scipy, v7.3 through h5py) and text
    (``.csv``/``.txt``: two columns y, z, comma or white-space separated, '#'
    comments).  `units` is 'mm' or 'm'.  NaN rows mark
    unused channels.  Positions are centred on their centroid.  A file that cannot be
    used raises :class:`processing.base.errors.InputError` naming it.
    """
    path = Path(path)
    scale = {"mm": 1e-3, "m": 1.0}.get(units)
    if scale is None:
        raise InputError("must be 'mm' or 'm'", file=path, key="units", value=units)
    if not path.is_file():
        raise InputError("array coordinates file not found", file=path)
    if path.suffix.lower() == ".mat":
        table = _read_mat(path, variable)
    else:
        try:
            text = path.read_text().replace(",", " ")
            table = np.loadtxt(text.splitlines(), ndmin=2, comments="#")
        except (ValueError, UnicodeDecodeError) as exc:
            raise InputError(f"not a table of numbers ({exc})", file=path) from None
    try:
        return from_coordinates(table * scale, name=name or path.stem, source=str(path))
    except InputError:
        raise
    except ValueError as exc:
        raise InputError(str(exc), file=path) from None


def _read_mat(path: Path, variable: str) -> np.ndarray:
    """`variable` of a MATLAB file as a float table: v4-v7 with scipy, v7.3 (HDF5,
    stored column-major, so transposed here) with h5py."""
    import h5py

    if h5py.is_hdf5(path):
        with h5py.File(path, "r") as f:
            found = [k for k in f if not k.startswith("#")]
            if variable not in found or not isinstance(f[variable], h5py.Dataset):
                raise InputError(f"no variable {variable!r} (found {found})", file=path)
            data = f[variable]
            if data.ndim != 2 or data.size > 1_000_000 or data.dtype.kind not in "fiu":
                raise InputError(
                    f"{variable!r} must be a numeric (M, 2) table, got {data.dtype} "
                    f"{data.shape[::-1]}",
                    file=path,
                )
            return np.asarray(data[()], dtype=float).T
    from scipy.io import loadmat

    try:
        data = loadmat(path)
    except (ValueError, TypeError, NotImplementedError, OSError) as exc:
        raise InputError(f"not a readable MATLAB file ({exc})", file=path) from None
    if variable not in data:
        found = [k for k in data if not k.startswith("__")]
        raise InputError(f"no variable {variable!r} (found {found})", file=path)
    try:
        return np.asarray(data[variable], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{variable!r} is not a numeric table", file=path) from None


def ertis_v3d1(path: str | Path | None = None) -> Array:
    """The eRTIS v3D1: 32 microphones in a pseudo-random layout.

    The layout is read from CoSys-Lab's layout file: `path`, or the copy inside the
    public rtisdev wheel, fetched once into the user cache (see
    :mod:`processing.sensor.rtisdev`).  Its license forbids bundling it here.
    """
    if path is None:
        from processing.sensor.rtisdev import layout_file

        try:
            path = layout_file("eRTIS_v3D1")
        except (OSError, RuntimeError) as exc:  # no network, no pip, a damaged cache
            raise InputError(
                f"the eRTIS v3D1 layout comes from the rtisdev wheel, which is not available "
                f"({exc}); connect once to cache it, or give the layout file "
                "(sensor.coordinates in a scene)",
                key="array",
                value="ertis_v3d1",
            ) from None
    return from_coordinates_file(path, units="mm", name="ertis_v3d1")


#: the array presets by name (the scene file's ``[sensor] array``): their functions
PRESETS = {
    "paper_8x8": paper_8x8,
    "urtis_v1": urtis_v1,
    "ertis_v3d1": ertis_v3d1,
}


def preset(name: str) -> Array:
    """Return a preset array by name (one of :data:`PRESETS`)."""
    if name not in PRESETS:
        raise InputError(unknown_choice("array preset", name, PRESETS), key="array", value=name)
    return PRESETS[name]()
