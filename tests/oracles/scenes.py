"""Set-up the diffraction tests and benchmarks share: square plates, cubes and a thin
screen of rigid faces, in front of a uRTIS at the origin facing +x, traced at that
one pose.  Geometry only: each test keeps its own independent reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: the paper's sensor in a scene file (the 8x8 URA, the 20-85 kHz chirp at 500 kHz, no
#: direct path): a scene file's ``[sensor]`` table, its pose and the rest to follow
PAPER_SENSOR_TOML = """[sensor]
array = "paper_8x8"
call = "paper"
sample_rate_hz = 500000
direct_path = false
"""


def turn_z(deg: float) -> np.ndarray:
    """(3, 3) rotation by `deg` degrees about z."""
    t = np.deg2rad(deg)
    return np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])


def square_faces(kind: str, size: float, rotation: np.ndarray, centre) -> list[np.ndarray]:
    """Corners (4, 3), m, of a square plate of side `size` (facing -x before the
    rotation) or of a cube's six faces, rotated by `rotation` (3, 3) about their centre
    and moved to `centre` (3,)."""
    h = size / 2
    if kind == "plate":
        local = [np.array([[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]], float)]
    else:
        local = []
        for i in range(3):
            j, m = [a for a in range(3) if a != i]
            for sign in (1, -1):
                q = np.zeros((4, 3))
                q[:, i] = sign * h
                q[:, j] = [-h, h, h, -h]
                q[:, m] = [-h, -h, h, h]
                local.append(q)
    return [q @ rotation.T + np.asarray(centre, float) for q in local]


def rigid_scene(tmp: Path, quads: list[np.ndarray], simulation: dict, material=None):
    """The scene of the faces `quads` (two triangles each, written to
    tmp/object.obj) of one material (default rigid: reflection 1) before a uRTIS at
    the origin facing +x, without its direct path; `simulation` its table."""
    import trimesh

    from acousim.scene import parse_scene

    tris = np.concatenate([[q[[0, 1, 2]], q[[0, 2, 3]]] for q in quads])
    mesh = trimesh.Trimesh(tris.reshape(-1, 3), np.arange(tris.shape[0] * 3).reshape(-1, 3))
    mesh.export(tmp / "object.obj")
    material = material or {"reflection": 1.0}
    return parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False},
            "simulation": simulation,
            "materials": [{"name": "m", **material}],
            "meshes": [{"file": "object.obj", "material": "m"}],
        },
        base_dir=tmp,
    )


def first_pose(scene) -> tuple[object, np.ndarray, np.ndarray]:
    """The scene's first pose, its emitter and the array centre (world frame, m)."""
    pose = scene.sensor.poses[0]
    emitter = pose.to_world(scene.sensor.array.emitter_m)
    receiver = pose.to_world(scene.sensor.array.positions_m.mean(axis=0))
    return pose, emitter, receiver


def trace_first_pose(scene):
    """The traced paths of the scene's first pose (one thread), its emitter and the
    array centre (m)."""
    from acousim.trace.tracer import Tracer

    pose, emitter, receiver = first_pose(scene)
    return Tracer(scene, threads=1).trace(pose), emitter, receiver


def plate_paths(tmp: Path, side: float, turn_deg: float, distance: float, **simulation):
    """The paths of a square rigid plate of `side` m at `distance` m ahead, facing the
    sensor turned by `turn_deg` about z, traced with diffraction (20000 rays, one
    bounce, no energy floor; `simulation` adds or overrides settings): the paths, the
    plate's corners (4, 3), the emitter and the array centre (m)."""
    quads = square_faces("plate", side, turn_z(turn_deg), [distance, 0, 0])
    settings = {"rays": 20000, "bounces": 1, "energy_floor_db": -200.0}
    paths, emitter, receiver = trace_first_pose(rigid_scene(tmp, quads, {**settings, **simulation}))
    return paths, quads[0], emitter, receiver


def spectrum(paths, receiver: np.ndarray, k: np.ndarray, sel=None) -> np.ndarray:
    """(F,) complex pressure at `receiver` of the paths (those of the mask `sel`) at
    wavenumbers `k` (F,), rad/m; phase ``exp(-i k L)``."""
    sel = slice(None) if sel is None else sel
    last = np.linalg.norm(paths.anchor_m[sel] - receiver, axis=1)
    phase = np.exp(-1j * k[:, None] * (paths.first_leg_m[sel] + last)[None, :])
    return (paths.strength[sel] / last * phase).sum(axis=1)


def screen(angle_rad: float = 2 * np.pi, **options):
    """A wedge's edge along z from -10 to 10 m, its face 1 the half-plane y = 0,
    x > 0 (normal +y), of open angle `angle_rad` (2 pi: a thin screen); `options` go
    to :class:`acousim.trace.diffraction.btm.Wedge`."""
    from acousim.trace.diffraction.btm import Wedge

    start, end = np.array([0.0, 0, -10]), np.array([0.0, 0, 10])
    return Wedge(start, end, np.array([1.0, 0, 0]), np.array([0.0, 1, 0]), angle_rad, **options)


def turned_box_and_plate(box_size, box_centre, half_side: float, plate_centre):
    """A box of `box_size` (3,) m and a square plate of half side `half_side` m, both
    tilted (0.5 and 0.35 rad about different axes), at their centres (3,) m."""
    import trimesh

    box = trimesh.creation.box(box_size)
    box.apply_transform(trimesh.transformations.rotation_matrix(0.5, [0.3, 0.2, 1]))
    box.apply_translation(box_centre)
    h = half_side
    rot = trimesh.transformations.rotation_matrix(0.35, [0.2, 0.3, 1])[:3, :3]
    corners = np.array([[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]]) @ rot.T + plate_centre
    return box, trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]])
