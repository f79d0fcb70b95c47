"""The picture of docs/export.md's "What the sensor sees": a two-bounce echo in a
2 m wide hallway, its chain and its apparent position, over the DAS image.

    python docs/truth/two_bounce.py      # writes docs/truth/two_bounce.png
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import trimesh

import processing as P
from acousim.scene import parse_scene
from acousim.simulator import Simulator
from acousim.viz.fan import draw_fan

HERE = Path(__file__).resolve().parent


def hallway(tmp: Path):
    """Walls at y = +1 m (left) and y = -1 m (right), the sensor between them facing
    along the hallway (+x)."""
    for y, name in ((1.0, "left"), (-1.0, "right")):
        wall = [[-15, y, -1.5], [15, y, -1.5], [15, y, 1.5], [-15, y, 1.5]]  # m
        trimesh.Trimesh(wall, [[0, 1, 2], [0, 2, 3]]).export(tmp / f"{name}.obj")
    return parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False},  # at the origin, facing +x
            "simulation": {"max_range_m": 3.0, "bounces": 2, "snr_db": 60.0, "beam_deg": 180.0},
            "materials": [{"name": "plaster", "reflection": 0.9}],
            "meshes": [
                {"file": "left.obj", "material": "plaster"},
                {"file": "right.obj", "material": "plaster"},
            ],
        },
        base_dir=tmp,
    )


def main() -> Path:
    with tempfile.TemporaryDirectory() as tmp:
        scene = hallway(Path(tmp))
        rec = Simulator(scene).simulate_pose(scene.sensor.poses[0])
    grid = P.Grid.degrees((-90, 90), (-20, 20), 2.0)
    settings = P.ProcessingSettings(grid=grid, energy_fraction=0.0, range_limits_m=(0.3, 2.8))
    image = P.acoustic_images(rec, ("das",), settings)["das"]
    t = rec.truth
    # the echo that crosses the hallway from the left wall to the right one and back
    two = np.flatnonzero(
        (t.order == 2)
        & (t.kind == "specular")
        & (t.first_point_m[:, 1] > 0.99)
        & (t.last_point_m[:, 1] < -0.99)
    )
    j = two[np.argmax(t.amplitude[two])]
    centre = rec.array.positions_m.mean(axis=0)
    emitter = rec.array.emitter_m
    fig, ax = plt.subplots(figsize=(7.5, 6.0), layout="constrained")
    im = draw_fan(ax, image, 2.8, 30.0, extent=(3.0, -3.0, -0.5, 2.8))
    fig.colorbar(im, ax=ax, shrink=0.8, label="DAS image, dB re strongest cell")
    for y in (1.0, -1.0):
        ax.axvline(y, color="white", lw=3, alpha=0.8)
    chain = np.array([emitter, t.first_point_m[j], t.last_point_m[j], centre])
    ax.plot(chain[:, 1], chain[:, 0], "-", color="cyan", lw=1.5, label="the path's chain")
    ax.plot(
        *t.first_point_m[j][[1, 0]], "s", mfc="none", mec="cyan", ms=8, label="first reflection"
    )
    ax.plot(*t.last_point_m[j][[1, 0]], "D", mfc="none", mec="cyan", ms=8, label="last reflection")
    app = t.apparent_position_sensor_m[j]
    ax.plot([centre[1], app[1]], [centre[0], app[0]], ":", color="white", lw=1.2)
    ax.plot(
        app[1],
        app[0],
        "o",
        mfc="none",
        mec="white",
        ms=12,
        mew=1.5,
        label=(
            f"apparent position: c·delay/2 = {np.linalg.norm(app - centre):.2f} m\n"
            "along the arrival direction"
        ),
    )
    ax.plot(0, 0, "o", color="gold", ms=8, label="sensor (facing +x)")
    ax.set_xlabel("y (m), left +")
    ax.set_ylabel("x forward (m)")
    ax.set_title(
        "A two-bounce echo in a 2 m hallway: 1 + 2 + 1 m, imaged 2 m to the right,\n"
        "beyond the wall where it last reflected",
        fontsize=10,
    )
    ax.legend(loc="upper left", fontsize=7.5, facecolor="0.25", labelcolor="white", framealpha=0.9)
    out = HERE / "two_bounce.png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(main())
