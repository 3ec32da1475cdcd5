"""A held-out corpus of meshes as users bring them, through the command line ("a user's mesh, the hard way", item 8).

Every mesh is made here, small (a few hundred faces), in every format anseg reads, with what real files carry: quads,
materials, groups and texture indices in OBJ, extra properties in PLY, scenes of several nodes in glTF/GLB; a stray
facet a billion units away and a tiny one nearby; several parts; coordinates near 1e8 and a millionth of a unit;
degenerate, repeated and needle faces; files cut short at half their bytes. Each goes through ``segment``,
``segment --repair``, ``features`` and ``features --repair`` (a few through ``segment --html``) with the shipped
psb/Teddy model, and every run keeps the command's contract:

- exit 0, one label line per face of the file (a polygon is one line), the coloured PLY holding the triangles
  segmented, the feature matrix one row per triangle (per repaired triangle with ``--repair``), every output replaced;
- or exit 2 and one line on stderr that names the file, without a traceback or an exception's name, every output
  that existed before byte for byte as it was and no file added.

Where ``--repair`` should rescue a mesh (a far facet that float32 rounds to a point, degenerate and repeated faces),
it does, and the faces it did not touch get the labels the same mesh gets without them.
A run expected to fail runs in a fresh process, so that its stderr is the user's (it fails before torch is imported,
so this costs little); a run expected to succeed goes through :func:`anseg.cli.main` in this process, as the other
command-line tests do, where an exception out of main() fails the test.
"""

from __future__ import annotations

import struct
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
from conftest import with_caps

from anseg.cli import main
from anseg.mesh import Mesh
from anseg.mesh_files import load_mesh

MODEL = "psb/Teddy"
FAR, HUGE, TINY = 1e9, 1e8, 1e-6
OK, REFUSED = "ok", "refused"
COMMANDS = {"segment": ["segment"], "segment --repair": ["segment", "--repair"], "features": ["features"],
            "features --repair": ["features", "--repair"]}
EARLIER = b"the output of an earlier run\n"


# ---------------------------------------------------------------------------------------------------- shapes


def capsule():
    import trimesh

    return trimesh.creation.capsule(height=1.5, radius=0.5, count=[12, 12])  # 288 faces, closed


def ball(subdivisions: int = 1):
    import trimesh

    return trimesh.creation.icosphere(subdivisions=subdivisions)  # 80 faces at 1, 320 at 2


def quad_ball(n: int = 5) -> tuple[np.ndarray, list[list[int]]]:
    """A closed ball of quads, as modellers make them: each side of a cube cut into n x n squares, pushed onto the
    unit sphere, each quad outward (6 n^2 quads)."""
    index: dict[tuple, int] = {}
    quads = []
    for axis in range(3):
        u, w = [a for a in range(3) if a != axis]
        for sign in (-n, n):
            for i in range(n):
                for j in range(n):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        point = [0, 0, 0]
                        point[axis], point[u], point[w] = sign, 2 * (i + di) - n, 2 * (j + dj) - n
                        quad.append(index.setdefault(tuple(point), len(index)))
                    quads.append(quad)
    vertices = np.array(list(index), dtype=np.float64)
    vertices /= np.linalg.norm(vertices, axis=1, keepdims=True)
    out = []
    for quad in quads:
        a, b, c = vertices[quad[:3]]
        out.append(quad if np.cross(b - a, c - a) @ (a + c) > 0 else quad[::-1])
    return vertices, out


def mixed_polygons(n: int = 5) -> tuple[np.ndarray, list[list[int]]]:
    """:func:`quad_ball` with every third quad given as its two fan triangles: a file of quads and triangles."""
    vertices, quads = quad_ball(n)
    polygons = []
    for k, quad in enumerate(quads):
        polygons += [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] if k % 3 == 0 else [quad]
    return vertices, polygons


def with_parts(vertices, faces, *parts) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's vertices and faces with more (vertices, faces) appended, each part's faces indexing its own vertices."""
    vertices, faces = [np.asarray(vertices, float)], [np.asarray(faces)]
    for part_vertices, part_faces in parts:
        faces.append(np.asarray(part_faces) + sum(len(v) for v in vertices))
        vertices.append(np.asarray(part_vertices, float))
    return np.vstack(vertices), np.vstack(faces)


def triangle(at, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(at, float) + size * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])


# ---------------------------------------------------------------------------------------------------- writers


def write_obj(path: Path, vertices, polygons, newline: str = "\n") -> Path:
    """An OBJ as exporters write it: a material library, an object, groups and smoothing, materials switching back and
    forth, texture coordinates and normals (``v/vt/vn``, ``v//vn``), and some faces with negative (relative) indices;
    ``newline="\\r\\n"`` as Windows tools end lines."""
    n = len(vertices)
    lines = ["# exported by a modeller", "mtllib parts.mtl", "o shape"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices).tolist()]
    lines += ["vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1"]
    normals = np.asarray(vertices) / np.maximum(np.linalg.norm(vertices, axis=1, keepdims=True), 1e-300)
    lines += [f"vn {x:.6f} {y:.6f} {z:.6f}" for x, y, z in normals.tolist()]
    for k, polygon in enumerate(polygons):
        if k % 40 == 0:
            lines += [f"g part{k // 40}", "s 1" if k % 80 else "s off"]
        if k % 7 == 0:
            lines.append(f"usemtl {'skin' if k % 2 else 'cloth'}")
        if k % 5 == 0:
            corners = [f"{i - n}//{i - n}" for i in polygon]  # -1 is the last vertex listed
        else:
            corners = [f"{i + 1}/{c % 4 + 1}/{i + 1}" for c, i in enumerate(polygon)]
        lines.append("f " + " ".join(corners))
    (path.parent / "parts.mtl").write_text("newmtl skin\nKd 0.9 0.7 0.6\nnewmtl cloth\nKd 0.1 0.2 0.8\n")
    path.write_bytes((newline.join(lines) + newline).encode())
    return path


def write_ply(path: Path, vertices, polygons, encoding: str = "ascii") -> Path:
    """A PLY as scanners write it: normals and colours with the coordinates, a comment, a face flag after the indices."""
    vertices = np.asarray(vertices, float)
    normals = vertices / np.maximum(np.linalg.norm(vertices - vertices.mean(axis=0), axis=1, keepdims=True), 1e-300)
    coordinate = "double" if encoding != "binary_big_endian" else "float"
    header = ["ply", f"format {encoding} 1.0", "comment made by a scanner", f"element vertex {len(vertices)}",
              *(f"property {coordinate} {a}" for a in "xyz"), *(f"property float n{a}" for a in "xyz"),
              *(f"property uchar {c}" for c in ("red", "green", "blue", "alpha")), f"element face {len(polygons)}",
              "property list uchar int vertex_indices", "property uchar flags", "end_header"]
    if encoding == "ascii":
        lines = [" ".join([*map(repr, v), *(f"{x:.5f}" for x in nv), "200", "180", "160", "255"])
                 for v, nv in zip(vertices.tolist(), normals.tolist())]
        lines += [" ".join(map(str, [len(p), *p, k % 2])) for k, p in enumerate(polygons)]
        path.write_text("\n".join(header + lines) + "\n")
        return path
    order = "<" if encoding == "binary_little_endian" else ">"
    vertex = f"{order}{'ddd' if coordinate == 'double' else 'fff'}fffBBBB"
    body = b"".join(struct.pack(vertex, *v, *nv, 200, 180, 160, 255) for v, nv in zip(vertices.tolist(), normals.tolist()))
    body += b"".join(struct.pack(f"{order}B{len(p)}iB", len(p), *p, k % 2) for k, p in enumerate(polygons))
    path.write_bytes(("\n".join(header) + "\n").encode("ascii") + body)
    return path


def write_off(path: Path, vertices, polygons) -> Path:
    """An OFF file of polygons, coordinates in full float64 precision."""
    lines = ["OFF", "# a comment", f"{len(vertices)} {len(polygons)} 0"]
    lines += [" ".join(map(repr, v)) for v in np.asarray(vertices, dtype=np.float64).tolist()]
    lines += [" ".join(map(str, [len(p), *map(int, p)])) for p in polygons]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_trimesh(path: Path, vertices, faces, file_type: str) -> Path:
    """STL (binary: ``stl``, text: ``stl_ascii``) or GLB through trimesh's exporters, in float32 as those formats keep."""
    import trimesh

    trimesh.Trimesh(vertices, faces, process=False).export(path, file_type=file_type)
    return path


def write_scene(path: Path, placements) -> Path:
    """A glTF (buffers embedded) or GLB scene: (node name, trimesh, translation, parent node or None), in this order."""
    import trimesh

    scene = trimesh.Scene()
    for name, mesh, offset, parent in placements:
        scene.add_geometry(mesh, node_name=name, geom_name=name, parent_node_name=parent,
                           transform=trimesh.transformations.translation_matrix(offset))
    if path.suffix == ".gltf":
        path.write_bytes(scene.export(file_type="gltf", embed_buffers=True)["model.gltf"])
    else:
        scene.export(path, file_type="glb")
    return path


# ---------------------------------------------------------------------------------------------------- the corpus


@dataclass
class Built:
    """A file of the corpus and what a run on it must give."""

    path: Path
    faces: int  # faces of the file: lines of the label file
    triangles: int  # triangles as read (a polygon of k sides is k - 2)
    sides: np.ndarray | None = None  # triangles of each file face, in order (None: one each)
    kept: int | None = None  # triangles left by --repair (None: all of them)
    clean: Path | None = None  # the same shape without what --repair drops (or without the stray facet), as a file
    untouched: np.ndarray | None = None  # the file faces that are the clean file's faces, in its order


def triangles_of(polygons) -> int:
    return sum(len(p) - 2 for p in polygons)


def polygons_case(writer, n: int = 5, **options):
    def build(folder: Path, name: str) -> Built:
        vertices, polygons = mixed_polygons(n)
        path = writer(folder / name, vertices, polygons, **options)
        return Built(path, len(polygons), triangles_of(polygons), sides=np.array([len(p) - 2 for p in polygons]))

    return build


def trimesh_case(shape, file_type: str, transform=lambda v: v, solid_header: bool = False):
    """An STL or GLB of ``shape()``; ``solid_header``: a binary STL whose 80-byte header starts with "solid", as many
    CAD exporters write it (the text format's first word)."""
    def build(folder: Path, name: str) -> Built:
        mesh = shape()
        path = write_trimesh(folder / name, transform(np.asarray(mesh.vertices)), mesh.faces, file_type)
        if solid_header:
            data = path.read_bytes()
            path.write_bytes(b"solid part exported by a CAD tool".ljust(80, b" ") + data[80:])
        return Built(path, len(mesh.faces), len(mesh.faces))

    return build


def off_case(make, stray: bool = False):
    """An OFF file of the (vertices, faces) that ``make()`` returns; ``stray``: the capsule's faces come first, and the
    capsule alone is the clean file."""
    def build(folder: Path, name: str) -> Built:
        vertices, faces = make()
        built = Built(write_off(folder / name, vertices, faces), len(faces), len(faces))
        if stray:
            c = capsule()
            built.clean, built.untouched = write_off(folder / "clean.off", c.vertices, c.faces), np.arange(len(c.faces))
        return built

    return build


def with_byte_order_mark(build, encoding: str = "utf-8-sig"):
    """The file ``build`` writes, saved again with a byte-order mark as Windows editors save text (``utf-8-sig``;
    ``utf-16`` also writes one)."""
    def mark(folder: Path, name: str) -> Built:
        built = build(folder, name)
        built.path.write_bytes(built.path.read_bytes().decode("utf-8").encode(encoding))
        return built

    return mark


def scene_case(kind: str = "parts"):
    """A body with a head as its child node and a third root beside them: a bigger ball (``parts``), a facet a billion
    units away (``far``), or the head's mesh again (``copies``: one mesh placed twice, each placement one object)."""
    def build(folder: Path, name: str) -> Built:
        import trimesh

        body, head = capsule(), ball(1)
        third = {"parts": ball(2), "far": trimesh.Trimesh(*triangle([0, 0, 0]), process=False), "copies": head}[kind]
        placements = [("body", body, [0, 0, 0], None), ("head", head, [0, 0, 1.6], "body"),
                      ("third", third, [FAR] * 3 if kind == "far" else [2.5, 0, 0], None)]
        path = write_scene(folder / name, placements)
        faces = sum(len(m.faces) for _, m, _, _ in placements)
        return Built(path, faces, faces)

    return build


def capsule_and(*parts):
    c = capsule()
    return with_parts(c.vertices, c.faces, *parts)


def several_parts():
    """Three balls and a capsule apart from each other: one file, four components."""
    parts = [(ball(1).vertices + [3.0 * k, 0, 0], ball(1).faces) for k in (1, 2, 3)]
    return capsule_and(*parts)


def needles():
    """A capsule, a closed sliver (a tetrahedron 1 long and 1e-7 thick: kept, its faces are not degenerate) and a
    thin rod (faces 500 times longer than wide) beside it."""
    import trimesh

    sliver = (np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-7, 0], [0.5, 0, 1e-7]]) + [1.0, 0, 0],
              np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
    rod = trimesh.creation.cylinder(radius=0.002, height=2.0, sections=6)
    return capsule_and(sliver, (rod.vertices + [-1.0, 0, 0], rod.faces))


def capped_capsule():
    """The capsule with 40 caps (conftest.with_caps): slivers, not faces of zero area."""
    c = capsule()
    capped = with_caps(Mesh(c.vertices, c.faces), 40)
    return capped.vertices, capped.faces


def rescued_case(file_type: str):
    """A capsule with a facet a billion units away, in a format of float32 coordinates (STL, a GLB of one mesh): there
    its corners round to one point, a degenerate face that plain runs refuse and --repair drops alone."""
    def build(folder: Path, name: str) -> Built:
        c = capsule()
        vertices, faces = capsule_and(triangle([FAR] * 3))
        path = write_trimesh(folder / name, vertices, faces, file_type)
        clean = write_trimesh(folder / f"clean{path.suffix}", c.vertices, c.faces, file_type)
        return Built(path, len(faces), len(faces), kept=len(c.faces), clean=clean, untouched=np.arange(len(c.faces)))

    return build


def degenerate_off(folder: Path, name: str) -> Built:
    """A capsule with faces a careless export leaves: three collinear corners apart from the mesh, a face naming one
    vertex twice, a face repeating another (reversed), and one over three distinct vertices at one point."""
    c = capsule()
    a, b, d = c.faces[0]
    point = c.vertices[5]
    vertices, faces = capsule_and((np.array([[3.0, 0, 0], [3.5, 0, 0], [4.0, 0, 0]]), [[0, 1, 2]]),
                                  (np.array([point, point, point]), [[0, 1, 2]]))
    faces = np.vstack([faces[:len(c.faces)], [[a, a, b], [d, b, a]], faces[len(c.faces):]])
    path = write_off(folder / name, vertices, faces)
    clean = write_off(folder / "clean.off", c.vertices, c.faces)
    return Built(path, len(faces), len(faces), kept=len(c.faces), clean=clean, untouched=np.arange(len(c.faces)))


def degenerate_obj(folder: Path, name: str) -> Built:
    """:func:`mixed_polygons` as an OBJ with a collapsed quad (a b b a) and a quad of four collinear corners among its
    faces: each a face of the file, so each gets a line, from its neighbours."""
    vertices, polygons = mixed_polygons()
    a, b = polygons[0][:2]
    line = np.array([[2.0, 0, 0], [2.5, 0, 0], [3.0, 0, 0], [3.5, 0, 0]])
    n = len(vertices)
    middle = len(polygons) // 2
    all_polygons = polygons[:middle] + [[a, b, b, a], [n, n + 1, n + 2, n + 3]] + polygons[middle:]
    path = write_obj(folder / name, np.vstack([vertices, line]), all_polygons)
    clean = write_obj(folder / "clean.obj", vertices, polygons)
    return Built(path, len(all_polygons), triangles_of(all_polygons), sides=np.array([len(p) - 2 for p in all_polygons]),
                 kept=triangles_of(polygons), clean=clean, untouched=np.r_[0:middle, middle + 2:len(all_polygons)])


def touching_boxes(folder: Path, name: str) -> Built:
    """Two boxes of a CAD assembly touching along an edge, as one STL: once its corners are merged, the edge is shared by
    four faces (non-manifold); --repair cuts it apart and drops nothing."""
    import trimesh

    box = trimesh.creation.box().subdivide().subdivide()  # 192 faces; every coordinate exact in float32
    vertices, faces = with_parts(box.vertices, box.faces, (box.vertices + [1.0, 1.0, 0], box.faces))
    path = write_trimesh(folder / name, vertices, faces, "stl")
    return Built(path, len(faces), len(faces))


def nan_vertex_obj(folder: Path, name: str) -> Built:
    """:func:`mixed_polygons` as an OBJ in which one vertex an exporter could not place is written ``nan nan nan``."""
    vertices, polygons = mixed_polygons()
    vertices[7] = np.nan
    path = write_obj(folder / name, vertices, polygons)
    return Built(path, len(polygons), triangles_of(polygons))


def bad_index_off(folder: Path, name: str) -> Built:
    """A capsule whose last face names a vertex the file does not hold (an off-by-one of a hand-written exporter)."""
    c = capsule()
    faces = np.array(c.faces)
    faces[-1, 2] = len(c.vertices)
    return Built(write_off(folder / name, c.vertices, faces), len(faces), len(faces))


def truncated(build):
    """A file of the corpus cut at half its bytes, as an interrupted download or copy leaves it."""
    def cut(folder: Path, name: str) -> Built:
        built = build(folder, name)
        data = built.path.read_bytes()
        built.path.write_bytes(data[: len(data) // 2])
        return built

    return cut


@dataclass
class Case:
    build: Callable[[Path, str], Built]
    file: str  # the file's name: its suffix says the format
    plain: str  # what segment and features give without --repair: OK or REFUSED
    repaired: str  # and with --repair


def capsule_off():
    c = capsule()
    return c.vertices, c.faces


CORPUS = {
    # every format we read, clean
    "off": Case(off_case(capsule_off), "capsule.off", OK, OK),
    "off polygons": Case(polygons_case(write_off), "ball.off", OK, OK),
    "obj quads and materials": Case(polygons_case(write_obj), "ball.obj", OK, OK),
    "obj, windows line ends": Case(polygons_case(write_obj, newline="\r\n"), "ball.obj", OK, OK),
    "ply ascii quads": Case(polygons_case(write_ply), "ball.ply", OK, OK),
    "ply binary quads": Case(polygons_case(write_ply, encoding="binary_little_endian"), "ball.ply", OK, OK),
    "ply binary big endian": Case(polygons_case(write_ply, encoding="binary_big_endian"), "ball.ply", OK, OK),
    "stl ascii": Case(trimesh_case(capsule, "stl_ascii"), "capsule.stl", OK, OK),
    "stl binary": Case(trimesh_case(capsule, "stl"), "capsule.stl", OK, OK),
    "stl binary, header saying solid": Case(trimesh_case(capsule, "stl", solid_header=True), "capsule.stl", OK, OK),
    # text saved by an editor with a byte-order mark
    "off, utf-8 byte-order mark": Case(with_byte_order_mark(off_case(capsule_off)), "bom.off", OK, OK),
    "off, utf-16": Case(with_byte_order_mark(off_case(capsule_off), "utf-16"), "utf16.off", OK, OK),
    "obj, utf-8 byte-order mark": Case(with_byte_order_mark(polygons_case(write_obj)), "bom.obj", OK, OK),
    "gltf scene": Case(scene_case(), "scene.gltf", OK, OK),
    "glb scene": Case(scene_case(), "scene.glb", OK, OK),
    "glb scene placing one mesh twice": Case(scene_case("copies"), "copies.glb", OK, OK),
    # stray geometry
    "far facet, off (float64)": Case(off_case(lambda: capsule_and(triangle([FAR] * 3)), stray=True), "far.off", OK, OK),
    "far facet, stl (float32)": Case(rescued_case("stl"), "far.stl", REFUSED, OK),
    "far facet, glb of one mesh": Case(rescued_case("glb"), "far.glb", REFUSED, OK),
    "far node, glb scene": Case(scene_case("far"), "far_node.glb", OK, OK),
    "tiny triangle nearby": Case(off_case(lambda: capsule_and(triangle([0.6, 0, 0], size=1e-3)), stray=True), "speck.off",
                                 OK, OK),
    # several components
    "several parts": Case(off_case(several_parts), "parts.off", OK, OK),
    "boxes touching along an edge, stl": Case(touching_boxes, "assembly.stl", REFUSED, OK),
    # far from the origin, and very small
    "huge offset, off": Case(off_case(lambda: (capsule().vertices + HUGE, capsule().faces), stray=True), "huge.off", OK, OK),
    "huge offset, ply binary": Case(polygons_case(lambda p, v, f: write_ply(p, v + [HUGE, -2 * HUGE, 3 * HUGE], f,
                                                                             "binary_little_endian")), "huge.ply", OK, OK),
    # float32 rounds every corner of a capsule 1e8 away onto a few points: nothing left to segment, said so
    "huge offset, stl (float32)": Case(trimesh_case(capsule, "stl", lambda v: v + HUGE), "huge.stl", REFUSED, REFUSED),
    "tiny scale, off": Case(off_case(lambda: (capsule().vertices * TINY, capsule().faces), stray=True), "tiny.off", OK, OK),
    "tiny scale, stl": Case(trimesh_case(capsule, "stl", lambda v: v * TINY), "tiny.stl", OK, OK),
    # degenerate and needle faces, and what no repair can mend
    "degenerate and repeated faces, off": Case(degenerate_off, "degenerate.off", REFUSED, OK),
    "collapsed quads, obj": Case(degenerate_obj, "collapsed.obj", REFUSED, OK),
    "needles and slivers": Case(off_case(needles), "needles.off", OK, OK),
    # a CAD export's caps: faces 1e-12 as high as long, with an area and a normal (refused before, as "degenerate")
    "40 caps, off": Case(off_case(capped_capsule), "caps.off", OK, OK),
    "a nan vertex, obj": Case(nan_vertex_obj, "nan.obj", REFUSED, REFUSED),
    "a face index past the end, off": Case(bad_index_off, "index.off", REFUSED, REFUSED),
}
TRUNCATED = {  # cut at half: refused, whatever the format
    "off": Case(off_case(capsule_off), "capsule.off", REFUSED, REFUSED),
    "obj": Case(polygons_case(write_obj), "ball.obj", REFUSED, REFUSED),
    "ply ascii": Case(polygons_case(write_ply), "ball.ply", REFUSED, REFUSED),
    "ply binary": Case(polygons_case(write_ply, encoding="binary_little_endian"), "ball.ply", REFUSED, REFUSED),
    "stl ascii": Case(trimesh_case(capsule, "stl_ascii"), "capsule.stl", REFUSED, REFUSED),
    "stl binary": Case(trimesh_case(capsule, "stl"), "capsule.stl", REFUSED, REFUSED),
    "gltf": Case(scene_case(), "scene.gltf", REFUSED, REFUSED),
    "glb": Case(scene_case(), "scene.glb", REFUSED, REFUSED),
}
CORPUS.update({f"truncated {name}": Case(truncated(case.build), case.file, case.plain, case.repaired)
               for name, case in TRUNCATED.items()})


# ---------------------------------------------------------------------------------------------------- running


@dataclass
class Run:
    code: int
    out: str
    err: str


def anseg(args: list, capsys, fresh_process: bool = False) -> Run:
    """``anseg ARGS`` in a fresh process, or through main() here: an exception out of main() is what a user would see as
    a traceback, so it fails the test with its repr."""
    args = [str(a) for a in args]
    if fresh_process:
        result = subprocess.run([sys.executable, "-m", "anseg.cli", *args], capture_output=True, text=True)
        return Run(result.returncode, result.stdout, result.stderr)
    capsys.readouterr()
    try:
        code = main(args)
    except (Exception, SystemExit) as exc:  # SystemExit from argparse included: none is expected here
        pytest.fail(f"anseg {' '.join(args)} raised {exc!r}: a traceback for the user")
    captured = capsys.readouterr()
    return Run(code, captured.out, captured.err)


def outputs_for(command: str, folder: Path, html: bool = False) -> list[Path]:
    if command.startswith("segment"):
        return [folder / "labels.ply", folder / "labels.txt", *([folder / "view.html"] if html else [])]
    return [folder / "features.npy"]


def argv(command: str, mesh: Path, outputs: list[Path]) -> list:
    words = COMMANDS[command]
    if words[0] == "segment":
        html = ["--html", outputs[2]] if len(outputs) > 2 else []
        return [*words, "--model", MODEL, mesh, "-o", outputs[0], "--labels", outputs[1], *html]
    return [*words, mesh, "-o", outputs[0]]


def run_and_check(case: Case, command: str, tmp_path: Path, capsys, html: bool = False,
                  expected: str | None = None) -> tuple[Built, Run, list[Path]]:
    """Build the case, run the command on it with every output already there from an earlier run, and check the
    contract; returns what was built, the run and the outputs. A run expected to fail runs in a fresh process (it
    fails before torch is imported, so at little cost): its stderr is the user's."""
    folder, out_folder = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    out_folder.mkdir()
    built = case.build(folder, case.file)
    outputs = outputs_for(command, out_folder, html)
    for path in outputs:
        path.write_bytes(EARLIER)
    inputs_before = {p: p.read_bytes() for p in folder.iterdir()}
    repair = command.endswith("--repair")
    expected = expected or (case.repaired if repair else case.plain)
    run = anseg(argv(command, built.path, outputs), capsys, fresh_process=expected == REFUSED)
    assert {p: p.read_bytes() for p in folder.iterdir()} == inputs_before, "the input folder changed"
    assert sorted(out_folder.iterdir()) == sorted(outputs), f"files added or removed: {sorted(out_folder.iterdir())}"
    if expected == REFUSED:
        assert run.code == 2, f"expected a refusal, got exit {run.code}: {run.out}{run.err}"
        check_refusal(run, command, built.path, outputs)
        return built, run, outputs
    assert run.code == 0, f"expected success, got exit {run.code}: {run.err}"
    assert "Traceback" not in run.err
    triangles = built.kept if repair and built.kept is not None else built.triangles
    if command.startswith("segment"):
        check_segment_outputs(run, built, triangles, outputs, dropped=repair and built.kept is not None)
    else:
        check_features_output(run, triangles, outputs[0])
    return built, run, outputs


def check_refusal(run: Run, command: str, mesh: Path, outputs: list[Path]) -> None:
    err = run.err
    assert err.count("\n") == 1 and err.endswith("\n"), f"not one line on stderr: {err!r}"
    assert err.startswith(f"anseg {command.split()[0]}: error: "), err
    assert str(mesh) in err, f"the message does not name the file: {err!r}"
    for internal in ("Traceback", "Error", "Exception", "Errno", "<class", "\\x", "object at 0x"):
        assert internal not in err, f"{internal!r} in the message: {err!r}"
    assert all(path.read_bytes() == EARLIER for path in outputs), "an output changed on failure"


def coloured_labels(ply: Path, n_classes: int) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's label, read back from its colour in the PLY segment wrote, and its area."""
    import trimesh

    from anseg.viz import palette

    mesh = trimesh.load(ply, process=False)
    match = (np.asarray(mesh.visual.face_colors)[:, None, :3] == palette(n_classes)[None]).all(axis=2)
    assert (match.sum(axis=1) == 1).all(), "a triangle's colour is no label's"
    return match.argmax(axis=1), np.asarray(mesh.area_faces)


def by_area(labels: np.ndarray, areas: np.ndarray, sides: np.ndarray, n_classes: int) -> np.ndarray:
    """As docs/usage.md says: each file face the label covering most of its triangles' area (ties to the smaller label), by
    count where its triangles have no area."""
    face = np.repeat(np.arange(len(sides)), sides)
    area, count = np.zeros((len(sides), n_classes)), np.zeros((len(sides), n_classes))
    np.add.at(area, (face, labels), areas)
    np.add.at(count, (face, labels), 1)
    return np.where(area.sum(axis=1) > 0, area.argmax(axis=1), count.argmax(axis=1))


def check_segment_outputs(run: Run, built: Built, triangles: int, outputs: list[Path], dropped: bool) -> None:
    ply, txt = outputs[:2]
    assert all(path.read_bytes() != EARLIER for path in outputs), "an output was not written"
    labels = np.loadtxt(txt, dtype=np.int64, ndmin=1)
    assert labels.shape == (built.faces,), f"{len(labels)} label lines for {built.faces} faces of the file"
    assert len(txt.read_text().splitlines()) == built.faces
    # the summary: "N faces [(T triangles)] -> ...", then one line per part with its count of triangles
    first, *parts = run.out.splitlines()
    assert first.startswith(f"{built.faces} faces"), first
    counts = [int(line.rsplit(":", 1)[1].split()[0]) for line in parts if line.startswith("  ")]
    n_classes = len(counts)
    assert sum(counts) == triangles, run.out
    assert labels.min() >= 0 and labels.max() < n_classes
    coloured = load_mesh(ply, validate=False)
    assert coloured.n_faces == triangles and np.isfinite(coloured.vertices).all()
    triangle_labels, areas = coloured_labels(ply, n_classes)
    assert np.array_equal(np.bincount(triangle_labels, minlength=n_classes), counts)
    if not dropped:  # the PLY's triangles are the file's, in its order: line k is file face k's, by area
        sides = built.sides if built.sides is not None else np.ones(built.faces, dtype=np.int64)
        assert np.array_equal(labels, by_area(triangle_labels, areas, sides, n_classes))
    if len(outputs) > 2:
        page = outputs[2].read_text()
        assert "<html" in page[:2000].lower() and "anseg-legend" in page


def check_features_output(run: Run, triangles: int, npy: Path) -> None:
    x = np.load(npy)
    assert x.ndim == 2 and x.shape[0] == triangles, f"{x.shape} for {triangles} triangles"
    assert np.isfinite(x).all(), f"{int((~np.isfinite(x)).any(axis=1).sum())} rows with NaN or infinite features"
    assert run.out.startswith(f"{triangles} faces x {x.shape[1]} features")


# ---------------------------------------------------------------------------------------------------- the tests

def params():
    for name in CORPUS:
        for command in COMMANDS:
            yield pytest.param(name, command, id=f"{name}-{command}")


@pytest.mark.parametrize("name, command", list(params()))
def test_the_corpus_through_the_command_line(tmp_path, capsys, name, command):
    run_and_check(CORPUS[name], command, tmp_path, capsys)


def labels_of_the_clean_mesh(built: Built, tmp_path: Path, capsys) -> np.ndarray:
    clean = [tmp_path / "clean.ply", tmp_path / "clean.txt"]
    run = anseg(argv("segment", built.clean, clean), capsys)
    assert run.code == 0, run.err
    return np.loadtxt(clean[1], dtype=np.int64, ndmin=1)


# refused as they are, segmented with --repair, which drops faces that are not the shape's
RESCUED = ["far facet, stl (float32)", "far facet, glb of one mesh", "degenerate and repeated faces, off", "collapsed quads, obj"]


@pytest.mark.parametrize("name", RESCUED)
def test_repair_rescues_and_the_untouched_faces_keep_their_labels(tmp_path, capsys, name):
    """What --repair drops changes nothing for the rest: the untouched faces get the labels of the mesh without them."""
    built, _, outputs = run_and_check(CORPUS[name], "segment --repair", tmp_path, capsys)
    labels = np.loadtxt(outputs[1], dtype=np.int64, ndmin=1)
    assert np.array_equal(labels[built.untouched], labels_of_the_clean_mesh(built, tmp_path, capsys))


# a far facet, a speck beside the shape, the shape moved far away or shrunk: the stray pieces (Mesh.stray_faces) set
# no scale, frame or range of the shape's features, and a new frame rounds no label away
STRAY = ["far facet, off (float64)", "tiny triangle nearby", "huge offset, off", "tiny scale, off"]


@pytest.mark.parametrize("name", STRAY)
def test_a_stray_facet_or_a_new_frame_leaves_the_labels_of_the_rest(tmp_path, capsys, name):
    """A facet that is not the shape's, or the shape moved 1e8 away or shrunk a million times, changes few labels of the
    shape's own faces (not none: a capsule's many equal faces are ties that rounding breaks one way or the other)."""
    built, _, outputs = run_and_check(CORPUS[name], "segment", tmp_path, capsys)
    labels = np.loadtxt(outputs[1], dtype=np.int64, ndmin=1)[built.untouched]
    same = np.mean(labels == labels_of_the_clean_mesh(built, tmp_path, capsys))
    assert same >= 0.8, f"{same:.0%} of the shape's faces keep their label"


HTML = {"obj quads and materials": ("segment", OK), "glb scene": ("segment", OK),
        "degenerate and repeated faces, off": ("segment --repair", OK), "far facet, stl (float32)": ("segment --repair", OK),
        # --html draws one object: a scene of copies is refused, at once
        "glb scene placing one mesh twice": ("segment", REFUSED), "truncated glb": ("segment", REFUSED)}


@pytest.mark.parametrize("name", list(HTML))
def test_segment_with_a_view(tmp_path, capsys, name):
    command, expected = HTML[name]
    run_and_check(CORPUS[name], command, tmp_path, capsys, html=True, expected=expected)
