"""The corridor with a metal cabinet beside its plaster walls: the scene whose
materials the calibration benchmark (:mod:`benchmarks.calibration`) and its tests
(tests/acousim/calibrate/test_calibrate.py) fit.  uRTIS at 450 kHz, range 4 m, 2 bounces, 30 dB of
noise; the fit starts from the bundled values and traces fewer rays than the
"recordings" (another draw of the diffuse tail).  Each caller keeps its own truth."""

from __future__ import annotations

import shutil
from pathlib import Path

from tests import REPO

ROOT = REPO
#: rays of the scene the fit starts from, and of the simulated "recordings"
START_RAYS, TRUTH_RAYS = 5000, 7000

SCENE = """# a corridor with a metal cabinet
[scene]
name = "corridor_metal"

[sensor]
array = "urtis_v1"
call = "default_25_50"
sample_rate_hz = 450000
emitter_m = [0.0, 0.0, -0.012]
emitter_radius_m = 0.004
direct_path = true

[sensor.trajectory]
file = "corridor_drive.csv"
rate_hz = 10
continuous = false   # each pose frozen for its measurement (the fit models it so)

[simulation]
max_range_m = 4.0
rays = {rays}
bounces = 2
snr_db = 30.0
seed = 1

[[materials]]
name = "plaster"   # a guess
{plaster}
lobe_deg = 5.0

[[materials]]
name = "metal"
{metal}
lobe_deg = 3.0

[[meshes]]
file = "corridor.stl"
material = "plaster"

[[meshes]]
file = "cabinet.stl"
material = "metal"
{extra}"""

#: the bundled materials, where the fit starts
BUNDLED = dict(plaster="reflection = 0.95\ndiffuse = 0.2", metal="reflection = 0.99\ndiffuse = 0.0")


def folder(tmp: Path) -> Path:
    """`tmp` with the corridor's mesh and drive, the cabinet (a box 0.5 x 0.55 x 1.9
    m) and start.toml: the scene with the bundled materials."""
    import trimesh

    shutil.copy(ROOT / "scenes/meshes/corridor.stl", tmp / "corridor.stl")
    shutil.copy(ROOT / "scenes/corridor_drive.csv", tmp / "corridor_drive.csv")
    trimesh.creation.box(bounds=[[4.5, 0.45, 0.0], [5.0, 1.0, 1.9]]).export(tmp / "cabinet.stl")
    (tmp / "start.toml").write_text(SCENE.format(rays=START_RAYS, extra="", **BUNDLED))
    return tmp


def simulate_truth(path: Path, poses: list[int], *, plaster: str, metal: str, extra: str = ""):
    """Write the scene with these materials' TOML lines (and `extra` at its end) to
    `path` and simulate it at the drive's `poses` (each frozen, as the scene says):
    the "recordings"."""
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    path.write_text(SCENE.format(rays=TRUTH_RAYS, plaster=plaster, metal=metal, extra=extra))
    scene = load_scene(path)
    sim = Simulator(scene)
    return [sim.simulate_pose(scene.sensor.poses[i], i) for i in poses]
