"""Line k of a label file describes face k of the mesh file: readers keep the file's order, polygons stay whole."""

from __future__ import annotations

import struct
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import grid_mesh

from anseg import cli
from anseg.cli import main
from anseg.mesh import Mesh, MeshError
from anseg.mesh_files import load_mesh, save_mesh

TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def prism(n: int = 5) -> tuple[np.ndarray, list[list[int]]]:
    """A closed prism as the file holds it: a pentagon, five quads, a pentagon (outward)."""
    angle = 2 * np.pi * (np.arange(n) + 0.5) / n
    ring = np.column_stack([np.cos(angle), np.sin(angle), np.zeros(n)])
    sides = [[i, (i + 1) % n, (i + 1) % n + n, i + n] for i in range(n)]
    return np.vstack([ring, ring + [0, 0, 1]]), [list(range(n))[::-1], *sides, list(range(n, 2 * n))]


def write_polygons(path, vertices, polygons, binary=False):
    """OBJ (a material switch every two faces, as Blender writes), OFF, or PLY with an extra edge element."""
    suffix = path.suffix
    if suffix == ".obj":
        lines = ["mtllib m.mtl", *(f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist())]
        for k, p in enumerate(polygons):
            lines += [f"usemtl {'red' if k % 4 == 0 else 'blue'}"] if k % 2 == 0 else []
            lines.append("f " + " ".join(f"{i + 1}/{i + 1}" for i in p))
        (path.parent / "m.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n")
    elif suffix == ".off":
        lines = ["OFF", f"{len(vertices)} {len(polygons)} 0", *(" ".join(map(repr, v)) for v in vertices.tolist()),
                 *(" ".join(map(str, [len(p), *p])) for p in polygons)]
    else:  # an edge element, with a list property, after the faces: left out by the reader
        header = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", f"element vertex {len(vertices)}",
                  *(f"property double {a}" for a in "xyz"), f"element face {len(polygons)}",
                  "property list uchar int vertex_indices", "element edge 1", "property list uchar int vertex_indices",
                  "end_header"]
        if binary:
            body = vertices.astype("<f8").tobytes() + b"".join(struct.pack(f"<B{len(p)}i", len(p), *p) for p in polygons)
            path.write_bytes(("\n".join(header) + "\n").encode() + body + struct.pack("<B2i", 2, 0, 1))
            return path
        lines = header + [" ".join(map(repr, v)) for v in vertices.tolist()]
        lines += [" ".join(map(str, [len(p), *p])) for p in polygons] + ["2 0 1"]
    path.write_text("\n".join(lines) + "\n")
    return path


def fan(polygons):
    """What the readers promise: polygon k as triangles (c0, c1, c2), (c0, c2, c3), ..., right after polygon k-1's."""
    return [[p[0], p[j], p[j + 1]] for p in polygons for j in range(1, len(p) - 1)]


@pytest.mark.parametrize("name", ["prism.obj", "prism.off", "prism.ply", "binary.ply"])
def test_polygons_are_read_as_fans_in_file_order(tmp_path, name):
    vertices, polygons = prism()
    path = write_polygons(tmp_path / name, vertices, polygons, binary=name.startswith("binary"))
    mesh = load_mesh(path)
    assert mesh.faces.tolist() == fan(polygons) and np.array_equal(mesh.vertices, vertices)
    from anseg.mesh_files import load_mesh_with_faces

    _, file_face = load_mesh_with_faces(path)
    assert file_face.tolist() == [k for k, p in enumerate(polygons) for _ in range(len(p) - 2)]


def test_an_obj_whose_faces_switch_material_reads_in_file_order(tmp_path):
    sphere = grid_mesh(4, closed=True)
    path = write_polygons(tmp_path / "sphere.obj", sphere.vertices, sphere.faces.tolist())
    mesh = load_mesh(path)  # a clean closed mesh: no "non-manifold vertices" from faces grouped by material
    assert np.array_equal(mesh.faces, sphere.faces) and np.array_equal(mesh.vertices, sphere.vertices)


def test_a_polygon_takes_the_label_covering_most_of_its_area():
    from anseg.mesh_files import labels_for_file_faces

    # a quad read as (0, 1, 2) of area 2 and (0, 2, 3) of area 6, then a triangle
    mesh = Mesh([[0, 0, 0], [4, 0, 0], [4, 1, 0], [0, 3, 0], [0, 0, 1]], [[0, 1, 2], [0, 2, 3], [0, 1, 4]])
    assert labels_for_file_faces([0, 1, 0], [0, 0, 1], mesh).tolist() == [1, 0]
    assert labels_for_file_faces([1, 0, 2], [0, 0, 1], mesh).tolist() == [0, 2]
    assert labels_for_file_faces([2, 0, 1], [0, 1, 2], mesh).tolist() == [2, 0, 1]


def direction(normals: np.ndarray) -> np.ndarray:
    """A label per normal: which axis it is nearest to, and which way (0 .. 5)."""
    axis = np.abs(normals).argmax(axis=1)
    return 2 * axis + (normals[np.arange(len(normals)), axis] > 0)


def stub_model(monkeypatch):
    """A model that labels each triangle by the direction of its normal: what is tested is where the labels go."""
    import anseg.pipeline

    model = SimpleNamespace(config=None, n_classes=6, label_names=[f"part{i}" for i in range(6)],
                            network=SimpleNamespace(parameters=lambda: iter([SimpleNamespace(device="cpu")])))
    monkeypatch.setattr(cli, "_load_model", lambda path: model)
    monkeypatch.setattr(anseg.pipeline, "segment", lambda mesh, *a, **k: SimpleNamespace(labels=direction(mesh.face_normals)))


@pytest.mark.parametrize("name", ["prism.obj", "binary.ply"])
@pytest.mark.parametrize("repair", [[], ["--repair"]])
def test_segment_writes_line_k_for_file_face_k(tmp_path, monkeypatch, capsys, name, repair):
    stub_model(monkeypatch)
    vertices, polygons = prism()
    path = write_polygons(tmp_path / name, vertices, polygons, binary=name.startswith("binary"))
    assert main(["segment", "--model", "psb/Teddy", str(path), "-o", str(tmp_path / "out.ply"), *repair]) == 0, \
        capsys.readouterr().err
    corners = vertices[[p[:3] for p in polygons]]
    expected = direction(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    assert np.loadtxt(tmp_path / "out.txt", dtype=int).tolist() == expected.tolist()


def scene_file(tmp_path, third: str):
    """A GLB scene of a box, a tetrahedron and ``third`` (a bigger box, or the tetrahedron again), node names in reverse
    alphabetical order; and the triangles of each placement, in node order."""
    import trimesh

    box, tetra = trimesh.creation.box(), trimesh.Trimesh(TETRA_V, TETRA_F, process=False)
    placements = [("z_first", box, [5.0, 0, 0]), ("m_second", tetra, [0, 5.0, 0]),
                  ("a_third", tetra if third == "tetra" else trimesh.creation.box(extents=[2, 2, 2]), [0, 0, 5.0])]
    scene = trimesh.Scene()
    for name, mesh, offset in placements:
        scene.add_geometry(mesh, node_name=name, transform=trimesh.transformations.translation_matrix(offset))
    path = tmp_path / "scene.glb"
    scene.export(path)
    return path, np.concatenate([(mesh.vertices + offset)[mesh.faces] for _, mesh, offset in placements])


def test_a_glb_scene_is_read_in_its_node_order(tmp_path):
    path, triangles = scene_file(tmp_path, third="big box")
    mesh = load_mesh(path)
    assert np.allclose(mesh.vertices[mesh.faces], triangles, atol=1e-6)


def test_a_glb_scene_placing_one_mesh_twice_is_segmented_one_placement_at_a_time(tmp_path, monkeypatch, capsys):
    path, triangles = scene_file(tmp_path, third="tetra")
    with pytest.raises(MeshError, match="places one mesh more than once"):
        load_mesh(path)
    from anseg.mesh_files import load_shapes

    shapes = load_shapes(path)
    assert [mesh.n_faces for mesh, _ in shapes] == [12, 4, 4]
    assert np.allclose(np.concatenate([m.vertices[m.faces] for m, _ in shapes]), triangles, atol=1e-6)
    stub_model(monkeypatch)
    import anseg.pipeline

    seen = []
    monkeypatch.setattr(anseg.pipeline, "segment", lambda mesh, *a, **k: seen.append(mesh.n_faces) or SimpleNamespace(
        labels=direction(mesh.face_normals)))
    assert main(["segment", "--model", "psb/Teddy", str(path), "-o", str(tmp_path / "out.ply")]) == 0, capsys.readouterr().err
    assert seen == [12, 4, 4]  # each placement on its own
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    assert np.loadtxt(tmp_path / "out.txt", dtype=int).tolist() == direction(normals).tolist()
    assert main(["segment", "--model", "psb/Teddy", str(path), "--html", str(tmp_path / "view.html")]) == 2
    assert "--html draws one object" in capsys.readouterr().err
    assert main(["features", str(path), "-o", str(tmp_path / "x.npy"), "--groups", "edge"]) == 0, capsys.readouterr().err
    assert np.load(tmp_path / "x.npy").shape[0] == 20


@pytest.mark.parametrize("suffix", [".off", ".obj", ".ply"])
def test_saved_meshes_keep_float64_coordinates(tmp_path, suffix):
    sphere = grid_mesh(4, closed=True)
    for name, vertices in (("far", sphere.vertices + 1e8), ("tiny", sphere.vertices * 1e-9)):
        save_mesh(tmp_path / f"{name}{suffix}", Mesh(vertices, sphere.faces))
        back = load_mesh(tmp_path / f"{name}{suffix}")
        assert np.array_equal(back.vertices, vertices) and np.array_equal(back.faces, sphere.faces), name


def test_the_coloured_ply_of_a_far_scan_keeps_its_shape(tmp_path, monkeypatch, capsys):
    stub_model(monkeypatch)
    sphere = grid_mesh(4, closed=True)
    scan = Mesh(sphere.vertices * 0.01 + [1e8, -2e8, 3e8], sphere.faces)
    save_mesh(tmp_path / "scan.off", scan)
    assert main(["segment", "--model", "psb/Teddy", str(tmp_path / "scan.off")]) == 0, capsys.readouterr().err
    coloured = load_mesh(tmp_path / "scan_labels.ply")
    assert np.array_equal(coloured.vertices, scan.vertices) and np.array_equal(coloured.faces, scan.faces)
