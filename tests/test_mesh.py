"""Mesh container, loading, checks and repair."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import grid_mesh, with_caps

from anseg.mesh import MAX_COORDINATE, Mesh, MeshError, repair
from anseg.mesh_files import load_mesh, save_mesh

TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def write_off(path, vertices, faces):
    lines = ["OFF", f"{len(vertices)} {len(faces)} 0"]
    lines += [" ".join(map(str, v)) for v in vertices]
    lines += ["3 " + " ".join(map(str, f)) for f in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_tetrahedron_quantities():
    m = Mesh(TETRA_V, TETRA_F).validate()
    assert m.face_areas == pytest.approx([0.5, 0.5, 0.5, np.sqrt(3) / 2])
    assert np.allclose(np.linalg.norm(m.face_normals, axis=1), 1)
    # outward orientation: normals point away from the centroid
    assert ((m.face_centroids - TETRA_V.mean(0)) * m.face_normals).sum(1).min() > 0
    assert len(m.edges) == 6 and m.euler_characteristic == 2 and m.boundary_loop_count == 0
    assert (m.face_neighbors >= 0).all() and len(m.face_adjacency) == 6
    # a convex solid: every edge convex
    assert (m.dihedral_angles > 0).all()


def test_edge_order_is_first_appearance():
    m = Mesh(TETRA_V, TETRA_F)
    assert m.edges[:3].tolist() == [[0, 2], [1, 2], [0, 1]]
    # local edge k of face f joins faces[f, k] and faces[f, k+1]
    for f in range(4):
        for k in range(3):
            assert sorted(m.edges[m.face_edges[f, k]]) == sorted([m.faces[f, k], m.faces[f, (k + 1) % 3]])


def test_neighbors_are_symmetric_on_grid():
    m = grid_mesh(5)
    nb = m.face_neighbors
    assert m.boundary_loop_count == 1 and m.euler_characteristic == 1
    assert (nb == -1).sum() == 20  # the 20 boundary edges of a 5x5 grid
    for f, k in zip(*np.nonzero(nb >= 0)):
        assert f in nb[nb[f, k]]
    assert np.allclose(m.dihedral_angles, 0)


def test_concave_edge_has_negative_dihedral():
    # two triangles folded like a valley (normals +z, opposite vertices raised)
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0.5], [0.5, -1, 0.5]], float)
    m = Mesh(v, [[0, 1, 2], [1, 0, 3]])
    assert m.dihedral_angles[0] < 0
    m_ridge = Mesh(v * [1, 1, -1], [[0, 1, 2], [1, 0, 3]])
    assert m_ridge.dihedral_angles[0] > 0


def test_normalized_has_unit_area_and_centre():
    m = Mesh(TETRA_V * 13.0 + 5, TETRA_F).unit_area()
    assert m.face_areas.sum() == pytest.approx(1.0)
    assert np.allclose((m.face_centroids * m.face_areas[:, None]).sum(0), 0, atol=1e-12)


def test_unit_area_copy_is_made_once_and_its_shared_tables_equal_its_own():
    mesh = grid_mesh(4)
    neighbors = mesh.face_neighbors
    copy = mesh.unit_area()
    assert mesh.unit_area() is copy
    assert copy.face_neighbors is neighbors  # shared, not built again
    fresh = Mesh(copy.vertices, copy.faces)
    for table in ("edges", "face_edges", "edge_faces", "face_neighbors", "corner_fans", "vertex_components"):
        assert np.array_equal(getattr(copy, table), getattr(fresh, table)), table
    assert copy.boundary_loop_count == fresh.boundary_loop_count == 1


def test_unit_area_copy_without_unused_vertices_builds_its_own_tables():
    mesh = Mesh(np.vstack([TETRA_V, [[9.0, 9.0, 9.0]]]), TETRA_F).validate()
    copy = mesh.unit_area()
    assert copy.n_vertices == 4 and "_edge_table" not in copy.__dict__
    assert np.array_equal(copy.edges, Mesh(TETRA_V, TETRA_F).edges)


@pytest.mark.parametrize("suffix", [".off", ".obj", ".ply"])
def test_save_load_roundtrip_keeps_order(tmp_path, suffix):
    m = grid_mesh(3)
    path = tmp_path / f"grid{suffix}"
    save_mesh(path, m)
    back = load_mesh(path)
    assert np.array_equal(back.faces, m.faces)
    assert np.allclose(back.vertices, m.vertices)
    assert back.vertices.dtype == np.float64 and back.faces.dtype == np.int64


def test_load_errors(tmp_path):
    with pytest.raises(MeshError, match="no such file"):
        load_mesh(tmp_path / "missing.off")
    bad = tmp_path / "bad.off"
    bad.write_text("this is not a mesh\n")
    with pytest.raises(MeshError):
        load_mesh(bad)
    with pytest.raises(MeshError, match="unsupported format"):
        load_mesh(write_off(tmp_path / "m.3ds", TETRA_V, TETRA_F))
    ragged = tmp_path / "ragged.obj"  # a vertex line short of a coordinate (found by the reader fuzz test)
    ragged.write_text("v 0 0 0\nv 1 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n")
    with pytest.raises(MeshError, match="without 3 entries"):
        load_mesh(ragged)
    superscript = tmp_path / "superscript.off"  # a header count that str.isdigit() takes and int() refuses
    superscript.write_bytes(b"OFF\n4 2\xb2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 2 3\n")
    with pytest.raises(MeshError):
        load_mesh(superscript)


ALL_FORMATS = (".off", ".obj", ".ply", ".stl", ".glb", ".gltf")


def test_an_unsupported_format_is_named_with_every_supported_one(tmp_path):
    with pytest.raises(MeshError, match="unsupported format '.3ds'") as error:
        load_mesh(write_off(tmp_path / "m.3ds", TETRA_V, TETRA_F))
    assert all(suffix in str(error.value) for suffix in ALL_FORMATS)
    with pytest.raises(MeshError, match=r"cannot write '\.stl'.*\.off, \.obj, \.ply"):
        save_mesh(tmp_path / "m.stl", Mesh(TETRA_V, TETRA_F))


def face_components(mesh: Mesh) -> int:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = mesh.face_adjacency
    return connected_components(coo_matrix((np.ones(len(pairs)), tuple(pairs.T)), shape=(mesh.n_faces,) * 2), directed=False)[0]


@pytest.mark.parametrize("file_type", ["stl", "stl_ascii"])
def test_stl_reads_as_the_same_connected_mesh(tmp_path, file_type):
    import trimesh

    m = grid_mesh(4, closed=True)
    path = tmp_path / "sphere.stl"
    trimesh.Trimesh(m.vertices, m.faces, process=False).export(path, file_type=file_type)
    back = load_mesh(path)
    # the same faces in the same order, vertices renumbered one to one (STL keeps corners, not vertex numbers)
    assert back.n_faces == m.n_faces and back.n_vertices == m.n_vertices
    renumber = np.full(m.n_vertices, -1)
    renumber[m.faces.ravel()] = back.faces.ravel()
    assert np.array_equal(renumber[m.faces], back.faces)
    assert np.allclose(back.vertices[renumber], m.vertices, atol=1e-6)
    assert face_components(back) == 1 and back.boundary_loop_count == 0


def test_a_glb_scene_is_one_mesh_with_the_node_transforms_applied(tmp_path):
    import trimesh
    from scipy.spatial import cKDTree

    box, tetra = trimesh.creation.box(), trimesh.Trimesh(TETRA_V, TETRA_F, process=False)
    turn = trimesh.transformations.rotation_matrix(np.pi / 3, [0, 0, 1])
    move = trimesh.transformations.translation_matrix([5.0, -2.0, 1.0]) @ turn
    scene = trimesh.Scene()
    scene.add_geometry(box, node_name="box", transform=move)
    scene.add_geometry(tetra, node_name="tetra", transform=trimesh.transformations.translation_matrix([-3.0, 0, 0]))
    path = tmp_path / "two.glb"
    scene.export(path)
    back = load_mesh(path)
    expected = np.concatenate([trimesh.transform_points(box.vertices, move)[box.faces], (TETRA_V - [3.0, 0, 0])[TETRA_F]])
    assert back.n_faces == len(expected) and back.n_vertices == len(box.vertices) + len(TETRA_V)
    got = back.vertices[back.faces]
    gap, match = cKDTree(got.mean(axis=1)).query(expected.mean(axis=1))  # the scene's order of meshes is trimesh's
    assert np.sort(match).tolist() == list(range(len(expected)))
    assert np.allclose(got[match], expected, atol=1e-5)
    assert face_components(back) == 2


def test_a_scene_without_triangles_is_one_clear_error(tmp_path):
    path = tmp_path / "empty.gltf"
    path.write_text('{"asset": {"version": "2.0"}, "scenes": [{"nodes": []}], "scene": 0}')
    with pytest.raises(MeshError, match="no triangle mesh"):
        load_mesh(path, validate=False)


STRAY = [1e9, 1e9, 1e9]


@pytest.mark.parametrize("extra_face, message", [(None, None), ("degenerate", "of zero area"), ("repeated", "repeat")])
def test_an_unreferenced_far_vertex_changes_no_check(extra_face, message):
    # CAD exports leave vertices that no face uses; far away, they once made every face "zero-area"
    base = grid_mesh(4, closed=True)
    extra = {None: np.zeros((0, 3), int), "degenerate": [[0, 1, 1]], "repeated": base.faces[:1]}[extra_face]
    faces = np.vstack([base.faces, extra])
    with_stray = Mesh(np.vstack([STRAY, base.vertices]), faces + 1)
    if message is None:
        Mesh(base.vertices, faces).validate()
        with_stray.validate()
        return
    for mesh in (Mesh(base.vertices, faces), with_stray):
        with pytest.raises(MeshError, match=message):
            mesh.validate()


def test_repair_drops_an_unreferenced_far_vertex_and_keeps_every_face():
    base = grid_mesh(4, closed=True)
    fixed, face_map = repair(Mesh(np.vstack([STRAY, base.vertices]), base.faces + 1))
    assert face_map.tolist() == list(range(base.n_faces))
    assert np.array_equal(fixed.faces, base.faces) and np.array_equal(fixed.vertices, base.vertices)
    # a tiny real triangle still counts against the used vertices' scale, not the stray one's
    v = np.vstack([STRAY, base.vertices, [[0, 0, 2], [1e-4, 0, 2], [0, 1e-4, 2]]])
    n = len(v)
    fixed, face_map = repair(Mesh(v, np.vstack([base.faces + 1, [n - 3, n - 2, n - 1]])))
    assert len(face_map) == base.n_faces + 1


@pytest.mark.parametrize(
    "vertices, faces, message",
    [
        (np.zeros((0, 3)), np.zeros((0, 3), int), "empty"),
        (np.where(np.arange(12).reshape(4, 3) == 4, np.nan, TETRA_V), TETRA_F, "NaN or infinite"),
        (np.where(np.arange(12).reshape(4, 3) == 4, np.inf, TETRA_V), TETRA_F, "NaN or infinite"),
        (np.where(np.arange(12).reshape(4, 3) == 4, -1e300, TETRA_V), TETRA_F, "beyond 3.4e\\+38"),
        (TETRA_V, np.vstack([TETRA_F[:3], [1, 2, 7]]), "index missing vertices"),
        (np.vstack([TETRA_V, [2, 0, 0]]), np.vstack([TETRA_F, [0, 1, 4]]), "of zero area"),
        (np.vstack([TETRA_V, [1, 1, 1]]), np.vstack([TETRA_F, [1, 2, 4]]), "non-manifold"),
    ],
)
def test_validate_errors(vertices, faces, message):
    with pytest.raises(MeshError, match=message):
        Mesh(vertices, faces).validate()


def test_coordinates_up_to_the_limit_are_checked_without_overflow_and_beyond_it_refused():
    """A flipped exponent byte in a binary file gives coordinates like 1e300, whose squares overflow float64."""
    largest = TETRA_V / np.abs(TETRA_V).max() * MAX_COORDINATE
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert Mesh(largest, TETRA_F).validate().n_faces == 4
        assert repair(Mesh(largest, TETRA_F))[0].n_faces == 4
        beyond = largest.copy()
        beyond[1, 2] = np.nextafter(-MAX_COORDINATE, -np.inf)
        with pytest.raises(MeshError, match="1 vertices have coordinates beyond"):
            Mesh(beyond, TETRA_F).validate()
        with pytest.raises(MeshError, match="cannot repair coordinates beyond"):
            repair(Mesh(beyond, TETRA_F))


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_file_with_an_overflowing_coordinate_gives_a_mesh_error(tmp_path):
    path = write_off(tmp_path / "huge.off", np.where(np.arange(12).reshape(4, 3) == 4, 1e300, TETRA_V), TETRA_F)
    with pytest.raises(MeshError, match=r"huge\.off: 1 vertices have coordinates beyond"):
        load_mesh(path)


def test_load_reports_file_and_problem(tmp_path):
    path = write_off(tmp_path / "nm.off", np.vstack([TETRA_V, [1, 1, 1]]), np.vstack([TETRA_F, [1, 2, 4]]))
    with pytest.raises(MeshError, match=r"nm\.off.*non-manifold"):
        load_mesh(path)
    assert load_mesh(path, validate=False).n_faces == 5


def test_shape_errors():
    with pytest.raises(MeshError, match=r"\(V, 3\)"):
        Mesh(np.zeros((4, 2)), TETRA_F)
    with pytest.raises(MeshError, match="triangles only"):
        Mesh(TETRA_V, np.zeros((2, 4), int))


def test_repair_merges_and_drops_with_face_map():
    # duplicate vertex 4 == vertex 0; a degenerate face; a duplicate face
    v = np.vstack([TETRA_V, TETRA_V[0]])
    f = np.array([[4, 2, 1], [0, 1, 3], [0, 0, 2], [0, 3, 2], [1, 2, 3], [3, 1, 0]])
    fixed, face_map = repair(Mesh(v, f))
    assert face_map.tolist() == [0, 1, 3, 4]
    assert fixed.n_vertices == 4 and fixed.n_faces == 4
    fixed.validate()
    # repaired faces are the input faces (through the vertex merge), in input order
    assert np.allclose(fixed.vertices[fixed.faces], v[f[face_map]])
    labels = np.array([10, 11, 12, 13, 14, 15])
    assert labels[face_map].tolist() == [10, 11, 13, 14]


def test_repair_refuses_what_it_cannot_fix():
    with pytest.raises(MeshError, match="NaN"):
        repair(Mesh(np.full((3, 3), np.nan), [[0, 1, 2]]))
    with pytest.raises(MeshError, match="missing vertices"):
        repair(Mesh(TETRA_V, [[0, 1, 9]]))
    with pytest.raises(MeshError, match="no faces left"):
        repair(Mesh(TETRA_V, [[0, 0, 1]]))


def two_spheres_sharing_a_vertex() -> Mesh:
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=1)
    n = len(sphere.vertices)
    a, b = np.argmax(sphere.vertices[:, 0]), np.argmin(sphere.vertices[:, 0])  # a of the left touches b of the right
    right = sphere.faces + n
    right[right == n + b] = a  # one shared vertex index
    return Mesh(np.vstack([sphere.vertices, sphere.vertices + [2.0 * sphere.vertices[a, 0], 0, 0]]),
                np.vstack([sphere.faces, right]))


def two_cones_touching_at_their_apex() -> Mesh:
    ring = np.stack([np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3), np.zeros(6)], axis=1)
    vertices = np.vstack([[0, 0, 0], ring + [0, 0, 1], [0, 0, 1], ring - [0, 0, 1], [0, 0, -1]])
    faces = []
    for base, centre in ((1, 7), (8, 14)):
        for k in range(6):
            i, j = base + k, base + (k + 1) % 6
            faces += [[0, i, j], [centre, j, i]]
    return Mesh(vertices, np.array(faces))


def grid_with_a_fin(fins: int = 1) -> Mesh:
    grid = grid_mesh(4)
    u, w = grid.edges[grid.edge_face_counts == 2][0]  # an interior edge
    vertices, faces = [grid.vertices], [grid.faces]
    for k in range(fins):
        tip = (grid.vertices[u] + grid.vertices[w]) / 2 + [0.3 * k, 0, 1.0]
        vertices.append(tip[None])
        faces.append(np.array([[u, w, grid.n_vertices + k]]))
    return Mesh(np.vstack(vertices), np.vstack(faces))


@pytest.mark.parametrize("make, message", [
    (two_spheres_sharing_a_vertex, "1 non-manifold vertices"),
    (two_cones_touching_at_their_apex, "1 non-manifold vertices"),
    (lambda: grid_with_a_fin(1), "non-manifold edges"),
    (lambda: grid_with_a_fin(2), "non-manifold edges"),
])
def test_repair_cuts_non_manifold_edges_and_vertices_apart(make, message):
    mesh = make()
    with pytest.raises(MeshError, match=message):
        mesh.validate()
    fixed, face_map = repair(mesh)
    fixed.validate()
    assert face_map.tolist() == list(range(mesh.n_faces))  # nothing dropped, the order kept
    np.testing.assert_array_equal(fixed.vertices[fixed.faces], mesh.vertices[mesh.faces])  # the same triangles
    assert fixed.n_vertices > len(np.unique(mesh.faces))  # vertices were copied where sheets meet


def test_a_manifold_mesh_has_one_fan_per_vertex():
    for mesh in (grid_mesh(5), grid_mesh(4, closed=True), Mesh(TETRA_V, TETRA_F)):
        assert mesh.corner_fans.max() + 1 == mesh.n_vertices
        assert (mesh.corner_fans.ravel() >= 0).all()
    fixed, face_map = repair(grid_mesh(5))
    assert fixed.n_vertices == grid_mesh(5).n_vertices and face_map.tolist() == list(range(fixed.n_faces))


def test_labels_go_back_to_every_input_face():
    from anseg.mesh import labels_for_input_faces

    v = np.vstack([TETRA_V, TETRA_V[0]])
    f = np.array([[4, 2, 1], [0, 1, 3], [0, 0, 2], [0, 3, 2], [1, 2, 3], [3, 1, 0]])
    mesh = Mesh(v, f)
    fixed, face_map = repair(mesh)
    labels = labels_for_input_faces(np.array([10, 11, 13, 14]), face_map, mesh)
    assert labels.tolist()[:2] == [10, 11] and labels[5] == 11  # the repeated face takes its twin's label
    assert labels[2] in (10, 11, 13, 14) and labels[3] == 13 and labels[4] == 14


@pytest.mark.realdata
@pytest.mark.slow
def test_a_psb_mesh_with_a_fin_is_repaired_and_segmented_face_for_face(psb_sample):
    mesh = psb_sample["Teddy"][0].mesh
    u, w = mesh.edges[mesh.edge_face_counts == 2][0]
    tip = (mesh.vertices[u] + mesh.vertices[w]) / 2 + 0.05 * np.ptp(mesh.vertices, axis=0).max() * mesh.face_normals[0]
    glued = Mesh(np.vstack([mesh.vertices, tip]), np.vstack([mesh.faces, [[u, w, mesh.n_vertices]]]))
    with pytest.raises(MeshError, match="non-manifold edges"):
        glued.validate()
    fixed, face_map = repair(glued)
    fixed.validate()
    assert face_map.tolist() == list(range(glued.n_faces))
    np.testing.assert_allclose(fixed.face_areas, glued.face_areas)
    # and it segments, one label per input face (a tiny model trained on synthetic shapes will do)
    import torch

    from anseg import datasets
    from anseg.mesh import labels_for_input_faces
    from anseg.pipeline import SegmentConfig, segment
    from anseg.train import TrainConfig, fit

    torch.set_num_threads(1)
    shapes = datasets.load("synthetic", "figure", "train", n_shapes=4, progress=False)
    model = fit(shapes[:2], shapes[0].label_names, SegmentConfig(cycles=1, clusters=4), TrainConfig(epochs=1, width=16, depth=1),
                progress=False)
    labels = labels_for_input_faces(segment(fixed, model).labels, face_map, glued)
    assert labels.shape == (glued.n_faces,) and labels.min() >= 0


def test_a_valid_mesh_is_checked_once(monkeypatch):
    mesh = grid_mesh(4, 4)
    assert mesh.validate() is mesh
    monkeypatch.setattr(Mesh, "corner_fans", property(lambda self: pytest.fail("checked again")))
    assert mesh.validate() is mesh
    broken = Mesh(mesh.vertices, np.vstack([mesh.faces, mesh.faces[:1]]))  # a new mesh is checked in full
    with pytest.raises(MeshError, match="repeat"):
        broken.validate()


def sphere_and_a_far_facet() -> tuple[Mesh, Mesh]:
    sphere = grid_mesh(5, closed=True)
    far = np.array([[1e9, 1e9, 1e9], [1e9 + 1, 1e9, 1e9], [1e9, 1e9 + 1, 1e9]])
    n = sphere.n_vertices
    return sphere, Mesh(np.vstack([sphere.vertices, far]), np.vstack([sphere.faces, [[n, n + 1, n + 2]]]))


def test_degeneracy_is_judged_per_face_not_against_the_whole_mesh():
    sphere, with_far = sphere_and_a_far_facet()
    with_far.validate()  # the far facet is a good triangle, and makes no other face "zero-area"
    fixed, face_map = repair(with_far)
    assert face_map.tolist() == list(range(with_far.n_faces))
    assert np.array_equal(fixed.vertices[fixed.faces][: sphere.n_faces], sphere.vertices[sphere.faces])
    from anseg.mesh import degenerate_faces

    # scale and position change nothing; a needle is degenerate however small or large the rest
    needle = Mesh(np.vstack([TETRA_V, [[0.5, 1e-12, 0]]]), np.vstack([TETRA_F, [[0, 1, 4]]]))
    for scale, shift in ((1.0, 0.0), (1e-6, 0.0), (1e6, 0.0), (1.0, 1e6)):
        moved = Mesh(needle.vertices * scale + shift, needle.faces)
        assert degenerate_faces(moved).tolist() == [False] * 4 + [True]


def test_repair_refuses_to_drop_most_of_a_mesh():
    sphere = grid_mesh(5, closed=True)
    flat = sphere.vertices * [1, 1, 0]  # every face squashed onto a plane: most become degenerate
    with pytest.raises(MeshError, match=r"repair would drop most faces: \d+ of \d+ are degenerate.*more than 50%"):
        repair(Mesh(np.vstack([flat, sphere.vertices + 5]), np.vstack([sphere.faces, sphere.faces[:10] + sphere.n_vertices])))


def test_library_errors_name_the_function_not_the_flag():
    for mesh in (Mesh(np.vstack([TETRA_V, [2, 0, 0]]), np.vstack([TETRA_F, [0, 1, 4]])),
                 Mesh(TETRA_V, np.vstack([TETRA_F, TETRA_F[:1]]))):
        with pytest.raises(MeshError, match=r"anseg\.repair\(mesh\)") as error:
            mesh.validate()
        assert "--repair" not in str(error.value)


def test_a_folder_or_a_short_file_is_named_as_such(tmp_path):
    with pytest.raises(MeshError, match="is a directory"):
        load_mesh(tmp_path)
    full = write_off(tmp_path / "m.off", TETRA_V, TETRA_F).read_text()
    (tmp_path / "short.off").write_text(full[: full.rindex("3 ")])  # the last face line gone: the reader stops quietly
    with pytest.raises(MeshError, match="holds only 3 of the 4 face elements its header declares"):
        load_mesh(tmp_path / "short.off")


def test_faces_of_zero_area_are_refused_and_slivers_pass():
    """Three corners on a line have no area and are refused; caps 1e-12 as high as long have one, and pass."""
    from anseg.mesh import degenerate_faces, zero_area_faces

    base = grid_mesh(4, closed=True)
    a, b = base.vertices[base.faces[0, :2]]
    on_line = Mesh(np.vstack([base.vertices, (a + b) / 2]), np.vstack([base.faces, [[base.faces[0, 0], base.faces[0, 1],
                                                                                   base.n_vertices]]]))
    assert zero_area_faces(on_line)[-1] and not zero_area_faces(on_line)[:-1].any()
    with pytest.raises(MeshError, match=r"^1 face of zero area \(first: \d+\)"):
        on_line.validate()
    capped = with_caps(base, 3)
    assert degenerate_faces(capped).sum() == 3 and not zero_area_faces(capped).any()
    capped.validate()


def test_repair_keeps_slivers_unless_asked_to_drop_them():
    """Slivers pass validation, so repair keeps them; the data set readers drop them (drop_slivers), as before."""
    capped = with_caps(grid_mesh(4, closed=True), 3)
    assert len(repair(capped)[1]) == capped.n_faces
    assert len(repair(capped, drop_slivers=True)[1]) == capped.n_faces - 3
