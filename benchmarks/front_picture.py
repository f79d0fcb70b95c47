"""The front's picture (docs/front.png): time per measurement against the error, drawn
for a reader choosing a setting.

Each point is a marker (a star per quality preset, a circle per knob setting coloured by
its knob; filled when the image's peaks are unchanged). Labels are placed here, without
overlap: each tries positions around its point, nearest first (a leader line when it
lands away from it), and keeps the first that covers no marker, no other label and stays
inside the axes. Knob settings crowded together (three or more within a label's size of
each other, or stacked in one column) are boxed, lettered and listed in the panel with
their numbers instead, the list beside its box where it covers nothing; a label that
finds no free place is listed likewise rather than lost. The grey band is the spread of
the times of the settings whose errors equal the default's (within 0.1 dB): this run's
noise on time. A panel where every preset's time lies inside it says so. The legend is
outside the axes. The reference run is the errors' zero and its time is not drawn: the
one time near it is the "reference" preset's star (paired with the defaults; the
reference run, that preset with the renderer's knobs at their finest, is timed once,
unpaired, and its time is in the section's text).

Drawn from the points :func:`benchmarks.front.load` reads (benchmarks/data/front.json):
``python -m benchmarks.front --redraw``.
"""

from __future__ import annotations

import string
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from benchmarks.front import FLOOR_DB, Point

#: gid of a point's marker and of a label (tests read the figure back by these)
POINT_GID = "front-point"
LABEL_GID = "front-label"
GROUP_GID = "front-group"
#: errors within this of the default's: the same output, for the noise band (dB)
SAME_DB = 0.1
DPI = 90
#: points within this of each other (px, x and y) are crowded; and in one column (x
#: within COLUMN_PX[0]) within COLUMN_PX[1]
CROWD_PX = (34.0, 11.0)
COLUMN_PX = (4.0, 24.0)
PANELS = (("waveform_db", "waveform"), ("image_db", "DAS image"))


def draw(results: Mapping[str, tuple[Point, list[Point]]], path: Path) -> None:
    """Draw `results` (per scene: the reference's point and the variants') to `path`
    (PNG, written atomically)."""
    import matplotlib.pyplot as plt

    from processing.base.atomic import atomic_path

    fig = figure(results)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")
    plt.close(fig)


def figure(results: Mapping[str, tuple[Point, list[Point]]]):
    """The figure (matplotlib, Agg): a row per scene, time against the waveform and
    the image residual."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = len(results)
    fig, axes = plt.subplots(rows, 2, figsize=(15, 5.6 * rows + 0.9), dpi=DPI, squeeze=False)
    fig.subplots_adjust(
        left=0.06,
        right=0.83,
        top=1 - 1.0 / (5.6 * rows + 0.9),
        bottom=0.9 / (5.6 * rows + 0.9),
        hspace=0.32,
        wspace=0.16,
    )
    knobs = list(
        dict.fromkeys(
            p.variant.knob for _, ps in results.values() for p in ps if p.variant.quality is None
        )
    )
    colours = dict(zip(knobs, plt.get_cmap("tab10").colors))
    letters = iter(string.ascii_uppercase)
    for row, (name, (_, points)) in zip(axes, results.items()):
        for ax, (attr, what) in zip(row, PANELS):
            _panel(ax, name, what, attr, points, colours, letters)
    _legend(fig, knobs, colours)
    fig.suptitle(
        "Run time against error, one knob at a time from the scene's defaults", fontsize=13
    )
    fig.text(
        0.06,
        0.008,
        "Errors re a reference run: the reference preset with the renderer's knobs at their "
        f"finest; an error of none (identical output) is drawn at {FLOOR_DB:.0f} dB.\n"
        "Filled: the image's peaks within 30 dB unchanged.  Numbers: BENCHMARKS.md "
        "(benchmarks/data/front.json).",
        fontsize=8.5,
        color="0.3",
    )
    return fig


def _panel(
    ax, scene: str, what: str, attr: str, points: Sequence[Point], colours, letters: Iterator[str]
) -> None:
    xs = {id(p): getattr(p, attr) for p in points}
    for p in points:
        _marker(ax, xs[id(p)], p, colours)
    _axes(ax, [xs[id(p)] for p in points], [p.ms for p in points], what)
    note = _noise(ax, points)
    ax.set_title(
        f"{scene}: time against {what} error" + (f"\n{note}" if note else ""), fontsize=10.5
    )
    place = _Placer(ax)
    knobs = [p for p in points if p.variant.quality is None]
    groups = sorted(
        (g for g in _crowds(ax, knobs, xs) if len(g) >= 3),
        key=lambda g: min(xs[id(p)] for p in g),  # lettered left to right
    )
    grouped = {id(p) for g in groups for p in g}
    boxes = [_group_box(ax, g, xs, place) for g in groups]
    for p in points:
        place.block(_marker_box(ax, xs[id(p)], p))
    alone = [p for p in points if id(p) not in grouped]
    unplaced = [p for p in sorted(alone, key=_is_knob) if not _label(place, xs, p, colours)]
    for g, box in zip(groups, boxes):
        letter = next(letters)
        place.label(
            box.x1, box.y1, letter, colour="0.2", gap=2, px=True, fontsize=10, weight="bold"
        )
        header = f"{letter}: the {len(g)} settings in box {letter}"
        _group_list(ax, header, g, xs, colours, place, box)
    if unplaced:  # no free place near them (not seen yet): listed rather than lost
        near = _marker_box(ax, xs[id(unplaced[0])], unplaced[0])
        _group_list(ax, "no room for their labels:", unplaced, xs, colours, place, near)


def _is_knob(p: Point) -> bool:
    return p.variant.quality is None


def _label(place: _Placer, xs, p: Point, colours):
    """Label `p` (a preset's label bold, a knob setting's in its knob's ink)."""
    preset = p.variant.quality is not None
    c = "k" if preset else _ink(colours[p.variant.knob])
    style = dict(fontsize=10.5, weight="bold") if preset else dict(fontsize=8)
    return place.label(xs[id(p)], p.ms, p.variant.label, colour=c, gap=_radius(p), **style)


def _marker(ax, x: float, p: Point, colours) -> None:
    same = p.lost == 0 and p.added == 0
    if p.variant.quality is not None:
        style = dict(marker="*", ms=17, mfc="k" if same else "w", mec="k", mew=1.3, zorder=5)
    else:
        c = colours[p.variant.knob]
        style = dict(marker="o", ms=7, mfc=c if same else "w", mec=c, mew=1.6, zorder=4)
    ax.plot([x], [p.ms], ls="", gid=POINT_GID, **style)


def _radius(p: Point) -> float:
    """The marker's radius (px)."""
    return (17 if p.variant.quality is not None else 7) * DPI / 72 / 2


def _marker_box(ax, x: float, p: Point):
    from matplotlib.transforms import Bbox

    px, py = ax.transData.transform((x, p.ms))
    r = _radius(p) + 1
    return Bbox([[px - r, py - r], [px + r, py + r]])


def _axes(ax, xs: Sequence[float], ms: Sequence[float], what: str) -> None:
    from matplotlib.ticker import FuncFormatter, LogLocator

    lo, hi = min(xs), max(xs)
    span = max(hi - lo, 10.0)
    ax.set_xlim(lo - 0.06 * span, hi + 0.06 * span)
    ax.set_yscale("log")
    ax.set_ylim(min(ms) / 1.35, max(ms) * 1.5)
    ax.xaxis.set_major_formatter(
        FuncFormatter(lambda v, _: "none" if abs(v - FLOOR_DB) < 1e-9 else f"{v:g}")
    )
    if lo <= FLOOR_DB:
        ax.set_xticks(sorted({FLOOR_DB, *[t for t in ax.get_xticks() if t > FLOOR_DB + 10]}))
        ax.set_xlim(lo - 0.06 * span, hi + 0.06 * span)
    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_minor_locator(LogLocator(subs=np.arange(1, 10)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
    ax.set_xlabel(f"{what} residual re the reference (dB; none: identical output)")
    ax.set_ylabel("ms per measurement (log)")
    ax.grid(True, which="major", alpha=0.35)
    ax.grid(True, which="minor", alpha=0.12)


def _noise(ax, points: Sequence[Point]) -> str:
    """Shade the times of the settings with the default's errors; the panel's note."""
    default = next((p for p in points if p.variant.quality == "default"), None)
    if default is None:
        return ""
    same = [
        p
        for p in points
        if abs(p.waveform_db - default.waveform_db) <= SAME_DB
        and abs(p.image_db - default.image_db) <= SAME_DB
    ]
    if len(same) < 3:
        return ""
    lo, hi = min(p.ms for p in same), max(p.ms for p in same)
    ax.axhspan(lo, hi, color="0.5", alpha=0.16, lw=0, zorder=0, gid="front-noise")
    note = (
        f"grey: run-to-run noise, {lo:.0f}-{hi:.0f} ms "
        f"(the {len(same)} settings with the default's errors)"
    )
    presets = [p.ms for p in points if p.variant.quality is not None]
    if all(lo <= t <= hi for t in presets):
        note += "\nevery preset's time lies in it: choose here by error, not time"
    return note


#: directions tried around a point, in order (degrees: right first, then left, up, down)
ANGLES = np.deg2rad([0, 25, -25, 180, 155, 205, 90, 270, 50, -50, 130, 230])
#: distances tried from a marker's edge (px); beyond NEAR a leader line is drawn
RADII = (3, 10, 20, 32, 48, 68, 92, 120)
NEAR = 12


class _Placer:
    """Places texts in an axes where they cover nothing placed before (display px)."""

    def __init__(self, ax) -> None:
        self.ax = ax
        self.renderer = ax.figure.canvas.get_renderer()
        self.area = ax.get_window_extent(self.renderer).padded(-2)
        self.taken: list = []
        self.lists: list = []  # the crowds' lists among the taken

    def block(self, box) -> None:
        self.taken.append(box)

    def fits(self, box) -> bool:
        inside = self.area.contains(box.x0, box.y0) and self.area.contains(box.x1, box.y1)
        return inside and not any(box.overlaps(t) for t in self.taken)

    def size(self, text: str, **style) -> tuple[float, float]:
        t = self.ax.text(0, 0, text, **style)
        box = t.get_window_extent(self.renderer)
        t.remove()
        return box.width, box.height

    def label(
        self, x: float, y: float, text: str, *, colour, gap: float, px: bool = False, **style
    ):
        """Annotate (x, y) (data, or display px with `px`) with `text` at the nearest
        free place; None when there is none."""
        from matplotlib.transforms import Bbox

        at = (x, y) if px else tuple(self.ax.transData.transform((x, y)))
        w, h = self.size(text, **style)
        for r in RADII:
            for a in ANGLES:
                c, s = np.cos(a), np.sin(a)
                dx, dy = (gap + r) * c, (gap + r) * s
                ha = "left" if c > 0.3 else "right" if c < -0.3 else "center"
                va = "bottom" if s > 0.3 else "top" if s < -0.3 else "center"
                x0 = at[0] + dx - {"left": 0, "right": w, "center": w / 2}[ha]
                y0 = at[1] + dy - {"bottom": 0, "top": h, "center": h / 2}[va]
                box = Bbox.from_bounds(x0, y0, w, h).padded(1.0)
                if not self.fits(box):
                    continue
                line = dict(arrowstyle="-", color=colour, lw=0.7, shrinkA=0, shrinkB=gap * 72 / DPI)
                self.ax.annotate(
                    text,
                    at if px else (x, y),
                    xycoords="figure pixels" if px else "data",
                    xytext=(dx, dy),
                    textcoords="offset pixels",
                    ha=ha,
                    va=va,
                    color=colour,
                    arrowprops=line if r > NEAR else None,
                    gid=LABEL_GID,
                    zorder=6,
                    **style,
                )
                self.block(box)
                return box
        return None


def _crowds(ax, points: Sequence[Point], xs) -> list[list[Point]]:
    """`points` in groups linked by neighbours closer than CROWD_PX or COLUMN_PX
    (display px)."""
    at = [ax.transData.transform((xs[id(p)], p.ms)) for p in points]
    group = list(range(len(points)))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    for i in range(len(points)):
        for j in range(i):
            dx, dy = abs(at[i] - at[j])
            if (dx < CROWD_PX[0] and dy < CROWD_PX[1]) or (dx < COLUMN_PX[0] and dy < COLUMN_PX[1]):
                group[root(i)] = root(j)
    out: dict[int, list[Point]] = {}
    for i, p in enumerate(points):
        out.setdefault(root(i), []).append(p)
    return list(out.values())


def _group_box(ax, group: Sequence[Point], xs, place: _Placer):
    """A dashed box around a crowd's markers (display px box returned and blocked)."""
    from matplotlib.patches import Rectangle
    from matplotlib.transforms import Bbox

    at = np.array([ax.transData.transform((xs[id(p)], p.ms)) for p in group])
    pad = _radius(group[0]) + 3
    box = Bbox([at.min(axis=0) - pad, at.max(axis=0) + pad])
    ax.add_patch(
        Rectangle(
            (box.x0, box.y0),
            box.width,
            box.height,
            transform=None,
            fill=False,
            ls="--",
            lw=0.9,
            ec="0.35",
            zorder=3,
            gid=GROUP_GID,
        )
    )
    place.block(box)
    return box


def _group_list(ax, header: str, group: Sequence[Point], xs, colours, place: _Placer, near):
    """The crowd's settings, one a line with their time and error, in the axes' corner
    or side that covers nothing (the least) and lies nearest the crowd's box `near`."""
    from matplotlib.offsetbox import AnchoredOffsetbox

    tried = []
    spots = [(loc, None) for loc in range(1, 11)]  # the axes' corners and sides
    for k, (loc, anchor) in enumerate(spots):
        where = {} if anchor is None else {"bbox_to_anchor": anchor, "bbox_transform": ax.transAxes}
        box = AnchoredOffsetbox(
            loc,
            child=_list(header, group, xs, colours),
            frameon=True,
            pad=0.3,
            borderpad=0.4,
            **where,
        )
        box.patch.set(fc="white", ec="0.6", alpha=0.92, lw=0.6)
        box.set_gid(GROUP_GID)
        ax.add_artist(box)
        extent = box.get_window_extent(place.renderer)
        # what it covers; another list covered by a tenth of it or more counts as
        # three things covered (it hides several lines at once)
        others = [t for t in place.taken if not any(t is x for x in place.lists)]
        cost = sum(extent.overlaps(t) for t in others) + 3 * sum(
            _shared_area(extent, t) > 0.1 * _area(t) for t in place.lists
        )
        far = np.hypot(*(np.mean(extent.get_points(), 0) - np.mean(near.get_points(), 0)))
        tried.append((cost, far, k, box, extent))
    tried.sort(key=lambda t: t[:3])
    for *_, box, _ in tried[1:]:
        box.remove()
    place.block(tried[0][-1])
    place.lists.append(tried[0][-1])


def _area(b) -> float:
    return b.width * b.height


def _shared_area(a, b) -> float:
    """The area (display units²) two boxes share."""
    return max(min(a.x1, b.x1) - max(a.x0, b.x0), 0.0) * max(min(a.y1, b.y1) - max(a.y0, b.y0), 0.0)


def _list(header: str, group: Sequence[Point], xs, colours):
    from matplotlib.offsetbox import TextArea, VPacker

    bold = dict(fontsize=8, weight="bold")
    lines = [TextArea(header, textprops=bold)]
    order = ["preset", *colours]
    for p in sorted(group, key=lambda p: (order.index(p.variant.knob), -xs[id(p)])):
        mark = "\u25cf" if p.lost == 0 and p.added == 0 else "\u25cb"
        text = f"{mark} {p.variant.knob} {p.variant.label}: {p.ms:.0f} ms, {_db(xs[id(p)])}"
        ink = dict(fontsize=8, color=_ink(colours.get(p.variant.knob, (0, 0, 0))))
        lines.append(TextArea(text, textprops=ink))
    return VPacker(children=lines, align="left", pad=0, sep=1.5)


def _ink(colour) -> tuple[float, float, float]:
    """A knob's colour darkened for text (the light ones, olive and grey, read on white)."""
    return tuple(0.75 * v for v in colour[:3])


def _db(x: float) -> str:
    return "none" if x <= FLOOR_DB else f"{x:.1f} dB"


def _legend(fig, knobs: Sequence[str], colours) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle

    handles = [
        Line2D([], [], marker="o", ls="", ms=7, mfc=colours[k], mec=colours[k], label=k)
        for k in knobs
    ]
    handles += [
        Line2D([], [], marker="*", ls="", ms=14, mfc="k", mec="k", label="quality preset"),
        Line2D(
            [],
            [],
            marker="o",
            ls="",
            ms=7,
            mfc="w",
            mec="k",
            mew=1.4,
            label="open: image peaks changed",
        ),
        Patch(
            fc="0.5",
            alpha=0.16,
            label="time noise: the times of\nsettings with the default's\nerrors",
        ),
        Rectangle(
            (0, 0),
            1,
            1,
            fill=False,
            ls="--",
            ec="0.35",
            label="crowded settings,\nlisted by letter",
        ),
    ]
    fig.legend(
        handles=handles,
        loc="center left",
        bbox_to_anchor=(0.845, 0.5),
        fontsize=9,
        title="knob",
        frameon=False,
    )
