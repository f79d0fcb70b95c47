"""Second-order (edge-to-edge) BTM diffraction against references written here.

* Two parallel rims of a long thin strip at normal incidence: the geometrical theory
  of diffraction (Keller's coefficient of a rigid half-plane, the ray-tube spreading
  of a straight edge, the factor 1/2 of a ray grazing a rigid face, the two sides of
  the strip); the BTM double integral tends to it for k w >> 1.
* Reciprocity of the whole stage: swapping emitter and receiver (bistatic, a turned
  box and a turned plate) leaves the edge-to-edge field unchanged.
* Small plates facing the sensor: geometric + first + second order within 1 dB of
  physical optics, as first order alone is.
"""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from acousim.scene import parse_scene
from acousim.trace import KIND
from acousim.trace.btm import Wedge, edge_pair_elements
from acousim.trace.edges import find_edges
from acousim.trace.tracer import Tracer
from processing.errors import InputError

C = 343.0


def keller(k, phi, phi_in):
    """Diffraction coefficient of a rigid (Neumann) half-plane, normal incidence on
    the edge, angles from the face (time factor exp(+j w t): fields exp(-j k r))."""
    return (
        -np.exp(-1j * np.pi / 4)
        / (2 * np.sqrt(2 * np.pi * k))
        * (1 / np.cos((phi - phi_in) / 2) + 1 / np.cos((phi + phi_in) / 2))
    )


def strip_double_diffraction_gtd(d, w, k):
    """GTD field at the source (monostatic, on the strip's axis at distance d) of the
    ray source -> rim 1 -> along the strip -> rim 2 -> source, one direction.

    Rim 1 is lit at angle phi_in = acos((w / 2) / s) from its face (s = the distance
    source-rim) and diffracts along the face (phi = 0); its field at rim 2 spreads as
    sqrt(s / (w (w + s))).  That field grazes rim 2's face: half of Keller's
    coefficient, spreading sqrt(rho / (s (s + rho))) with rho = s + w (the wave's
    radius of curvature along the edge).  The ray runs along both faces of the strip;
    their two contributions are equal (the diffracted field changes sign from one
    face to the other, at both rims)."""
    s = np.hypot(d, w / 2)
    phi_in = np.arccos((w / 2) / s)
    at_rim2 = np.exp(-1j * k * (s + w)) / s * keller(k, 0.0, phi_in) * np.sqrt(s / (w * (w + s)))
    rho = s + w
    one_side = (
        at_rim2
        * 0.5
        * keller(k, phi_in, 0.0)
        * np.sqrt(rho / (s * (s + rho)))
        * np.exp(-1j * k * s)
    )
    return 2 * one_side


def response(el, receiver, k):
    return (el.amplitude * np.exp(-1j * k[:, None] * (el.first_leg_m + el.second_leg_m))).sum(1)


def test_long_strip_edge_to_edge_matches_the_geometrical_theory():
    """A 4 cm wide, 2 m long rigid strip at 0.5 m, facing the sensor: the edge-to-edge
    echo of the two rims (one direction) within 0.3 dB and 0.1 rad of GTD at
    20-80 kHz (k w = 15-59), at the default step."""
    d, w, length = 0.5, 0.04, 2.0
    normal = np.array([-1.0, 0, 0])
    rim1 = Wedge(
        np.array([d, -w / 2, -length / 2]),
        np.array([d, -w / 2, length / 2]),
        np.array([0, 1.0, 0]),
        normal,
        2 * np.pi,
    )
    rim2 = Wedge(
        np.array([d, w / 2, -length / 2]),
        np.array([d, w / 2, length / 2]),
        np.array([0, -1.0, 0]),
        normal,
        2 * np.pi,
    )
    k = 2 * np.pi * np.linspace(20e3, 80e3, 7) / C
    origin = np.zeros(3)
    el = edge_pair_elements(rim1, rim2, 0.0, 0.0, 2, origin, origin)
    ours = response(el, origin, k)
    ref = strip_double_diffraction_gtd(d, w, k)
    err_db = 20 * np.log10(np.abs(ours) / np.abs(ref))
    assert np.max(np.abs(err_db)) < 0.3, err_db
    assert np.max(np.abs(np.angle(ours / ref))) < 0.1
    # and it is a small correction: about 35 dB under the wall's echo 1 / (2 d)
    assert np.all(20 * np.log10(np.abs(ours) * 2 * d) < -25)


def plane_ids(mesh) -> np.ndarray:
    """Plane id per face: normal and offset rounded (written here, not the tracer's)."""
    n = np.asarray(mesh.face_normals)
    off = np.einsum("ij,ij->i", n, mesh.triangles[:, 0])
    key = np.round(np.column_stack([n, off]), 6)
    return np.unique(key, axis=0, return_inverse=True)[1].ravel()


def test_edge_to_edge_is_reciprocal():
    """Swapping emitter and receiver leaves the second-order field unchanged (within
    1e-3 of its peak): a turned box and a turned plate, bistatic."""
    from acousim.trace.diffraction import diffract
    from acousim.trace.embree import RayCaster

    box = trimesh.creation.box([0.06, 0.05, 0.04])
    box.apply_transform(trimesh.transformations.rotation_matrix(0.5, [0.3, 0.2, 1]))
    box.apply_translation([0.5, 0.02, 0])
    h = 0.03
    rot = trimesh.transformations.rotation_matrix(0.35, [0.2, 0.3, 1])[:3, :3]
    corners = np.array([[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]]) @ rot.T + [0.4, 0, 0]
    plate = trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]])
    s, r = np.array([0, 0.05, 0.02]), np.array([0.1, -0.2, 0.1])
    k = 2 * np.pi * np.linspace(20e3, 80e3, 13) / C
    for mesh in (box, plate):
        edges, caster = find_edges(mesh), RayCaster(mesh.triangles, 1)
        refl, planes = np.ones(len(mesh.faces)), plane_ids(mesh)
        fwd = diffract(edges, caster, s, r, 8.0, refl, order=2, face_plane=planes)
        bwd = diffract(edges, caster, r, s, 8.0, refl, order=2, face_plane=planes)
        a = _spectrum(fwd, fwd.order == 2, r, k)
        b = _spectrum(bwd, bwd.order == 2, s, k)
        assert (fwd.order == 2).sum() > 10
        assert np.max(np.abs(a - b)) < 1e-3 * np.max(np.abs(a)), np.abs(a - b) / np.abs(a)


def _spectrum(paths, sel, receiver, k):
    last = np.linalg.norm(paths.anchor_m[sel] - receiver, axis=1)
    phase = np.exp(-1j * k[:, None] * (paths.first_leg_m[sel] + last)[None, :])
    return (paths.strength[sel] / last * phase).sum(axis=1)


def plate_paths(tmp_path: Path, side, distance, order, turn_deg=0.0):
    h = side / 2
    v = np.array([[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]], float)
    t = np.deg2rad(turn_deg)
    rz = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    v = v @ rz.T + [distance, 0, 0]
    trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]]).export(tmp_path / "plate.obj")
    scene = parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False},
            "simulation": {
                "max_range_m": distance + 1.0,
                "rays": 20000,
                "bounces": 1,
                "beam_deg": 30.0,
                "diffraction": True,
                "diffraction_order": order,
                "energy_floor_db": -200.0,
            },
            "materials": [{"name": "rigid", "reflection": 1.0}],
            "meshes": [{"file": "plate.obj", "material": "rigid"}],
        },
        base_dir=tmp_path,
    )
    pose = scene.sensor.poses[0]
    emitter = pose.to_world(scene.sensor.array.emitter_m)
    receiver = pose.to_world(scene.sensor.array.positions_m.mean(axis=0))
    return Tracer(scene, threads=1).trace(pose), v, emitter, receiver


@pytest.mark.parametrize("side", [0.04, 0.10])
def test_plate_facing_the_sensor_with_second_order_matches_physical_optics(tmp_path, side):
    """Normal incidence at 0.5 m, half-widths with k a from 7.3 to 78 (the regime
    where physical optics is accurate): geometric + first + second order within 1 dB
    of physical optics at 20-85 kHz; the tracer adds edge-to-edge paths (kind
    diffraction, order 2).  (A 2 cm plate, k a = 3.7 at 20 kHz, is 1.1 dB under
    physical optics there with second order and 0.5 dB over it without: physical
    optics, which knows no edge-to-edge waves, is no reference at that size.)"""
    from tests.test_diffraction import physical_optics  # the first-order tests' reference

    k = 2 * np.pi * np.linspace(20e3, 85e3, 14) / C
    one, *_ = plate_paths(tmp_path, side, 0.5, 1)
    paths, v, e, r = plate_paths(tmp_path, side, 0.5, 2)
    diffracted = paths.kind == KIND["diffraction"]
    assert (diffracted & (paths.order == 2)).sum() > (one.order == 2).sum() + 8
    ours = _spectrum(paths, np.ones(len(paths), bool), r, k)
    ref = physical_optics(v, e, r, k, n=int(side / 0.0002))
    err = 20 * np.log10(np.abs(ours) / np.abs(ref))
    assert np.max(np.abs(err)) < 1.0, err


def test_scene_key_diffraction_order(tmp_path):
    base = {"sensor": {"array": "urtis_v1"}, "points": [{"position_m": [1.0, 0, 0]}]}
    assert parse_scene(base).simulation.diffraction_order == 1
    sim = parse_scene({**base, "simulation": {"diffraction_order": 2}}).simulation
    assert sim.diffraction_order == 2
    for bad in (0, 3, 1.5, "two"):
        with pytest.raises(InputError, match="diffraction_order"):
            parse_scene({**base, "simulation": {"diffraction_order": bad}})
