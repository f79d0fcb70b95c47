"""The drive's plan view: the scene cut by the sensor's horizontal plane, seen from
above in the sensor's frame (its axis up, its left to the left: the fan's axes), with
what the 3D view draws: the traced echoes where the sensor sees them, the paths of
the strongest, the image's peaks, the LiDAR's points, the moving meshes, the sensor's
sweep during its measurement and the drive's track.

Drawn straight from arrays, for an animation's frames: the section is a vectorised
triangle-plane intersection (:func:`plane_section`), each kind of thing one matplotlib
artist made once, its data replaced per frame and drawn by blitting
(:class:`PlanPanel`).  The sensor stays where it is (the origin, pointing up), so it,
the axes and their ticks are in the figure's background; the world moves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from acousim.viz.fan import FAN_ELEVATION_BAND_RAD
from acousim.viz.render3d import (
    AXIS_LENGTH_M,
    CHAIN_COLOR,
    LIDAR_COLOR,
    MOVING_COLOR,
    PEAK_COLOR,
    SENSOR_COLOR,
    SWEEP_COLOR,
    TRUTH_COLOR,
    WEDGE_LENGTH_M,
    FrameContent,
)

__all__ = [
    "PlanPanel",
    "PlanScene",
    "drive_track",
    "plane_section",
    "sensor_rotation",
    "to_sensor_frame",
    "SECTION_COLOR",
    "TRACK_COLOR",
]

SECTION_COLOR = (0.25, 0.25, 0.28)  # the scene cut at the sensor's height: dark grey
TRACK_COLOR = (0.55, 0.55, 0.58)  # the drive's track: grey, dotted
#: the plan shows at least this much behind the sensor (m)
BEHIND_M = 0.6
#: the LiDAR's points drawn: those within this of the sensor's plane (m), a slice
#: of the scan as the section is of the meshes (its floor and ceiling rings, seen
#: from above, would be arcs across the plan where nothing stands)
LIDAR_SLICE_M = 0.25


def to_sensor_frame(points_world: np.ndarray, position_m: np.ndarray, rotation: np.ndarray):
    """Points (..., 3) in the world frame (m) in the sensor's frame at `position_m`
    (3,) with `rotation` (3, 3) (sensor -> world: its columns are the sensor's x
    forward, y left, z up in the world): ``R^T (p - position)``, (..., 3)."""
    p = np.asarray(points_world, float)
    flat = (p.reshape(-1, 3) - np.asarray(position_m, float)) @ np.asarray(rotation, float)
    return flat.reshape(p.shape)  # one (N, 3) x (3, 3) product, not N small ones


def sensor_rotation(content: FrameContent) -> np.ndarray:
    """The sensor's rotation (3, 3), sensor -> world, of a frame: its own, or (a
    frame without it) the one that points x along its axis with z as near the world's
    up as the axis allows."""
    if content.sensor_rotation is not None:
        return np.asarray(content.sensor_rotation, float)
    x = np.asarray(content.sensor_axis, float)
    x = x / np.linalg.norm(x)
    up = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
    y = np.cross(up, x)
    y /= np.linalg.norm(y)
    return np.column_stack([x, y, np.cross(x, y)])


def plane_section(triangles: np.ndarray) -> np.ndarray:
    """Where triangles (F, 3, 3) cross the plane z = 0: segments (S, 2, 2), each two
    (x, y) end points (the triangles' own units).

    Algorithm:
    1. Each vertex's height z; a vertex exactly on the plane counts as just above
       it (a face lying in the plane, or touching it at a vertex, gives no segment;
       an edge on the plane is given by the face below it).
    2. A triangle crosses the plane when its vertices' heights differ in sign: then
       exactly two of its edges cross it.
    3. Each crossing edge (a, b) meets the plane at ``a + (b - a) za / (za - zb)``.
    """
    tri = np.asarray(triangles, float).reshape(-1, 3, 3)
    z = tri[..., 2]
    above = z >= 0.0
    crossing = above.any(axis=1) & ~above.all(axis=1)
    tri, z, above = tri[crossing], z[crossing], above[crossing]
    a, b = tri, np.roll(tri, -1, axis=1)  # edges (0, 1), (1, 2), (2, 0)
    za, zb = z, np.roll(z, -1, axis=1)
    cuts = above != np.roll(above, -1, axis=1)  # (S, 3): two per triangle
    t = np.divide(za, za - zb, out=np.zeros_like(za), where=cuts)
    points = a[..., :2] + (b[..., :2] - a[..., :2]) * t[..., None]
    order = np.argsort(~cuts, axis=1, kind="stable")[:, :2]  # the two crossing edges
    return np.take_along_axis(points, order[..., None], axis=1)


def _section(triangles, position_m: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """The plan's segments (S, 2, 2) of world `triangles` (F, 3, 3) cut by the plane
    of the sensor at `position_m` turned by `rotation`: each vertex's height over
    that plane first, then only the faces that cross it turned into the sensor's
    frame (a subdivided mesh of 725k faces: a few thousand)."""
    if triangles is None or not len(triangles):
        return np.empty((0, 2, 2))
    tri = np.asarray(triangles, float)
    up = np.asarray(rotation, float)[:, 2]  # the sensor's z in the world
    above = (tri.reshape(-1, 3) @ up >= np.dot(position_m, up)).reshape(-1, 3)
    crossing = above.any(axis=1) & ~above.all(axis=1)
    return _yx(plane_section(to_sensor_frame(tri[crossing], position_m, rotation)))


def _yx(points: np.ndarray) -> np.ndarray:
    """Sensor-frame points (..., >= 2) as the plan's axes take them: (y, x)."""
    return np.asarray(points)[..., [1, 0]]


def drive_track(positions_m: np.ndarray | Sequence, sensors=None) -> np.ndarray:
    """The drive's track for :class:`PlanScene`: the sensor's positions (K, 3)
    (world, m) in the order of the recordings; with `sensors` (K,) (a rig's: each
    recording's sonar) one track per sonar, in order of first firing, a row of NaN
    between two (no line from one sonar's corner to the next's)."""
    pos = np.asarray(positions_m, float).reshape(-1, 3)
    if sensors is None:
        return pos
    names = list(dict.fromkeys(sensors))
    gap = np.full((1, 3), np.nan)
    parts = [[pos[[s == n for s in sensors]], gap] for n in names]
    return np.concatenate([a for part in parts for a in part][:-1])


def _off_plane(points: np.ndarray) -> np.ndarray:
    """(N,) bool: sensor-frame points (N, 3) more than the fan's elevation band
    (:data:`acousim.viz.fan.FAN_ELEVATION_BAND_RAD`) above or below its plane."""
    elevation = np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))
    return np.abs(elevation) > FAN_ELEVATION_BAND_RAD


@dataclass(frozen=True)
class PlanScene:
    """What the plan draws in every frame: the scene's still faces (F, 3, 3) (world,
    m; None: no mesh) and the drive's track, the sensor's positions (K, 3) (world,
    m; a row of NaN between two tracks: :func:`drive_track`)."""

    triangles: np.ndarray | None
    track: np.ndarray


class PlanPanel:
    """The plan view on a matplotlib axes, for the frames of an animation.

    ax : the axes (laid out by the caller's figure); extent : (left, right, bottom,
        top) in metres of the sensor frame, as :func:`acousim.viz.fan.common_extent`
        gives the fan's (y left +, so left > right; x forward up); the plan also shows
        :data:`BEHIND_M` behind the sensor.
    scene : :class:`PlanScene`; truth_range_db : the traced echoes within this of the
        strongest are drawn (dB), the stronger larger; filled within the fan's
        elevation band (:data:`acousim.viz.fan.FAN_ELEVATION_BAND_RAD` about the
        sensor's plane), hollow rings beyond it (a floor echo below the sensor is
        not an obstacle beside it; the fan marks it "off the slice"); the image's
        peaks the same.  The LiDAR's points within :data:`LIDAR_SLICE_M` of the plane.
    entries : the legend's (label, RGB) entries of what the frames draw
        (:func:`acousim.viz.render3d.legend_entries`); the plan's own (the section,
        the track) are added by :meth:`legend_entries`.

    Call :meth:`draw` after the figure's background (with :meth:`static` drawn, the
    others hidden) was saved.
    """

    def __init__(self, ax, *, extent, scene: PlanScene, truth_range_db: float) -> None:
        from matplotlib.collections import LineCollection

        self.ax, self.scene, self.truth_range_db = ax, scene, truth_range_db
        left, right, bottom, top = extent
        ax.set_xlim(left, right)
        ax.set_ylim(min(bottom, -BEHIND_M), top)
        ax.set_aspect("equal")
        ax.set_xlabel("y (m), left +")
        ax.set_ylabel("x forward (m)")

        def lines(color, width, **kw):
            return ax.add_collection(
                LineCollection([], colors=[color], linewidths=width, animated=True, **kw)
            )

        def dots(color, size, **kw):
            return ax.scatter([], [], s=size, c=[color], animated=True, **kw)

        def rings(color, size, width):  # hollow: off the sensor's plane
            return ax.scatter(
                [], [], s=size, facecolors="none", edgecolors=[color], linewidths=width,
                animated=True,
            )  # fmt: skip

        # drawn in this order, the last on top
        self.artists = {
            "section": lines(SECTION_COLOR, 1.4),
            "moving": lines(MOVING_COLOR, 1.8),
            "track": ax.plot([], [], ":", color=TRACK_COLOR, lw=1.0, animated=True)[0],
            "sweep": lines(SWEEP_COLOR, 1.5, alpha=0.8),
            "lidar": dots(LIDAR_COLOR, 1.5, linewidths=0),
            "chains": lines(CHAIN_COLOR, 0.8),
            "truth": dots(TRUTH_COLOR, 8.0, edgecolors="none"),
            "truth off": rings(TRUTH_COLOR, 8.0, 0.9),
            "peaks": dots(PEAK_COLOR, 22.0, marker="o", edgecolors="black", linewidths=0.4),
            "peaks off": rings(PEAK_COLOR, 22.0, 1.0),
        }
        self._sensor()

    def _sensor(self) -> None:
        """The sensor: at the origin pointing up (the same in every frame), drawn on
        top of what the frame draws."""
        ax = self.ax
        self.artists["sensor axis"] = ax.annotate(
            "",
            xy=(0.0, AXIS_LENGTH_M),
            xytext=(0.0, 0.0),
            arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 1.2},
            animated=True,
        )
        self.artists["sensor"] = ax.plot(
            [0.0], [0.0], "o", ms=7, mfc=SENSOR_COLOR, mec="black", mew=0.8, animated=True
        )[0]

    def legend_entries(self, entries) -> list:
        """Legend handles: the plan's lines (the section if the scene has still faces,
        the track if the sensor moved), then `entries` ((label, RGB):
        :func:`acousim.viz.render3d.legend_entries`), lines for the paths, the sweep
        and the moving meshes, dots for the rest, and the hollow ring of the echoes
        and peaks off the sensor's plane."""
        from matplotlib.lines import Line2D

        def line(label, color, style="-"):
            return Line2D([], [], color=color, ls=style, lw=1.5, label=label)

        def dot(label, color):
            return Line2D(
                [], [], ls="", marker="o", ms=6, mfc=color, mec="black", mew=0.4, label=label
            )

        kind = {CHAIN_COLOR: line, SWEEP_COLOR: line, MOVING_COLOR: line}
        handles = []
        if self.scene.triangles is not None and len(self.scene.triangles):
            handles.append(line("scene cut at the sensor's height", SECTION_COLOR))
        track = self.scene.track[np.isfinite(self.scene.track).all(axis=1)]
        if len(track) and np.ptp(track, axis=0).max() > 0:  # the sensor moved
            handles.append(line("the drive's track", TRACK_COLOR, ":"))
        lidar = f"LiDAR points within {LIDAR_SLICE_M:g} m of its plane"
        entries = [(lidar if tuple(c) == LIDAR_COLOR else label, c) for label, c in entries]
        handles += [kind.get(tuple(c), dot)(label, c) for label, c in entries]
        band = f"{np.rad2deg(FAN_ELEVATION_BAND_RAD):g}"
        ring = Line2D([], [], ls="", marker="o", ms=6, mfc="none", mec="black", mew=0.8)
        ring.set_label(f"echo or peak hollow: over {band}° above or below its plane")
        return handles + [ring]

    def draw(self, content: FrameContent) -> None:
        """Draw one frame of `content` (world frame) in the sensor's frame (at
        ``content.sensor_position``, turned by ``content.sensor_rotation``)."""
        pos = np.asarray(content.sensor_position, float)
        rotation = sensor_rotation(content)

        def local(points):
            return to_sensor_frame(points, pos, rotation)

        a = self.artists
        a["section"].set_segments(_section(self.scene.triangles, pos, rotation))
        a["moving"].set_segments(_section(content.moving_triangles, pos, rotation))
        track = _yx(local(self.scene.track))
        a["track"].set_data(track[:, 0], track[:, 1])
        a["sweep"].set_segments(self._sweep(content, local))
        a["chains"].set_segments([_yx(local(c)) for c in content.chains])
        lidar = self._local(content.lidar, local)
        a["lidar"].set_offsets(_yx(lidar[np.abs(lidar[:, 2]) <= LIDAR_SLICE_M]))
        sizes = self._truth_sizes(content)
        truth, peaks = self._local(content.truth, local), self._local(content.peaks, local)
        off, peak_off = _off_plane(truth), _off_plane(peaks)
        for key, shown in (("truth", (sizes > 0) & ~off), ("truth off", (sizes > 0) & off)):
            a[key].set_offsets(_yx(truth[shown]))
            a[key].set_sizes(sizes[shown])
        a["peaks"].set_offsets(_yx(peaks[~peak_off]))
        a["peaks off"].set_offsets(_yx(peaks[peak_off]))
        for artist in a.values():
            self.ax.draw_artist(artist)

    @staticmethod
    def _local(points, local) -> np.ndarray:
        """World `points` (N, 3) (or None) in the sensor's frame (N, 3)."""
        if points is None or not len(points):
            return np.empty((0, 3))
        return local(np.asarray(points, float).reshape(-1, 3))

    def _truth_sizes(self, c: FrameContent) -> np.ndarray:
        """Marker areas (points^2) of the traced echoes: 3 to 8 points across from
        the threshold to the strongest (as the 3D view's spheres grow from 2 to 6 cm);
        zero for those under the range (not drawn)."""
        n = 0 if c.truth is None else len(c.truth)
        lvl = np.zeros(n) if c.truth_level_db is None else np.asarray(c.truth_level_db, float)
        dr = c.truth_range_db or self.truth_range_db
        width = 3.0 + 5.0 * np.clip(1.0 + lvl / dr, 0.0, 1.0)
        return np.where(lvl >= -dr, width**2, 0.0)

    @staticmethod
    def _sweep(c: FrameContent, local) -> list:
        """The sensor's axis at each instant of its measurement (sensor frame)."""
        if c.sweep is None:
            return []
        positions, axes = c.sweep
        tips = np.asarray(positions) + WEDGE_LENGTH_M * np.asarray(axes)
        return [_yx(local(np.stack([p, t]))) for p, t in zip(positions, tips)]
