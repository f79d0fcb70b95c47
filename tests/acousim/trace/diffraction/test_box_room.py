"""A scene pays only for what it contains: inside a box room every edge is a
90-degree corner (the room's air fills a quarter space at each), which an image
source describes in full, so the diffraction stage finds nothing there, and finds it
without a ray; outside the same box, the edges whose outer quarter spaces are not
the sensor's are convex wedges of 270 degrees and diffract."""

from pathlib import Path

import numpy as np

from acousim.scene import load_scene
from acousim.trace import KIND
from acousim.trace.diffraction.first_order import pose_edges
from acousim.trace.diffraction.setup import DiffractionOptions, StageContext
from acousim.trace.diffraction.stage import diffract
from acousim.trace.tracer import Tracer

SHOEBOX = Path(__file__).resolve().parents[4] / "scenes" / "shoebox.toml"
ROOM = np.array([[-1.0, 3.2], [-1.6, 1.9], [-1.1, 1.5]])  # scenes/build_scenes.py


class CountingCaster:
    """A ray caster that counts the rays asked of it."""

    def __init__(self, caster):
        self.caster, self.rays = caster, 0

    def first_hit(self, origins, directions, *args, **kwargs):
        self.rays += len(origins)
        return self.caster.first_hit(origins, directions, *args, **kwargs)

    def occluded(self, origins, directions, *args, **kwargs):
        self.rays += len(origins)
        return self.caster.occluded(origins, directions, *args, **kwargs)

    def __getattr__(self, name):
        return getattr(self.caster, name)


def _stage(tracer, caster, emitter, receiver):
    options = DiffractionOptions(max_path_m=tracer.settings.max_path_m)
    return diffract(tracer.edges, caster, emitter, receiver, options)


def _outer_edges_convex(point: np.ndarray) -> int:
    """Of the box ROOM's 12 edges, those whose two faces do not both face `point`
    (outside the box) from the inside: the edges for which `point` is not in the
    quarter space bounded by the planes of its faces on the box's side."""
    n = 0
    for axis in range(3):  # edges along `axis`: the other two coordinates at a corner
        a, b = [i for i in range(3) if i != axis]
        for ea in ROOM[a]:
            for eb in ROOM[b]:
                # the box lies on the side of ea towards the other wall along a, and so on
                inner_a = (point[a] - ea) * (np.mean(ROOM[a]) - ea) >= 0
                inner_b = (point[b] - eb) * (np.mean(ROOM[b]) - eb) >= 0
                n += not (inner_a and inner_b)
    return n


def test_a_box_room_has_twelve_edges_none_diffracting_inside_and_no_ray_cast():
    scene = load_scene(SHOEBOX)
    tracer = Tracer(scene, threads=1)
    edges = tracer.edges.edges
    # a box: 12 edges, four along each side of the room (4.2, 3.5, 2.6 m)
    assert len(edges) == 12
    assert np.allclose(np.sort(edges.length_m), np.repeat([2.6, 3.5, 4.2], 4))
    caster = CountingCaster(tracer.caster)
    rng = np.random.default_rng(1)
    for _ in range(5):
        emitter = rng.uniform(ROOM[:, 0] + 0.1, ROOM[:, 1] - 0.1)
        receiver = emitter + rng.normal(scale=0.01, size=3)
        assert len(_stage(tracer, caster, emitter, receiver)) == 0
    assert caster.rays == 0
    # the traced paths of the bundled pose: image sources only, no diffraction
    paths = tracer.trace(scene.sensor.poses[0])
    assert len(paths) > 0 and not np.any(paths.kind == KIND["diffraction"])


def test_the_same_box_seen_from_outside_diffracts_at_its_convex_edges():
    tracer = Tracer(load_scene(SHOEBOX), threads=1)
    for point in ([6.0, 4.0, 3.0], [6.0, 0.3, 0.2], [1.0, -4.0, 0.2]):
        point = np.array(point)
        ctx = StageContext(tracer.edges, None, point, point, DiffractionOptions(max_path_m=30.0))
        assert pose_edges(ctx).convex_e.sum() == _outer_edges_convex(point)
    emitter = np.array([6.0, 4.0, 3.0])
    d = _stage(tracer, tracer.caster, emitter, emitter + [0.0, 0.0, 0.01])
    assert len(d) > 0  # the edges it sees diffract
