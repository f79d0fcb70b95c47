"""Edge diffraction (BTM) against independent references written here, not with our code.

* A rigid wedge (a thin screen, thW = 2 pi, and a box edge, thW = 3 pi / 2) lit by a
  point source: the exact solution as the eigenfunction series of the wedge for a
  line source (Bessel and Hankel functions of order nu n), turned into the point-
  source field by the integral over the axial wavenumber.  The same code with
  thW = pi must give a free field plus its image exactly (checked first).
* Finite rigid square plates: the physical-optics (Kirchhoff) surface integral.
"""

from pathlib import Path

import numpy as np
import pytest
import scipy.special as sp
import trimesh

import processing as P
from acousim.scene import parse_scene
from acousim.scene.model import Diffraction, Simulation
from acousim.simulator import Simulator
from acousim.trace import KIND
from acousim.trace.diffraction.btm import DEFAULT_STEP_M, ElementLimits, edge_elements
from acousim.trace.tracer import Tracer
from acousim.trace.world.edges import find_edges
from tests.oracles import scenes

C = 343.0


# -- the exact wedge field ------------------------------------------------------------


def wedge_series(wedge, r_s, th_s, r_r, th_r, dz, k, n_alpha=900, n_beta=300, soft=False):
    """Exact field of a rigid wedge (open angle `wedge`, faces at theta = 0 and
    theta = wedge) at receivers (r_r, th_r[i], dz) for a point source (r_s, th_s, 0),
    in units where the free field is exp(-j k R) / R; `soft`: of a pressure-release
    wedge (Dirichlet: sines in place of the cosines).

    2D Green's function of the Neumann wedge (time factor exp(-i w t)):
        G2 = (i pi / (2 wedge)) sum_n eps_n J_{nu n}(kt r<) H1_{nu n}(kt r>) cos cos,
    with kt = sqrt(k^2 - kz^2) (for kz > k: (1 / wedge) sum eps_n I K cos cos), and the
    3D field G3 = (1 / pi) int_0^inf G2 cos(kz dz) dkz (free field exp(ikR)/(4 pi R)).
    """
    nu = np.pi / wedge
    r1, r2 = min(r_s, r_r), max(r_s, r_r)
    n = int((k * r2 + 80) / nu) + 1
    mu = nu * np.arange(n)
    eps = np.where(np.arange(n) == 0, 1.0, 2.0)
    # propagating part: kz = k sin(alpha)
    x, w = np.polynomial.legendre.leggauss(n_alpha)
    alpha, w = (x + 1) * np.pi / 4, w * np.pi / 4
    kt, kz = k * np.cos(alpha), k * np.sin(alpha)
    with np.errstate(all="ignore"):
        prop = sp.jv(mu[None, :], kt[:, None] * r1) * sp.hankel1(mu[None, :], kt[:, None] * r2)
    prop = np.where(np.isfinite(prop), prop, 0)  # J underflows where H overflows: ~0
    s_prop = ((w * k * np.cos(alpha) * np.cos(kz * dz))[:, None] * prop).sum(0)
    s_prop *= 1j * np.pi / (2 * wedge)
    # evanescent part: kz = k cosh(beta)
    b_max = np.arcsinh(60 / ((r2 - r1) * k))
    x, w = np.polynomial.legendre.leggauss(n_beta)
    beta, w = (x + 1) * b_max / 2, w * b_max / 2
    kappa, kz = k * np.sinh(beta), k * np.cosh(beta)
    with np.errstate(all="ignore"):
        ev = sp.ive(mu[None, :], kappa[:, None] * r1) * sp.kve(mu[None, :], kappa[:, None] * r2)
        ev *= np.exp(-kappa * (r2 - r1))[:, None]
    ev = np.where(np.isfinite(ev), ev, 0)
    s_ev = ((w * k * np.sinh(beta) * np.cos(kz * dz))[:, None] * ev).sum(0) / wedge
    modal = eps * (s_prop + s_ev)
    trig = np.sin if soft else np.cos
    g3 = (modal[None, :] * trig(mu * th_s) * trig(np.outer(th_r, mu))).sum(1) / np.pi
    return np.conj(4 * np.pi * g3)  # exp(+ikR) convention -> ours, exp(-jkR)


def cyl(r, th, z):
    return np.array([r * np.cos(th), r * np.sin(th), z])


def geometric(wedge, r_s, th_s, r_r, th_r, dz, k, reflection=1.0):
    """Direct and reflected waves of an infinite wedge where they are visible (the
    reflected ones times `reflection`)."""
    rcv = cyl(r_r, th_r, dz)
    out = 0.0
    images = [(th_s, abs(th_r - th_s) < np.pi)]  # (source angle, visible)
    images.append((-th_s, th_r + th_s < np.pi))  # image in the face theta = 0
    images.append((2 * wedge - th_s, th_r + th_s > 2 * wedge - np.pi))  # face theta = wedge
    for i, (th, visible) in enumerate(images):
        if visible:
            d = np.linalg.norm(cyl(r_s, th, 0.0) - rcv)
            out = out + (1.0 if i == 0 else reflection) * np.exp(-1j * k * d) / d
    return out


def btm_field(wedge, r_s, th_s, r_r, th_r, dz, k, step=DEFAULT_STEP_M):
    """Ours: geometric part plus the BTM elements of a 20 m edge along z."""
    el = edge_elements(
        scenes.screen(angle_rad=wedge),  # face 1 is the half-plane y = 0, x > 0
        cyl(r_s, th_s, 0.0),
        cyl(r_r, th_r, dz),
        ElementLimits(step_m=step),
    )
    path = el.first_leg_m + el.second_leg_m
    return geometric(wedge, r_s, th_s, r_r, th_r, dz, k) + np.sum(
        el.amplitude * np.exp(-1j * k * path)
    )


def test_the_series_reference_gives_a_wall_exactly():
    """thW = pi: a rigid plane, so source plus image (checks the reference itself)."""
    k = 2 * np.pi * 40e3 / C
    th_r = np.deg2rad([30.0, 100.0, 170.0])
    p = wedge_series(np.pi, 0.15, np.deg2rad(60), 0.10, th_r, 0.05, k)
    for pi, th in zip(p, th_r):
        rcv = cyl(0.10, th, 0.05)
        ref = sum(
            np.exp(-1j * k * np.linalg.norm(cyl(0.15, a, 0) - rcv))
            / np.linalg.norm(cyl(0.15, a, 0) - rcv)
            for a in (np.deg2rad(60), -np.deg2rad(60))
        )
        assert abs(pi - ref) < 1e-5 * abs(ref)


# receiver angles (deg) for a source at 60 deg: lit, both sides of the reflection
# boundary (120), both sides of the shadow boundary (240), shadow zone
RECEIVERS = {
    2 * np.pi: [150.0, 120 - 1e-5, 120 + 1e-5, 240 - 1e-5, 240 + 1e-5, 265.0, 300.0, 340.0],
    1.5 * np.pi: [150.0, 120 - 1e-5, 120 + 1e-5, 240 - 1e-5, 240 + 1e-5, 255.0, 265.0],
}


@pytest.mark.parametrize("wedge", [2 * np.pi, 1.5 * np.pi], ids=["half-plane", "90-deg-wedge"])
@pytest.mark.parametrize("f", [20e3, 50e3, 85e3])
def test_wedge_matches_the_exact_solution(wedge, f):
    """A thin rigid screen and a box edge, point source 0.15 m from the edge, receiver
    0.10 m from it and 5 cm along it: lit, reflection boundary, shadow boundary and
    shadow zone within 0.5 dB and 3 degrees of the exact field (where it is above
    -30 dB of the incident), and continuous across both boundaries."""
    k = 2 * np.pi * f / C
    th_s, dz = np.deg2rad(60.0), 0.05
    th_r = np.deg2rad(RECEIVERS[wedge])
    exact = wedge_series(wedge, 0.15, th_s, 0.10, th_r, dz, k)
    ours = np.array([btm_field(wedge, 0.15, th_s, 0.10, t, dz, k) for t in th_r])
    incident = 1 / np.array([np.linalg.norm(cyl(0.15, th_s, 0) - cyl(0.10, t, dz)) for t in th_r])
    loud = np.abs(exact) > incident * 10 ** (-30 / 20)
    assert loud.sum() >= len(th_r) - 2
    err_db = 20 * np.log10(np.abs(ours[loud]) / np.abs(exact[loud]))
    assert np.max(np.abs(err_db)) < 0.5, err_db
    assert np.max(np.abs(np.angle(ours[loud] / exact[loud]))) < np.deg2rad(3)
    # continuity: the two sides of each boundary agree (the geometric wave jumps)
    for i in (1, 3):
        assert abs(20 * np.log10(abs(ours[i]) / abs(ours[i + 1]))) < 0.1


# -- finite plates against physical optics --------------------------------------------


def plate_tracer(tmp_path: Path, side, turn_deg=0.0, distance=2.0, beam_deg=10.0, order=1):
    """Paths of a square rigid plate (side, m) at `distance` facing the sensor, turned
    by turn_deg about z; order: the diffraction order (None: the scene's default)."""
    more = {} if order is None else {"diffraction": {"order": order}}
    return scenes.plate_paths(
        tmp_path, side, turn_deg, distance, max_range_m=4.0, beam_deg=beam_deg, **more
    )


def physical_optics(v, emitter, receiver, k, n):
    """Kirchhoff field of a rigid plate (corners v (4, 3)): surface pressure twice the
    incident one, radiated by the Helmholtz integral, midpoint rule on n x n cells:
    (1 / 2 pi) int e^{-jk r1} / r1  e^{-jk r2} / r2 (jk + 1 / r2) (cos1 + cos2) / 2 dS."""
    u, w = v[1] - v[0], v[3] - v[0]
    s = (np.arange(n) + 0.5) / n
    x = (v[0] + s[:, None, None] * u + s[None, :, None] * w).reshape(-1, 3)
    normal = np.cross(u, w)
    area = np.linalg.norm(normal) / n**2
    normal /= np.linalg.norm(normal)
    r1 = np.linalg.norm(x - emitter, axis=1)
    r2 = np.linalg.norm(x - receiver, axis=1)
    cos = (np.abs((emitter - x) @ normal) / r1 + np.abs((receiver - x) @ normal) / r2) / 2
    return np.array(
        [
            np.sum(np.exp(-1j * kk * (r1 + r2)) / (r1 * r2) * (1j * kk + 1 / r2) * cos)
            * area
            / (2 * np.pi)
            for kk in k
        ]
    )


FREQS = np.linspace(20e3, 85e3, 14)


@pytest.mark.parametrize("side", [0.02, 0.05, 0.10, 0.20])
def test_small_plate_facing_the_sensor_matches_physical_optics(tmp_path, side):
    """Normal incidence at 2 m: the specular echo alone is 0 dB (an infinite wall);
    physical optics gives -33 dB (2 cm, 20 kHz) to +5 dB; ours within 1 dB."""
    k = 2 * np.pi * FREQS / C
    paths, v, e, r = plate_tracer(tmp_path, side)
    assert (paths.kind == KIND["diffraction"]).sum() >= 8  # two halves of four rims
    ours = scenes.spectrum(paths, r, k)
    ref = physical_optics(v, e, r, k, n=400)
    err = 20 * np.log10(np.abs(ours) / np.abs(ref))
    assert np.max(np.abs(err)) < 1.0, err


def test_plate_turning_through_its_edge_stays_continuous(tmp_path):
    """A 0.5 m plate at 2 m turned until its mirror point leaves it: the specular
    echo disappears, the edge's reflection-boundary term takes over, and the total
    changes by less than 0.5 dB at every frequency across the crossing."""
    k = 2 * np.pi * FREQS / C
    lo, hi = 6.0, 8.5  # the mirror point leaves the plate near 7.1 degrees
    has_specular = {}

    def level(turn):
        p, *_, r = plate_tracer(tmp_path, 0.5, turn, beam_deg=60)
        has_specular[turn] = bool((p.kind == KIND["specular"]).any())
        return np.abs(scenes.spectrum(p, r, k))

    level(lo), level(hi)
    assert has_specular[lo] and not has_specular[hi]
    for _ in range(15):  # bisect for the crossing to 1e-4 degrees (float32 ray casting
        # decides the specular echo to ~1e-7 m, the edge term at its exact boundary)
        mid = (lo + hi) / 2
        level(mid)
        lo, hi = (mid, hi) if has_specular[mid] else (lo, mid)
    jump = 20 * np.log10(level(hi) / level(lo))
    assert not has_specular[hi] and has_specular[lo]
    assert hi - lo < 1e-4
    assert np.max(np.abs(jump)) < 0.5, jump


@pytest.mark.parametrize("turn", [7.5, 10.0, 20.0])
def test_plate_whose_mirror_point_misses_it_matches_physical_optics(tmp_path, turn):
    """0.5 m plate at 2 m, turned so that no specular echo exists: before, silence;
    now within 3 dB of physical optics (itself approximate away from the mirror
    direction) at every frequency of 20-85 kHz."""
    k = 2 * np.pi * FREQS / C
    paths, v, e, r = plate_tracer(tmp_path, 0.5, turn, beam_deg=60)
    assert not (paths.kind == KIND["specular"]).any()
    ours = scenes.spectrum(paths, r, k)
    ref = physical_optics(v, e, r, k, n=800)
    err = 20 * np.log10(np.abs(ours) / np.abs(ref))
    assert np.max(np.abs(err)) < 3.0, err


# -- which edges diffract ----------------------------------------------------------


def test_edges_of_a_box_a_sheet_a_sphere_and_a_cylinder():
    box_mesh = trimesh.creation.box([1.0, 1.0, 1.0])
    box = find_edges(box_mesh)
    assert len(box) == 12  # the face diagonals (coplanar seams) are not edges
    assert np.allclose(box.length_m, 1.0)
    outside, inside = np.array([3.0, 2.0, 1.0]), np.array([0.1, 0.2, -0.1])
    keep, wedge = box.oriented(outside, outside)
    # box edges seen from outside: 270 degrees of air, except the three edges on the
    # far side, whose quadrant behind the box holds the point (they are hidden)
    assert np.allclose(wedge.angle_rad[keep], 1.5 * np.pi)
    assert np.allclose(wedge.angle_rad[~keep], 0.5 * np.pi)
    n_seen = keep.sum()
    assert n_seen == 9
    keep, wedge = box.oriented(inside, inside)  # a room's corners: no real wedge
    assert not keep.any() and np.allclose(wedge.angle_rad, 0.5 * np.pi)
    flipped = find_edges(trimesh.Trimesh(box_mesh.vertices, box_mesh.faces[:, ::-1]))
    assert flipped.oriented(outside, outside)[0].sum() == n_seen  # winding does not matter
    sheet = find_edges(
        trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    )
    assert len(sheet) == 4 and np.allclose(sheet.angle_rad, 2 * np.pi)
    assert sheet.oriented([0.5, 0.5, 1.0], [0.5, 0.5, -1.0])[0].all()  # both sides
    assert np.all(sheet.faces[:, 1] == -1)
    # face_dir points into the face: the edge midpoint moved along it is inside
    mid = 0.5 * (sheet.start_m + sheet.end_m) + 0.1 * sheet.face_dir
    assert np.all((mid[:, :2] > 0) & (mid[:, :2] < 1))
    assert len(find_edges(trimesh.creation.icosphere(3))) == 0  # a tessellated sphere
    cyl_edges = find_edges(trimesh.creation.cylinder(0.1, 1.0, sections=32))
    assert len(cyl_edges) == 64  # the two rims, not the 32 seams of the side
    keep, wedge = cyl_edges.oriented([2.0, 0, 0], [2.0, 0, 0])
    assert keep.sum() == 32 and np.allclose(wedge.angle_rad[keep], 1.5 * np.pi)


def test_hidden_edges_do_not_diffract_and_truth_lists_diffraction(tmp_path):
    """A cube 2 m ahead, turned 30 degrees: its back edges are hidden behind it, and
    a simulated recording's ground truth lists the diffraction paths by kind."""
    box = trimesh.creation.box([0.4, 0.4, 0.4])
    box.apply_transform(trimesh.transformations.rotation_matrix(np.deg2rad(30), [0, 0, 1]))
    box.apply_translation([2.0, 0, 0])
    box.export(tmp_path / "box.obj")
    scene = parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False},
            "simulation": {
                "max_range_m": 3.0,
                "rays": 2000,
                "bounces": 1,
                "diffraction": {"order": 1},
            },
            "meshes": [{"file": "box.obj"}],
        },
        base_dir=tmp_path,
    )
    sim = Simulator(scene)
    pose = scene.sensor.poses[0]
    paths = sim.paths(pose)
    d = paths.select(paths.kind == KIND["diffraction"])
    assert len(d) > 0
    # the back corner (x = centre + 0.273 m) and the edges to it are hidden: nothing
    # diffracts behind the silhouette corners (x = centre + 0.2 (cos 30 - sin 30))
    silhouette = 2.0 + 0.2 * (np.cos(np.deg2rad(30)) - np.sin(np.deg2rad(30)))
    assert d.position_m[:, 0].max() <= silhouette + 1e-4
    assert (d.position_m[:, 0] < 2.0).any()  # the front edges do
    assert np.all(d.order == 1)
    rec = sim.simulate_pose(pose, 0)
    assert (rec.truth.kind == "diffraction").sum() == len(d)
    # magnitudes, though paths are signed: |strength| / distance to the array centre
    sel = rec.truth.kind == "diffraction"
    centre = pose.to_world(scene.sensor.array.positions_m).mean(axis=0)
    expected = np.abs(d.strength) / np.linalg.norm(d.anchor_m - centre, axis=1)
    assert np.allclose(np.sort(rec.truth.amplitude[sel]), np.sort(expected))
    assert (d.strength < 0).any() and np.all(rec.truth.amplitude >= 0)
    # the kind survives a file (what `acousim compare` and the pictures read back)
    P.save_recordings(tmp_path / "rec.h5", [rec])
    back = P.load_recording(tmp_path / "rec.h5")
    assert (back.truth.kind == "diffraction").sum() == len(d)


def test_edge_seen_through_a_floor_reflection(tmp_path):
    """A screen's lower rim 0.3 m above a rigid floor: with reflections on, the edge
    is also reached through the floor (image of the emitter below it) and left
    through the floor (image of the receiver); the shortest such path is the
    unfolded distance from the image to the rim plus the rim to the receiver."""
    floor = trimesh.Trimesh(
        [[-1, -3, 0], [5, -3, 0], [5, 3, 0], [-1, 3, 0]], [[0, 1, 2], [0, 2, 3]]
    )
    screen = trimesh.Trimesh(
        [[2, -1, 0.3], [2, 1, 0.3], [2, 1, 0.8], [2, -1, 0.8]], [[0, 1, 2], [0, 2, 3]]
    )
    floor.export(tmp_path / "floor.obj")
    screen.export(tmp_path / "screen.obj")
    sim = {"max_range_m": 4.0, "rays": 2000, "bounces": 1}
    sim["diffraction"] = {"reflections": True}
    sim["energy_floor_db"] = -200.0
    scene = parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "direct_path": False,
                "pose": {"position_m": [0.0, 0.0, 0.5]},
            },
            "simulation": sim,
            "meshes": [{"file": "floor.obj"}, {"file": "screen.obj"}],
        },
        base_dir=tmp_path,
    )
    tracer = Tracer(scene, threads=1)
    pose = scene.sensor.poses[0]
    e = pose.to_world(scene.sensor.array.emitter_m)
    r = pose.to_world(scene.sensor.array.positions_m.mean(axis=0))
    paths = tracer.trace(pose)
    d = paths.select((paths.kind == KIND["diffraction"]) & (paths.order == 2))
    rim = np.abs(d.position_m[:, 2] - 0.3) < 1e-9
    assert rim.sum() > 0
    total = d.first_leg_m + np.linalg.norm(d.anchor_m - r, axis=1)

    def unfolded(a, b):  # shortest path a -> rim line (x = 2, z = 0.3) -> b
        ra, rb = np.hypot(2 - a[0], 0.3 - a[2]), np.hypot(2 - b[0], 0.3 - b[2])
        return np.hypot(ra + rb, b[1] - a[1])

    image_e, image_r = e * [1, 1, -1], r * [1, 1, -1]
    for shortest in (unfolded(image_e, r), unfolded(e, image_r)):
        near = np.abs(total[rim] - shortest)
        assert near.min() < 1e-5  # the element at the apex
    assert total[rim].min() >= min(unfolded(image_e, r), unfolded(e, image_r)) - 1e-9


def test_a_plate_that_was_silent_now_echoes_at_its_edge(tmp_path):
    """End to end: the 0.5 m plate at 2 m turned 10 degrees has no specular echo; the
    simulated recording's matched-filter peak comes from the near rim's apex (its
    range within 1 cm), and with diffraction off the recording is silent."""
    import dataclasses

    from processing import matched_filter

    paths, v, e, r = plate_tracer(tmp_path, 0.5, 10.0, beam_deg=60)
    simulation = {"max_range_m": 4.0, "rays": 20000, "bounces": 1, "beam_deg": 60.0}
    scene = scenes.rigid_scene(tmp_path, [v], {**simulation, "diffraction": {"enabled": False}})
    pose = scene.sensor.poses[0]
    silent = Simulator(scene).simulate_pose(pose, 0)
    assert np.max(np.abs(silent.samples)) == 0
    on = dataclasses.replace(scene.simulation, diffraction=Diffraction())
    rec = Simulator(dataclasses.replace(scene, simulation=on)).simulate_pose(pose, 0)
    y = matched_filter(rec.samples, rec.waveform.sampled(rec.sample_rate_hz))
    env = np.abs(y).sum(axis=0)
    t = (np.argmax(env) - rec.emission_index) / rec.sample_rate_hz
    # the nearest point of the plate's rims (the near vertical rim, x smallest)
    near = v[np.argmin(v[:, 0])]
    apex = np.array([near[0], near[1], 0.0])
    expected = (np.linalg.norm(apex - e) + np.linalg.norm(apex - r)) / rec.speed_of_sound_m_s
    assert abs(t - expected) * rec.speed_of_sound_m_s < 0.01


def test_scene_keys_for_diffraction(tmp_path):
    base = {"sensor": {"array": "urtis_v1"}, "points": [{"position_m": [1.0, 0, 0]}]}
    assert parse_scene(base).simulation.diffraction == Diffraction(enabled=True)  # on by default
    off = {"diffraction": {"enabled": False}}
    assert parse_scene({**base, "simulation": off}).simulation.diffraction.enabled is False
    sim = parse_scene({**base, "simulation": {"diffraction": {"step_m": 0.002}}}).simulation
    assert sim.diffraction.enabled and sim.diffraction.step_m == 0.002
    assert not sim.diffraction.reflections
    with pytest.raises(ValueError, match="simulation.diffraction"):
        parse_scene({**base, "simulation": {"diffraction": "yes"}})
    with pytest.raises(ValueError, match="simulation.diffraction.step_m"):
        parse_scene({**base, "simulation": {"diffraction": {"step_m": 0.0}}})
    with pytest.raises(ValueError, match="did you mean 'step_m'"):
        parse_scene({**base, "simulation": {"diffraction": {"step": 0.002}}})


def test_flat_diffraction_keys_still_read_with_a_warning():
    """The keys before ``[simulation.diffraction]`` (one version's grace): the file's
    flat keys and the Python keywords give the same settings, with a warning naming
    the new spelling."""
    base = {"sensor": {"array": "urtis_v1"}, "points": [{"position_m": [1.0, 0, 0]}]}
    flat = {"diffraction": False, "diffraction_step_m": 0.002, "diffraction_order": 1}
    with pytest.warns(DeprecationWarning, match="simulation.diffraction.step_m"):
        sim = parse_scene({**base, "simulation": flat}).simulation
    assert sim.diffraction == Diffraction(enabled=False, step_m=0.002, order=1)
    with pytest.warns(DeprecationWarning, match=r"Diffraction\(enabled=False"):
        py = Simulation(diffraction=False, diffraction_order=1, diffraction_step_m=0.002)
    assert py.diffraction == sim.diffraction


def test_diffraction_is_reciprocal():
    """Swapping emitter and receiver leaves the diffracted field unchanged (a
    property of the exact solution): a tilted box and a tilted plate, bistatic."""
    from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions, diffract
    from acousim.trace.world.embree import RayCaster

    box, plate = scenes.turned_box_and_plate([0.3, 0.2, 0.25], [1.5, 0.1, 0], 0.05, [1.0, 0, 0])
    s, r = np.array([0, 0.05, 0.02]), np.array([0.1, -0.2, 0.1])
    k = 2 * np.pi * np.linspace(20e3, 80e3, 13) / C
    for mesh in (box, plate):
        edges, caster = find_edges(mesh), RayCaster(mesh.triangles, 1)
        refl = np.ones(len(mesh.faces))
        geometry, options = (
            DiffractingGeometry(edges, refl),
            DiffractionOptions(max_path_m=8.0, settings=Diffraction(order=1)),
        )
        forward = diffract(geometry, caster, s, r, options)
        backward = diffract(geometry, caster, r, s, options)
        assert len(forward) > 0
        a, b = scenes.spectrum(forward, r, k), scenes.spectrum(backward, s, k)
        assert np.max(np.abs(a - b)) < 1e-3 * np.max(np.abs(a))


def test_every_path_kind_is_a_ground_truth_kind():
    """The tracer's kinds (acousim) and the recording's (processing, which imports no
    acousim) are the same names: a diffraction path can be written and read back."""
    from processing.formats.native import _KINDS

    assert {k.name for k in KIND} == set(_KINDS)
