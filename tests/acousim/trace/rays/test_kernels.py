"""The tracer's compiled kernels (numba) against references written here: plain
loops of the geometry (mirror images, line-plane intersections, reflections,
barycentric coordinates by least squares, a Gauss-Newton search by scipy), and,
for the whole tracer, its numpy twins (numba missing): the same paths."""

import dataclasses
import tomllib

import numpy as np
import pytest
from scipy.optimize import least_squares

from acousim.scene import load_scene, parse_scene
from acousim.trace import KIND
from acousim.trace.tracer import Tracer
from tests import REPO

pytest.importorskip("numba")

from acousim.trace.rays import (  # noqa: E402 - after the skip
    bounce_kernel,
    cluster_kernel,
    glint_kernel,
    specular_kernel,
)
from acousim.trace.world import embree_kernel  # noqa: E402

CORRIDOR = REPO / "scenes" / "corridor.toml"


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _bary(tri, x):
    """Barycentric coordinates (3,) of x in the plane of tri (3, 3), least squares."""
    e = np.column_stack([tri[1] - tri[0], tri[2] - tri[0]])
    b12 = np.linalg.lstsq(e, x - tri[0], rcond=None)[0]
    return np.array([1 - b12.sum(), *b12])


def _planes(rng, P):
    normal = _unit(rng.normal(size=(P, 3)))
    return normal, rng.uniform(-2, 2, P)


def test_images_are_the_emitter_mirrored_plane_by_plane():
    rng = np.random.default_rng(0)
    normal, offset = _planes(rng, 7)
    ids = rng.integers(0, 7, (50, 3))
    emitter = rng.normal(size=3)
    out = np.empty((50, 4, 3))
    ok = specular_kernel.images(ids, emitter, normal, offset, 6.0, out)
    for s in range(50):
        p = emitter.copy()
        for j, q in enumerate(ids[s]):
            p = p - 2 * (p @ normal[q] - offset[q]) * normal[q]
            np.testing.assert_allclose(out[s, j + 1], p, rtol=0, atol=1e-12)
        assert ok[s] == (np.linalg.norm(p - emitter) <= 6.0)
    assert ok.any() and not ok.all()


def test_a_step_meets_the_plane_on_the_line_to_the_image():
    rng = np.random.default_rng(1)
    P, S, tol, eps = 5, 400, 1e-4, 1e-5
    normal, offset = _planes(rng, P)
    centre = normal * offset[:, None]
    boxes = np.stack([centre - 1.5, centre + 1.5], axis=1)
    planes = rng.integers(0, P, S)
    cur, image = rng.normal(size=(S, 3)) * 2, rng.normal(size=(S, 3)) * 3
    cur[:5] = image[:5] = centre[planes[:5]]  # on the plane: x on cur, an edge
    ok = np.ones(S, bool)
    ok[-20:] = False  # refused before this step: left alone
    x, start, at_edge = np.empty((S, 3)), np.empty((S, 3)), np.empty(S, bool)
    specular_kernel.step(
        planes, image, cur, ok, normal, offset, boxes, tol, eps, True, x, start, at_edge
    )
    for s in range(S):
        if s >= S - 20:
            assert not ok[s] and not at_edge[s]
            np.testing.assert_array_equal(x[s], cur[s])
            continue
        n, d = normal[planes[s]], image[s] - cur[s]
        length = np.linalg.norm(d)
        if length == 0:
            assert at_edge[s]
            continue
        t = (offset[planes[s]] - cur[s] @ n) / (d @ n)
        point = cur[s] + max(t, 0.0) * d
        box = boxes[planes[s]]
        inside = np.all((box[0] - 2.01 * tol <= point) & (point <= box[1] + 2.01 * tol))
        assert ok[s] == (t * length > -tol and t < 1 and inside)
        np.testing.assert_allclose(x[s], point, atol=1e-9)
        np.testing.assert_allclose(start[s], cur[s] + eps * d / length, atol=1e-12)
        assert at_edge[s] == (max(t, 0.0) * length <= tol)
    assert ok.any() and not ok.all()


def _faces_on_planes(rng, P, per_plane):
    """Random triangles lying in P planes: corners (F, 3, 3), the plane of each face,
    the faces by plane (order, starts), plane boxes (P, 2, 3)."""
    normal, offset = _planes(rng, P)
    tri, plane = [], []
    for p in range(P):
        a = _unit(np.cross(normal[p], rng.normal(size=3)))
        b = np.cross(normal[p], a)
        for _ in range(per_plane):
            uv = rng.uniform(-1, 1, (3, 2))
            tri.append(normal[p] * offset[p] + uv[:, :1] * a + uv[:, 1:] * b)
            plane.append(p)
    tri, plane = np.array(tri), np.array(plane)
    order = np.argsort(plane, kind="stable")
    starts = np.searchsorted(plane[order], np.arange(P + 1))
    lo = np.array([tri[plane == p].reshape(-1, 3).min(axis=0) for p in range(P)])
    hi = np.array([tri[plane == p].reshape(-1, 3).max(axis=0) for p in range(P)])
    return tri, plane, order, starts, np.stack([lo, hi], axis=1)


def test_points_on_faces_by_their_barycentric_coordinates():
    rng = np.random.default_rng(2)
    tri, plane, order, starts, boxes = _faces_on_planes(rng, 4, 6)
    longest = np.linalg.norm(tri[:, 1:] - tri[:, :1], axis=2).max(axis=1)
    tol = 1e-3
    pids = rng.integers(0, 4, 300)
    # points near a face of their plane: some inside, some just outside
    f = np.array([order[rng.integers(starts[p], starts[p + 1])] for p in pids])
    b = rng.dirichlet([1, 1, 1], 300) * 1.2 - 0.0666
    x = np.einsum("ki,kij->kj", b, tri[f])
    on = specular_kernel.on_planes(pids, x, tol, boxes, order, starts, tri, longest)
    rows, faces = specular_kernel.holding(pids, x, tol, boxes, order, starts, tri, longest)
    expect_pairs = []
    for i, p in enumerate(pids):
        for q in order[starts[p] : starts[p + 1]]:
            margin = -_bary(tri[q], x[i]).min() * longest[q]
            if abs(margin - tol) < 1e-9:
                pytest.skip("a point on the tolerance's edge")  # pragma: no cover
            if margin <= tol:
                expect_pairs.append((i, q))
    assert list(zip(rows.tolist(), faces.tolist())) == expect_pairs
    assert on.tolist() == [i in {r for r, _ in expect_pairs} for i in range(300)]
    assert 0 < on.sum() < 300


def test_a_bounce_reflects_about_the_normal_on_the_rays_side():
    rng = np.random.default_rng(3)
    F, R = 12, 60
    tri = rng.normal(size=(F, 3, 3))
    normals = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    vn = _unit(normals[:, None] + 0.3 * rng.normal(size=(F, 3, 3)))
    curved = np.arange(F) % 2 == 1
    refl, diffuse = rng.uniform(0.5, 1, F), rng.uniform(0, 0.5, F)
    alive = np.sort(rng.choice(R, 40, replace=False))
    f = rng.integers(0, F, 40)
    dirs = _unit(rng.normal(size=(R, 3)))
    # origins such that the ray meets its face at a point inside it
    b = rng.dirichlet([2, 2, 2], 40)
    hit = np.einsum("ki,kij->kj", b, tri[f])
    t = rng.uniform(0.5, 3, 40)
    origin = rng.normal(size=(R, 3))
    origin[alive] = hit - t[:, None] * dirs[alive]
    length, power = rng.uniform(0, 1, R), rng.uniform(0, 1, R)
    o0, d0, l0, p0 = origin.copy(), dirs.copy(), length.copy(), power.copy()
    x, normal, mirror = np.empty((3, 40, 3))
    power_in = np.empty(40)
    world = (normals, curved, tri, vn, refl, diffuse)
    bounce_kernel.bounce(
        alive, t, f, origin, dirs, length, power, world, 1e-6, x, normal, mirror, power_in
    )
    for i, (r, k) in enumerate(zip(alive, f)):
        point = o0[r] + t[i] * d0[r]
        n = _unit(_bary(tri[k], point) @ vn[k]) if curved[k] else normals[k]
        n = -n if n @ d0[r] > 0 else n
        m = d0[r] - 2 * (d0[r] @ n) * n
        np.testing.assert_allclose(x[i], point, atol=1e-12)
        np.testing.assert_allclose(normal[i], n, atol=1e-9)
        np.testing.assert_allclose(mirror[i], m, atol=1e-9)
        np.testing.assert_allclose(dirs[r], m, atol=1e-9)
        np.testing.assert_allclose(origin[r], point + 1e-6 * n, atol=1e-9)
        assert length[r] == pytest.approx(l0[r] + t[i], abs=1e-15)
        assert power_in[i] == p0[r]
        assert power[r] == pytest.approx(p0[r] * refl[k] ** 2 * (1 - diffuse[k]), rel=1e-15)
    others = np.setdiff1d(np.arange(R), alive)
    np.testing.assert_array_equal(origin[others], o0[others])
    np.testing.assert_array_equal(power[others], p0[others])


def test_the_view_of_the_receiver_from_scattering_hits():
    rng = np.random.default_rng(4)
    K = 50
    x, normal = rng.normal(size=(K, 3)), _unit(rng.normal(size=(K, 3)))
    length, receiver = rng.uniform(0, 4, K), rng.normal(size=3)
    out = [np.empty((K, 3)), np.empty(K), np.empty((K, 3)), np.empty(K), np.empty(K, bool)]
    start = np.empty((K, 3))
    bounce_kernel.towards(x, normal, length, receiver, 5.0, 1e-6, *out, start)
    v, r2, u, cos_s, ok = out
    for i in range(K):
        d = receiver - x[i]
        np.testing.assert_allclose(v[i], d, atol=1e-15)
        assert r2[i] == pytest.approx(np.sqrt(d @ d), rel=1e-15)
        np.testing.assert_allclose(u[i], d / np.sqrt(d @ d), atol=1e-15)
        assert cos_s[i] == pytest.approx(normal[i] @ d / np.sqrt(d @ d), abs=1e-15)
        assert ok[i] == (normal[i] @ d > 0 and length[i] + np.sqrt(d @ d) <= 5.0)
        np.testing.assert_allclose(start[i], x[i] + 1e-6 * normal[i], atol=1e-15)
    assert ok.any() and not ok.all()


def test_rays_for_embree_relative_and_unit_in_float32():
    rng = np.random.default_rng(5)
    o, d = rng.normal(size=(30, 3)) * 100, rng.normal(size=(30, 3))
    d[3] = 0.0  # a zero direction stays zero
    centre = np.array([10.0, -3.0, 2.5])
    o32, d32 = np.empty((30, 3), np.float32), np.empty((30, 3), np.float32)
    embree_kernel.prepare(o, d, centre, o32, d32)
    for i in range(30):
        n = float(np.sqrt(sum(v * v for v in d[i])))
        want = d[i] / n if n > 0 else d[i]
        np.testing.assert_array_equal(o32[i], np.float32(o[i] - centre))
        np.testing.assert_allclose(d32[i], want, rtol=1e-7, atol=0)


def test_dense_ranks_are_the_ranks_among_the_distinct_values():
    rng = np.random.default_rng(6)
    for v in (
        rng.integers(-50, 50, 200),
        rng.integers(-(10**15), 10**15, 200),  # wide: sorted, not tabled
        np.array([7]),
    ):
        ranks, n = cluster_kernel.dense(v.astype(np.int64))
        distinct = sorted(set(v.tolist()))
        assert n == len(distinct)
        assert ranks.tolist() == [distinct.index(x) for x in v.tolist()]


def test_reflectors_are_intensity_weighted_means_per_cluster():
    rng = np.random.default_rng(7)
    K, n = 80, 9
    inv = rng.integers(0, n, K)
    inv[:n] = np.arange(n)
    inten, first, last = rng.uniform(0.1, 1, K), rng.uniform(1, 3, K), rng.uniform(1, 3, K)
    point, receiver = rng.normal(size=(K, 3)), rng.normal(size=3)
    dep, order = _unit(rng.normal(size=(K, 3))), rng.integers(1, 3, K)
    w, length, leg, direction, departure, mean_order = cluster_kernel.reflectors(
        inv, n, inten, first, last, point, receiver, dep, order
    )
    for k in range(n):
        m = inv == k
        p = inten[m]
        assert w[k] == pytest.approx(p.sum(), rel=1e-14)
        assert length[k] == pytest.approx((p * (first + last)[m]).sum() / p.sum(), rel=1e-14)
        assert leg[k] == pytest.approx((p * last[m]).sum() / p.sum(), rel=1e-14)
        u = (point[m] - receiver) / last[m][:, None]
        np.testing.assert_allclose(direction[k], _unit(p @ u), atol=1e-13)
        np.testing.assert_allclose(departure[k], _unit(p @ dep[m]), atol=1e-13)
        assert mean_order[k] == round((p * order[m]).sum() / p.sum())


def _sphere_faces(radius=0.1, subdivisions=2):
    """A tessellated sphere around the origin: corners (F, 3, 3), radial corner
    normals (F, 3, 3)."""
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions, radius)
    tri = mesh.vertices[mesh.faces]
    return tri, _unit(tri)


def test_glints_solve_the_smooth_normal_against_the_bisector():
    """Per face, the specular point of the smooth surface (the corner normals
    interpolated) found by scipy's least squares from the centroid: the kernel finds
    the same faces and points."""
    tri, vn = _sphere_faces()
    emitter, receiver = np.array([0.5, 0.05, 0.02]), np.array([0.45, -0.04, 0.03])

    def residual(b, k):
        bb = np.array([1 - b.sum(), *b])
        n, x = _unit(bb @ vn[k]), bb @ tri[k]
        return n - _unit(_unit(emitter - x) + _unit(receiver - x))

    faces = np.arange(len(tri))
    b = np.empty((len(faces), 2))
    ok = glint_kernel.specular_points(vn, tri, faces, emitter, receiver, 20, 8, 1e-6, 1e-7, 1e-4, b)
    assert 1 <= ok.sum() <= 3  # one point, on one face or on the edges of a few
    for k in faces:
        sol = least_squares(residual, np.full(2, 1 / 3), args=(k,), xtol=1e-15, ftol=1e-15)
        inside = min(1 - sol.x.sum(), sol.x.min()) >= -1e-4
        found = np.linalg.norm(residual(sol.x, k)) < 1e-9 and inside
        if found or ok[k]:
            assert found and ok[k]
            np.testing.assert_allclose(b[k], sol.x, atol=1e-6)


def _all_kernels_off(monkeypatch):
    from acousim.trace.rays import cluster, glints, scatter, shoot, specular
    from acousim.trace.world import embree

    for module in (cluster, glints, scatter, shoot, embree):
        monkeypatch.setattr(module, "optional_kernel", lambda *a, **k: None)
    monkeypatch.setattr(specular, "_kernels", lambda: None)


def _corridor(spectra: bool, bounces: int = 2):
    """The corridor scene; `spectra`: its plaster frequency-dependent (a table);
    `bounces`: 3, too many plane sequences to enumerate (the rays find them)."""
    if bounces != 2:
        scene = load_scene(CORRIDOR)
        simulation = dataclasses.replace(scene.simulation, bounces=bounces)
        return dataclasses.replace(scene, simulation=simulation)
    if not spectra:
        return load_scene(CORRIDOR)
    with open(CORRIDOR, "rb") as fh:
        doc = tomllib.load(fh)
    for m in doc["materials"]:
        if m["name"] == "plaster":
            m.update(frequencies_khz=[20.0, 80.0], reflection=[0.97, 0.9])
    return parse_scene(doc, base_dir=CORRIDOR.parent)


@pytest.mark.parametrize(("spectra", "bounces"), [(False, 2), (True, 2), (False, 3)])
def test_the_compiled_tracer_traces_the_paths_of_its_numpy_twin(monkeypatch, spectra, bounces):
    """The corridor's poses (and with a frequency-dependent plaster, and with three
    bounces) traced with every kernel and with none (numba missing): the same rays
    and paths, bit for bit but the glints (their search stops within 1e-7 of its
    root; the kernel solves its 2 x 2 steps in closed form, LAPACK otherwise), whose
    points agree within a nanometre."""
    scene = _corridor(spectra, bounces)
    poses = [scene.sensor.poses[i] for i in (10, 31, 52)]

    def traced(tracer):
        return [tracer.traced(p) for p in poses]

    compiled = traced(Tracer(scene))
    _all_kernels_off(monkeypatch)
    plain = traced(Tracer(scene))
    for (a, ra), (b, rb) in zip(compiled, plain):
        assert ra == rb
        glint = (a.order == 1) & (a.kind == KIND["scatter"]) & (a.first_leg_m > 0)
        for name in ("anchor_m", "first_leg_m", "strength", "position_m", "departure"):
            x, y = getattr(a, name), getattr(b, name)
            np.testing.assert_array_equal(x[~glint], y[~glint])
            np.testing.assert_allclose(x[glint], y[glint], rtol=0, atol=1e-9)
        np.testing.assert_array_equal(a.kind, b.kind)
        np.testing.assert_array_equal(a.order, b.order)
        np.testing.assert_array_equal(a.interactions, b.interactions)
        assert a.interactions.shape[1] == (2 if spectra else 0)


@pytest.mark.parametrize("spectra", [False, True])
def test_the_first_two_batches_at_once_make_the_contributions_of_each(monkeypatch, spectra):
    """Batches 0 and 1 followed and scattered in one pass: the same contributions,
    in the same order, as each batch followed and scattered alone."""
    from acousim.trace.rays import budget

    scene = _corridor(spectra)
    tracer = Tracer(scene)
    pose = scene.sensor.poses[40]
    args = (tracer.world, tracer.caster, tracer.settings)
    array = scene.sensor.array
    ends = (pose.to_world(array.emitter_m), pose.to_world(array.positions_m.mean(axis=0)))
    together = budget.ray_work(*args, *ends, pose.rotation[:, 0])
    monkeypatch.setattr(budget, "_first_two", lambda *a, **k: None)
    apart = budget.ray_work(*args, *ends, pose.rotation[:, 0])
    assert together.rays == apart.rays >= 2000
    assert together.met == apart.met
    names = ("point_m", "intensity", "first_leg_m", "last_leg_m", "surface", "order")
    for name in (*names, "lambert", "interactions"):
        np.testing.assert_array_equal(
            getattr(together.contributions, name), getattr(apart.contributions, name)
        )
