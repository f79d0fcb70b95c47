"""Build the meshes and trajectories of the bundled scenes (run from anywhere):

    python scenes/build_scenes.py

Meshes are solids with outward normals, except the shoebox room, whose faces point
inwards (the sensor is inside it).  Everything is in metres, x forward along the
corridor, z up.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
MESHES = HERE / "meshes"


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(extents=hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


def corridor() -> trimesh.Trimesh:
    """A 2 m wide, 24 m long, 2.6 m high corridor like the paper's real run: door
    recesses with frames, a radiator, a pillar, pipes along the ceiling, an end wall."""
    L, W, H, t = 24.0, 2.0, 2.6, 0.2
    parts = [
        box([-1, -W / 2 - t, -t], [L, W / 2 + t, 0]),  # floor
        box([-1, -W / 2 - t, H], [L, W / 2 + t, H + t]),  # ceiling
        box([L, -W / 2 - t, -t], [L + t, W / 2 + t, H + t]),  # end wall
        box([-1 - t, -W / 2 - t, -t], [-1, W / 2 + t, H + t]),  # back wall
    ]
    doors = {1: [3.0, 9.5, 16.0, 21.0], -1: [5.5, 12.5, 18.5]}  # door centres per side
    for side, centres in doors.items():
        y_in = side * W / 2  # inner face of the wall
        edges = [-1.0]
        for c in centres:
            edges += [c - 0.6, c + 0.6]
        edges.append(L)
        for a, b in zip(edges[0::2], edges[1::2]):  # wall segments between recesses
            y0, y1 = sorted([y_in, y_in + side * t])
            parts.append(box([a, y0, 0], [b, y1, H]))
        for c in centres:
            # recess 0.25 m deep with a door leaf at its back, frames 5 cm proud
            y0, y1 = sorted([y_in + side * 0.25, y_in + side * (0.25 + 0.05)])
            parts.append(box([c - 0.6, y0, 0], [c + 0.6, y1, H]))  # door leaf
            y0, y1 = sorted([y_in + side * t, y_in + side * 0.25])
            parts.append(box([c - 0.6, y0, 2.1], [c + 0.6, y1, H]))  # wall above the door
            fy0, fy1 = sorted([y_in - side * 0.05, y_in + side * 0.02])
            for x0 in (c - 0.65, c + 0.6):  # frames
                parts.append(box([x0, fy0, 0], [x0 + 0.05, fy1, 2.15]))
    # a radiator on the left wall, a pillar on the right
    parts.append(box([7.0, W / 2 - 0.12, 0.15], [8.2, W / 2, 0.75]))
    parts.append(box([14.0, -W / 2, 0], [14.4, -W / 2 + 0.3, H]))
    # pipes along the ceiling (curved surfaces)
    for y, r in ((0.55, 0.05), (0.75, 0.035)):
        pipe = trimesh.creation.cylinder(radius=r, height=L + 1, sections=24)
        pipe.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
        pipe.apply_translation([L / 2 - 0.5, y, H - 0.15])
        parts.append(pipe)
    return trimesh.util.concatenate(parts)


def drive(rate_hz: float = 10.0, duration_s: float = 6.0) -> np.ndarray:
    """Rows [x, y, z, yaw_deg]: a robot at 0.5 m/s weaving gently down the corridor."""
    t = np.arange(0, duration_s, 1 / rate_hz)
    x = 0.5 + 0.5 * t
    y = 0.08 * np.sin(2 * np.pi * t / 6.0)
    yaw = np.rad2deg(np.arctan2(np.gradient(y, x), 1.0))
    return np.column_stack([x, y, np.full_like(x, 0.45), yaw])


def panel_wall() -> str:
    """An OBJ of a wall (plane x = 2, facing -x, y and z within +-2 m) with a 1 m
    square panel in its middle, as two groups, ``wall`` and ``panel`` (the wall's
    faces leave the panel's square free)."""
    ys, zs = [-2.0, -0.5, 0.5, 2.0], [-1.5, -0.5, 0.5, 1.5]
    verts, groups = [], {"wall": [], "panel": []}
    for i in range(3):
        for j in range(3):
            y0, y1, z0, z1 = ys[i], ys[i + 1], zs[j], zs[j + 1]
            k = len(verts) + 1
            # counter-clockwise seen from -x: the normal points to -x
            verts += [(2.0, y0, z0), (2.0, y0, z1), (2.0, y1, z1), (2.0, y1, z0)]
            group = "panel" if (i, j) == (1, 1) else "wall"
            groups[group] += [(k, k + 1, k + 2), (k, k + 2, k + 3)]
    lines = ["# a wall with a panel in its middle: groups 'wall' and 'panel'", "o panel_wall"]
    lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in verts]
    for name, faces in groups.items():
        lines.append(f"g {name}")
        lines += [f"f {a} {b} {c}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


def main() -> None:
    MESHES.mkdir(exist_ok=True)
    corridor().export(MESHES / "corridor.stl")
    np.savetxt(
        HERE / "corridor_drive.csv",
        drive(),
        delimiter=",",
        fmt="%.4f",
        header="x_m, y_m, z_m, yaw_deg at 10 Hz",
    )
    room = box([-1.0, -1.6, -1.1], [3.2, 1.9, 1.5])
    room.invert()  # normals inwards: the sensor is inside the room
    room.export(MESHES / "shoebox.stl")
    box([2.0, -5.0, -5.0], [2.1, 5.0, 5.0]).export(MESHES / "wall.stl")
    box([-0.01, -0.5, -0.5], [0.01, 0.5, 0.5]).export(MESHES / "plate.stl")  # 1 m x 1 m
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.2)
    sphere.apply_translation([1.5, 0.0, 0.0])
    sphere.export(MESHES / "sphere.stl")
    (MESHES / "panel_wall.obj").write_text(panel_wall())
    print(f"wrote meshes to {MESHES}")


if __name__ == "__main__":
    main()
