"""Image peaks as rows: the columns of ``peaks.csv``, declared once.

:class:`PeakRow` is the one declaration of the columns (name, unit, meaning, in
order): the ``peaks.csv`` writer (:func:`acousim.export.write_peaks_csv`) writes its
fields as the header and each row's values, and a :class:`PeakTable` (what
:meth:`processing.Peaks.table` and :func:`acousim.peak_table` return) is a sequence
of them. Adding a column is one ``column(...)`` line in :class:`PeakRow` (with a
default for the peaks that have no value) and the line that fills it.

A table hands itself to pandas or polars without either being imported here::

    pandas.DataFrame(table.to_records())      # or pandas.DataFrame(table.as_dict())
    polars.DataFrame(table.as_dict())
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, overload

__all__ = ["PeakRow", "PeakTable", "PEAK_COLUMNS", "column", "column_units"]


def column(unit: str, doc: str, default: Any = dataclasses.MISSING) -> Any:
    """A field of :class:`PeakRow`: its `unit` ("" when none) and meaning `doc`."""
    meta = {"unit": unit, "doc": doc}
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


NAN = math.nan


@dataclass(frozen=True)
class PeakRow:
    """One peak of an image: one row of ``peaks.csv`` (the same columns, in order).

    Angles in degrees (azimuth positive to the left, +y; elevation positive up, +z),
    lengths in metres, levels in dB. Frames: sensor (x forward, y left, z up) and
    world (through the recording's pose; the sensor frame without one). A column
    without a value is NaN (numbers), "" (text) or None (the recording index,
    truth_order, truth_behind); peaks.csv writes each of them as an empty cell.
    """

    recording: int | None = column("", "index of the recording in its file", None)
    method: str = column("", "imaging method (processing.METHODS)", "")
    range_m: float = column("m", "range from the array centre", NAN)
    azimuth_deg: float = column("deg", "azimuth, positive to the left (+y)", NAN)
    elevation_deg: float = column("deg", "elevation, positive up (+z)", NAN)
    level_db: float = column("dB", "level re the strongest cell of that image", NAN)
    x_m: float = column("m", "sensor frame: x forward", NAN)
    y_m: float = column("m", "sensor frame: y left", NAN)
    z_m: float = column("m", "sensor frame: z up", NAN)
    world_x_m: float = column("m", "world frame, through the recording's pose", NAN)
    world_y_m: float = column("m", "world frame", NAN)
    world_z_m: float = column("m", "world frame", NAN)
    on_grid_edge: bool = column(
        "", "on the grid's first/last azimuth or elevation (may not be a peak)", False
    )
    truth_kind: str = column(
        "", "the traced path shown in the peak's resolution cell ('' if none)", ""
    )
    truth_order: int | None = column(
        "", "its reflections (an edge counts as one); None: no truth", None
    )
    truth_object: str = column("", "what it last touched: '<mesh>/<material>' or 'point <i>'", "")
    truth_emitter: str = column(
        "", "the sonar whose call it carries (a rig's recording: crosstalk when not its own)", ""
    )
    truth_x_m: float = column(
        "m", "its apparent position (where the image shows it), sensor frame", NAN
    )
    truth_y_m: float = column("m", "its apparent position, sensor frame", NAN)
    truth_z_m: float = column("m", "its apparent position, sensor frame", NAN)
    truth_level_db: float = column("dB", "its level re the strongest traced echo", NAN)
    truth_offset_deg: float = column("deg", "angle between the peak and the apparent position", NAN)
    truth_range_offset_m: float = column("m", "the apparent position's range less the peak's", NAN)
    truth_behind: bool | None = column(
        "", "behind the array, heard as its mirror (-x, y, z); None: no truth", None
    )
    truth_note: str = column("", "why the peak has no truth ('' when it has one)", "")
    provenance: str = column("", "the recording's: simulated, real or emulated", "")

    def as_dict(self) -> dict[str, Any]:
        """The row as {column: value} (:data:`PEAK_COLUMNS` order)."""
        return {name: getattr(self, name) for name in PEAK_COLUMNS}


#: the columns of ``peaks.csv`` and of every :class:`PeakRow`, in order
PEAK_COLUMNS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(PeakRow))


def column_units() -> dict[str, str]:
    """{column: unit} of :data:`PEAK_COLUMNS` ("" when it has none)."""
    return {f.name: f.metadata["unit"] for f in dataclasses.fields(PeakRow)}


class PeakTable(Sequence[PeakRow]):
    """Peaks as rows (:class:`PeakRow`), strongest first per image: ``len``, indexing
    (an int gives a row, a slice a table), iteration; :meth:`to_records` and
    :meth:`as_dict` for a data frame (units: :func:`column_units`)."""

    def __init__(self, rows: Sequence[PeakRow] = ()) -> None:
        self.rows: tuple[PeakRow, ...] = tuple(rows)

    def __len__(self) -> int:
        return len(self.rows)

    @overload
    def __getitem__(self, i: int) -> PeakRow: ...

    @overload
    def __getitem__(self, i: slice) -> PeakTable: ...

    def __getitem__(self, i: int | slice) -> PeakRow | PeakTable:
        if isinstance(i, slice):
            return PeakTable(self.rows[i])
        return self.rows[i]

    def __iter__(self) -> Iterator[PeakRow]:
        return iter(self.rows)

    def __add__(self, other: PeakTable) -> PeakTable:
        return PeakTable(self.rows + tuple(other))

    @property
    def columns(self) -> tuple[str, ...]:
        """:data:`PEAK_COLUMNS`."""
        return PEAK_COLUMNS

    def to_records(self) -> list[dict[str, Any]]:
        """One {column: value} dict per row (``pandas.DataFrame(table.to_records())``)."""
        return [row.as_dict() for row in self.rows]

    def as_dict(self) -> dict[str, list[Any]]:
        """{column: list of values}, every column even with no rows
        (``pandas.DataFrame(...)``, ``polars.DataFrame(...)``)."""
        return {name: [getattr(r, name) for r in self.rows] for name in PEAK_COLUMNS}

    def __repr__(self) -> str:
        head = f"PeakTable({len(self)} peaks"
        if not self.rows:
            return head + ")"
        lines = [
            f"  {r.method or '-'} {r.range_m:.3f} m az {r.azimuth_deg:+.1f} deg "
            f"el {r.elevation_deg:+.1f} deg {r.level_db:.1f} dB"
            + (f" truth {r.truth_kind}" if r.truth_kind else "")
            for r in self.rows[:5]
        ]
        more = [f"  ... {len(self) - 5} more"] if len(self) > 5 else []
        return "\n".join([head + ":", *lines, *more]) + ")"
