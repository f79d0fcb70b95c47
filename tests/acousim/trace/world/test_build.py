"""Preparing a world in near-linear time: the fast groupings against the slow, plain
ones (numpy's row sort, trimesh's adjacency), and a finely tessellated mesh prepared
into the same planes and curved patches as its coarse original."""

import dataclasses

import numpy as np
import trimesh

from acousim.scene import load_scene
from acousim.trace.world.build import build_world, face_adjacency, plane_ids, smooth_corner_normals
from acousim.trace.world.embree import RayCaster
from tests import REPO

SCENES = REPO / "scenes"


def test_plane_ids_are_numpys_sorted_unique_rows():
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(40, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[:5] = [0.0, 0.0, 1.0]
    normals[5:8] = [-0.0, 0.0, 1.0]  # -0.0 and 0.0 are one plane, as np.unique has it
    offsets = rng.normal(size=40)
    offsets[:8] = 1.0
    pick = rng.integers(0, 40, 5000)
    material = rng.integers(0, 2, 5000)
    for mat in (None, material):
        key = np.column_stack([np.round(normals[pick], 6), np.round(offsets[pick], 5)])
        if mat is not None:
            key = np.column_stack([key, mat])
        expected = np.unique(key, axis=0, return_inverse=True)[1].ravel()
        np.testing.assert_array_equal(plane_ids(normals[pick], offsets[pick], mat), expected)


def test_face_adjacency_is_trimeshs():
    for mesh in (
        trimesh.creation.icosphere(3),
        trimesh.creation.box(),
        trimesh.load(SCENES / "meshes" / "corridor.stl", force="mesh"),
    ):
        mesh.merge_vertices()
        pairs, edges = face_adjacency(np.asarray(mesh.faces))
        ours = set(map(tuple, np.column_stack([pairs, edges]).tolist()))
        theirs = np.column_stack([mesh.face_adjacency, mesh.face_adjacency_edges])
        assert ours == set(map(tuple, theirs.tolist()))


def test_a_subdivided_mesh_keeps_its_planes_and_curved_surfaces():
    """The corridor's mesh with every face split in 16 (11,328 faces): the same
    planar planes (by their normal and offset) and the same curved area, and the
    smooth corner normals of the curved faces are those of the whole mesh's."""
    scene = load_scene(SCENES / "corridor.toml")
    mesh = trimesh.load(SCENES / "meshes" / "corridor.stl", force="mesh", process=False)
    fine = mesh.subdivide().subdivide()
    worlds = [
        build_world(
            dataclasses.replace(scene, meshes=(dataclasses.replace(scene.meshes[0], mesh=m),))
        )
        for m in (mesh, fine)
    ]

    def planes(w):
        flat = ~w.curved
        key = np.column_stack([np.round(w.normals[flat], 5), np.round(w.offsets[flat], 4)])
        return set(map(tuple, np.unique(key, axis=0).tolist()))

    assert planes(worlds[0]) == planes(worlds[1])
    assert len(np.unique(worlds[1].plane[~worlds[1].curved])) == len(planes(worlds[0]))
    area = [w.area[w.curved].sum() for w in worlds]
    assert abs(area[1] / area[0] - 1) < 1e-9
    w = worlds[1]
    tri_mesh = trimesh.Trimesh(w.vertices, w.faces, process=False)
    every = smooth_corner_normals(
        w.triangles,
        w.faces,
        w.normals,
        tri_mesh.face_adjacency,
        tri_mesh.face_adjacency_angles,
        tri_mesh.face_adjacency_edges,
    )
    np.testing.assert_array_equal(w.vertex_normals[w.curved], every[w.curved])


def test_the_indexed_mesh_casts_the_same_rays():
    scene = load_scene(SCENES / "corridor.toml")
    world = build_world(scene)
    soup = RayCaster(world.triangles, 1)
    indexed = RayCaster(world.triangles, 1, indexed=(world.vertices, world.faces))
    rng = np.random.default_rng(0)
    origins = rng.uniform(-1, 1, (5000, 3)) * [10, 0.9, 1.2] + [10, 0, 1.3]
    dirs = rng.normal(size=(5000, 3))
    t0, f0 = soup.first_hit(origins, dirs)
    t1, f1 = indexed.first_hit(origins, dirs)
    np.testing.assert_array_equal(f0, f1)
    np.testing.assert_array_equal(t0, t1)
    assert (f0 >= 0).mean() > 0.5


def test_radix_argsort_is_a_stable_sort():
    from acousim.trace.world.build import radix_argsort

    rng = np.random.default_rng(1)
    for top in (1, 300, 70_000, 2**40):
        code = rng.integers(0, top, 5000)
        np.testing.assert_array_equal(radix_argsort(code), np.argsort(code, kind="stable"))


def test_row_groups_are_numpys_unique_rows():
    """The first row of every group and the group of every row, numbered as
    np.unique numbers the rows' hashes: distinct rows, and rows with repeats."""
    from acousim.trace.world.build import row_groups

    rng = np.random.default_rng(8)
    distinct = rng.permutation(3000).reshape(-1, 3).astype(np.int64)
    repeats = rng.integers(0, 4, (3000, 3)).astype(np.int64)
    for key in (distinct, repeats):
        first, group = row_groups(key)
        np.testing.assert_array_equal(key[first][group], key)  # each row in its group
        assert len(first) == len(np.unique(key, axis=0))
        # the first row of a group comes before every other row of it
        assert np.all(first[group] <= np.arange(len(key)))


def test_a_mesh_is_cleaned_as_trimesh_cleans_it():
    """clean_mesh against trimesh's own steps (merge_vertices, nondegenerate_faces,
    unique_faces, remove_unreferenced_vertices): a soup with near-duplicate
    vertices, repeated and degenerate faces and an unused vertex."""
    from acousim.trace.world.mesh_index import clean_mesh

    rng = np.random.default_rng(1)
    v = np.round(rng.uniform(0, 1, (300, 3)), 2)
    v[::7] = v[1::7] + 3e-9  # equal to 1e-8 m: merged
    f = rng.integers(0, 300, (2000, 3))
    f[::11] = f[1::11]  # repeated faces
    f[::13, 2] = f[::13, 1]  # degenerate faces
    mesh = trimesh.Trimesh(np.vstack([v, [[9.0, 9.0, 9.0]]]), f, process=False)
    ours = clean_mesh(mesh.copy())
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces(height=1e-9))
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    np.testing.assert_array_equal(ours.vertices, mesh.vertices)
    np.testing.assert_array_equal(ours.faces, mesh.faces)
    np.testing.assert_array_equal(ours.cross, mesh.triangles_cross)
    assert ours.distinct


def test_a_mesh_in_memory_is_never_changed():
    """A trimesh mesh given to a scene keeps its vertices and faces, placed by a
    transform or not, with or without vertex normals (trimesh's own merge)."""
    scene = load_scene(SCENES / "shoebox.toml")
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0)).subdivide()
    smooth = trimesh.creation.icosphere(2)
    _ = smooth.vertex_normals  # cached: merged by trimesh with its normals
    moved = np.eye(4)
    moved[:3, 3] = [0.5, 0.0, 0.0]
    for mesh in (box, smooth):
        before = (mesh.vertices.copy(), mesh.faces.copy())
        for transform in (np.eye(4), moved):
            item = dataclasses.replace(scene.meshes[0], mesh=mesh, transform=transform)
            world = build_world(dataclasses.replace(scene, meshes=(item,)))
            assert world.n_faces == len(before[1])
            assert np.allclose(
                world.triangles.reshape(-1, 3).min(axis=0), before[0].min(axis=0) + transform[:3, 3]
            )
        np.testing.assert_array_equal(mesh.vertices, before[0])
        np.testing.assert_array_equal(mesh.faces, before[1])


def test_a_binary_stl_is_read_as_trimesh_reads_it(tmp_path):
    """The direct binary STL reader against trimesh's (unprocessed): the same vertices
    (float64 of the file's float32) and faces; an ASCII STL is left to trimesh."""
    from acousim.scene.mesh_file import binary_stl as _binary_stl

    for path in sorted((SCENES / "meshes").glob("*.stl")):
        ours = _binary_stl(path)
        theirs = trimesh.load(path, force="mesh", process=False)
        assert ours is not None, path
        assert ours.vertices.dtype == theirs.vertices.dtype
        np.testing.assert_array_equal(ours.vertices, theirs.vertices)
        np.testing.assert_array_equal(ours.faces, theirs.faces)
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    box.export(tmp_path / "box.stl", file_type="stl_ascii")
    assert _binary_stl(tmp_path / "box.stl") is None
    box.export(tmp_path / "box_binary.stl")
    read = _binary_stl(tmp_path / "box_binary.stl")
    np.testing.assert_allclose(read.vertices[read.faces], box.vertices[box.faces], atol=1e-6)
