"""A mesh on a track that also gives its orientation (another robot turning as it
drives by): rows [t, x, y, z, roll, pitch, yaw].

Independent reference: the exact monostatic echo of a wall turning about an axis in
its own face, as in tests/acousim/trace/motion/test_turning.py (whose check this reuses),
now with the turn given by the track's rows instead of a rate."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

import acousim
from acousim.scene import parse_scene
from processing.base.errors import InputError
from tests.acousim.trace.motion.test_turning import check_turning_wall, wall_box

pytest.importorskip("embreex")

D, W = 2.0, np.deg2rad(90.0)  # the wall 2 m ahead, turning at 90 deg/s about z


@pytest.mark.parametrize("t0", [0.2, 0.55])
def test_wall_turned_by_its_track_against_the_exact_echo(t0):
    """Rows every 0.25 s, the wall standing at (D, 0, 0) with the yaw W t (rad)."""
    rows = [[t, D, 0.0, 0.0, 0.0, 0.0, W * t] for t in np.arange(0.0, 1.01, 0.25)]
    wall = acousim.MeshItem(wall_box(), acousim.Material("w", 1.0), track=rows)
    assert wall.turning
    check_turning_wall(wall, t0, D, W)


def test_track_turns_in_a_scene_file_are_degrees(tmp_path):
    """The file's roll, pitch, yaw are degrees (as rotation_deg); bad rows are named."""
    trimesh.creation.box((0.2, 2, 2)).export(tmp_path / "box.stl")
    rows = [[0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 2.0, 1.0, 0.0, 10.0, 0.0, 90.0]]
    base = {"sensor": {"array": "urtis_v1"}, "meshes": [{"file": "box.stl", "track": rows}]}
    mesh = parse_scene(base, base_dir=tmp_path).meshes[0]
    assert mesh.turning
    # half way: yaw 45 deg about z after a roll of 5 deg about x (a smooth rotation
    # spline between two rows is the constant-rate turn between them)
    half = mesh.rotation_at(0.5)
    turn = np.deg2rad([10.0, 0.0, 90.0])
    end = Rotation.from_euler("ZYX", turn[::-1])
    expected = Rotation.from_rotvec(end.as_rotvec() / 2).as_matrix()
    assert half == pytest.approx(expected, abs=1e-9)
    assert mesh.angular_velocity_at(0.5) == pytest.approx(end.as_rotvec(), abs=1e-9)
    assert mesh.at(0.5)[0] == pytest.approx([2.0, 0.5, 0.0], abs=1e-9)

    def refused(mesh_table, match):
        bad = {**base, "meshes": [{"file": "box.stl", **mesh_table}]}
        with pytest.raises(InputError, match=match):
            parse_scene(bad, base_dir=tmp_path)

    fast = [[0.0, 2, 0, 0, 0, 0, 0], [0.01, 2, 0, 0, 0, 0, 90]]  # 9000 deg/s
    refused({"track": fast}, r"meshes\[0\]\.track.*turns faster")
    refused({"track": [r[:6] for r in rows]}, r"meshes\[0\]\.track.*roll, pitch, yaw")
    refused({"track": rows, "angular_rate_deg_s": [0, 0, 30]}, r"angular_rate_deg_s")
    point = {"sensor": {"array": "urtis_v1"}, "points": [{"track": rows}]}
    with pytest.raises(InputError, match=r"points\[0\]\.track"):
        parse_scene(point)
