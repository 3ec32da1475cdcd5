"""Mesh files: reading every format we take, in the file's face order, and writing meshes with their colours.

A label file promises one line per face of the file the user gave, so the
readers keep the file's face order whatever a format groups by (materials,
objects, scene nodes). A polygon with k sides becomes k - 2 adjacent
triangles, a fan from its first corner, and takes back the label covering
most of its area (:func:`labels_for_file_faces`). OBJ, OFF and PLY are read
here (trimesh regroups OBJ faces by material and refuses mixed polygons in
binary PLY); STL and glTF through trimesh, in the order the file lists them.
Meshes are written in float64, so far-off scans keep their shape.
"""

from __future__ import annotations

import codecs
import json
import os
import re
from functools import partial
from pathlib import Path

import numpy as np

from anseg.mesh import Mesh, MeshError, merge_identical_vertices

SUPPORTED_SUFFIXES = (".off", ".obj", ".ply", ".stl", ".glb", ".gltf")
WRITABLE_SUFFIXES = (".off", ".obj", ".ply")
# STL stores three vertices per triangle and glTF splits vertices at normal and UV seams:
# only merged do the triangles of these formats share edges
_PER_CORNER_SUFFIXES = (".stl", ".glb", ".gltf")
_SCENE_SUFFIXES = (".glb", ".gltf")


def load_mesh(path: str | os.PathLike, validate: bool = True) -> Mesh:
    """Read a triangle mesh in any of :data:`SUPPORTED_SUFFIXES`, keeping the file's face order.

    The triangles come in the order of the file's faces, whatever the file
    groups them by (an OBJ's materials, objects or groups, a glTF scene's
    nodes); a polygon of k sides becomes k - 2 adjacent triangles, a fan
    from its first corner (:func:`load_mesh_with_faces` says which file face
    each triangle comes from). OFF, OBJ and PLY keep their vertex order too.
    STL stores three vertices per triangle and glTF/GLB repeats a vertex at
    every normal or UV seam, so there vertices with identical coordinates
    are merged (in order of first appearance; the face order stays):
    otherwise no two triangles would share an edge. Extra PLY elements
    (edges, materials) and OBJ points and lines are left out.

    A glTF/GLB scene is read as one shape: every mesh placed by its node's
    transform, in the scene's node order (depth first, as the file lists
    them), each mesh's primitives in order; points and lines are left out,
    and a scene without triangles is a MeshError. A scene that places one
    mesh more than once (instances, or copies of one mesh) holds several
    objects, and is a MeshError here: :func:`load_shapes` reads it.

    With ``validate`` (the default) the mesh is checked and a MeshError says
    what is wrong; pass ``validate=False`` and call :func:`repair` to fix
    duplicate vertices and degenerate or duplicate faces.

    A file that cannot be read (a folder, empty, truncated, damaged, or in
    another format than its suffix says) is a one-line MeshError about the
    file, in our words: the reader's own exception (chained as the cause)
    speaks of its internals, not of the file. An OFF or PLY file holding
    fewer vertices or faces than its header declares is truncated, even
    where the reader stops quietly at the end.
    """
    return load_mesh_with_faces(path, validate)[0]


def load_mesh_with_faces(path: str | os.PathLike, validate: bool = True) -> tuple[Mesh, np.ndarray]:
    """:func:`load_mesh`, and ``file_face`` (F,): the index of the file's face each triangle comes from.

    A file of triangles gives ``file_face = arange(F)``; a polygon of k
    sides, read as k - 2 adjacent triangles, gives its index k - 2 times.
    :func:`labels_for_file_faces` turns per-triangle labels into one label
    per file face with it. In a glTF/GLB scene a file face is a triangle
    of the scene, in node order.
    """
    shapes = load_shapes(path, validate)
    if len(shapes) > 1:
        raise MeshError(f"{path}: the scene places one mesh more than once, so it holds {len(shapes)} objects; "
                        "`anseg segment` and `anseg features` take each on its own (anseg.mesh_files.load_shapes)")
    return shapes[0]


def load_shapes(path: str | os.PathLike, validate: bool = True) -> list[tuple[Mesh, np.ndarray]]:
    """The objects a file holds, each as :func:`load_mesh_with_faces` gives a mesh: (mesh, file_face).

    Every file is one object, except a glTF/GLB scene that places one mesh
    more than once (instances, or copies of one mesh): each placement (a
    node, with every primitive of its mesh) is then an object of its own,
    in node order, to be segmented on its own, since copies segmented as
    one shape would lose which copy a label belongs to. An object's
    ``file_face`` counts from its own first face; the objects' faces
    follow one another in the file. Checks and errors as :func:`load_mesh`.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        raise MeshError(f"{path}: is a directory, not a mesh file")
    if not path.is_file():
        raise MeshError(f"{path}: no such file")
    if suffix not in SUPPORTED_SUFFIXES:
        raise MeshError(f"{path}: unsupported format {path.suffix!r} (expected one of {', '.join(SUPPORTED_SUFFIXES)})")
    if path.stat().st_size == 0:
        raise MeshError(f"{path}: the file is empty")
    unreadable = f"{path}: cannot read mesh: not a complete {suffix[1:].upper()} file (truncated or damaged?)"
    try:
        vertices, corners, sides, placement = (*_READERS[suffix](path), None)[:4]  # a scene's reader adds its objects
    except MeshError as exc:  # ours: already about the file
        raise MeshError(f"{path}: {exc}") from None
    except Exception as exc:  # the readers raise many types on bad files
        raise MeshError(unreadable) from exc
    if suffix in _SCENE_SUFFIXES and len(sides) == 0:
        raise MeshError(f"{path}: the scene holds no triangle mesh")
    if len(sides) == 0:
        raise MeshError(f"{path}: cannot read mesh: no triangles in it (truncated, damaged, or not in "
                        f"{suffix[1:].upper()} format?)")
    if sides.min() < 3:
        raise MeshError(f"{path}: face {int(np.argmax(sides < 3))} has fewer than 3 corners")
    all_faces, all_file_faces = _fans(corners, sides)
    objects = [slice(None)] if placement is None else [placement == k for k in range(placement.max() + 1)]
    shapes = []
    for k, chosen in enumerate(objects):
        faces, file_face, own_vertices = all_faces[chosen], all_file_faces[chosen], vertices
        if placement is not None:  # the placement's own vertices, its faces counted from its first
            own = Mesh(vertices, faces).without_unused_vertices()
            own_vertices, faces, file_face = own.vertices, own.faces, file_face - file_face[0]
        in_range = faces.min() >= 0 and faces.max() < len(own_vertices)
        if suffix in _PER_CORNER_SUFFIXES and in_range:  # bad indices are left for validate to report
            own_vertices, faces = merge_identical_vertices(own_vertices, faces)
        mesh = Mesh(own_vertices, faces)
        if validate:
            try:
                mesh.validate()
            except MeshError as exc:
                where = f"placement {k + 1} of {len(objects)}: " if len(objects) > 1 else ""
                raise MeshError(f"{path}: {where}{exc}") from None
        shapes.append((mesh, file_face))
    return shapes


def _fans(corners: np.ndarray, sides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Polygons (their corners one after another, ``sides`` each) as triangle fans: (F, 3) faces and each one's polygon.

    Polygon p with corners c0 .. c(k-1) gives (c0, c1, c2), (c0, c2, c3), ...
    (c0, c(k-2), c(k-1)), in this order, right after polygon p - 1's.
    """
    if (sides == 3).all():
        return corners.reshape(-1, 3), np.arange(len(sides))
    polygon = np.repeat(np.arange(len(sides)), sides - 2)
    start = np.concatenate([[0], np.cumsum(sides)[:-1]])[polygon]
    step = np.arange(len(polygon)) - np.concatenate([[0], np.cumsum(sides - 2)[:-1]])[polygon]  # 0 .. k-3
    return np.stack([corners[start], corners[start + step + 1], corners[start + step + 2]], axis=1), polygon


def labels_for_file_faces(labels, file_face, mesh: Mesh) -> np.ndarray:
    """Per-triangle labels of ``mesh`` as one label per file face (``file_face`` from :func:`load_mesh_with_faces`).

    A polygon read as several triangles takes the label that covers most
    of its area (ties to the smaller label; by count where all its
    triangles have zero area), so that line k of a label file describes
    the file's face k, whatever its number of sides.
    """
    labels, file_face = np.asarray(labels), np.asarray(file_face)
    if len(file_face) == len(np.unique(file_face)):  # one triangle per file face
        out = np.empty_like(labels)
        out[file_face] = labels
        return out
    shape = (file_face.max() + 1, labels.max() + 1)
    area, count = np.zeros(shape), np.zeros(shape)
    np.add.at(area, (file_face, labels), mesh.face_areas)
    np.add.at(count, (file_face, labels), 1)
    return np.where(area.sum(axis=1) > 0, area.argmax(axis=1), count.argmax(axis=1)).astype(labels.dtype)


def _text(data: bytes) -> str:
    """A text mesh file's bytes as text: UTF-8, or UTF-16 where a byte-order mark says so; a UTF-8 mark (Windows
    editors save one) is skipped. Bytes that are not text become U+FFFD, which no number parses as."""
    if data.startswith(codecs.BOM_UTF8):
        return data[len(codecs.BOM_UTF8):].decode("utf-8", errors="replace")
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return data.decode("utf-16", errors="replace")
    return data.decode("utf-8", errors="replace")


def _read_obj(path: Path):
    """Vertices and faces of an OBJ in file order, whatever its ``usemtl``, ``o``, ``g`` and ``s`` lines group them by.

    trimesh's reader regroups faces by material (and splits vertices at
    UV seams), which loses the file's face order; OBJ is simple enough to
    read here. Indices count from 1, negative ones back from the last
    vertex so far; ``a/b/c`` keeps ``a``; 0 is left as an index out of
    range for validation to report.
    """
    vertices, corners, sides = [], [], []
    for line in _text(path.read_bytes()).replace("\\\n", " ").splitlines():
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        if words[0] == "v":
            if len(words) < 4:
                raise MeshError("cannot read mesh (a vertex or face without 3 entries)")
            vertices.append([float(w) for w in words[1:4]])
        elif words[0] == "f":
            n = len(vertices)
            index = [int(w.split("/", 1)[0]) for w in words[1:]]
            corners += [i - 1 if i > 0 else n + i if i < 0 else -1 for i in index]
            sides.append(len(index))
    return np.array(vertices, dtype=np.float64).reshape(-1, 3), np.array(corners, dtype=np.int64), np.array(sides, dtype=np.int64)


def _read_off(path: Path):
    """Vertices and polygons of an OFF file as written, polygons of any number of sides (trimesh's reader splits quads
    out of order); colours after the coordinates or the indices are left out."""
    data = path.read_bytes()
    lines = [line.split("#", 1)[0].split() for line in _text(data).splitlines()]
    lines = [words for words in lines if words]
    if not re.fullmatch(r"(ST)?C?N?OFF", lines[0][0]):
        raise ValueError("not an OFF header")
    counts, body = (lines[0][1:], lines[1:]) if len(lines[0]) > 1 else (lines[1], lines[2:])
    n_vertices, n_faces = int(counts[0]), int(counts[1])
    if min(n_vertices, n_faces) < 0:
        raise ValueError("a negative element count")
    declared = {"vertex": n_vertices, "face": n_faces}
    _check_declared_counts(declared, len(data), binary=False)
    if any(len(words) < 3 for words in body[:n_vertices]):
        raise MeshError("cannot read mesh (a vertex or face without 3 entries)")
    vertices = np.array([words[:3] for words in body[:n_vertices]], dtype=np.float64).reshape(-1, 3)
    polygons = [words[1:1 + int(words[0])] for words in body[n_vertices:n_vertices + n_faces]]
    if any(len(p) < int(w[0]) for p, w in zip(polygons, body[n_vertices:])):
        raise ValueError("a face line short of its indices")
    _check_read_counts(declared, {"vertex": len(vertices), "face": len(polygons)})
    corners = np.array([i for p in polygons for i in p], dtype=np.int64)
    return vertices, corners, np.array([len(p) for p in polygons], dtype=np.int64)


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2", "ushort": "u2",
              "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4",
              "double": "f8", "float64": "f8"}


def _read_ply(path: Path):
    """The ``vertex`` and ``face`` elements of a PLY file as stored (ASCII or binary), polygons of any number of sides.

    Read here rather than by trimesh, whose reader splits polygons out of
    order, takes every face of a binary file to have as many sides as the
    first, and refuses some extra elements; other elements (``edge``,
    ``material``...) are read past and left out.
    """
    data = path.read_bytes()
    end = data.index(b"end_header")
    body = data[data.index(b"\n", end) + 1:]
    elements, encoding = [], "ascii"
    for words in (line.split() for line in data[:end].decode("latin-1").splitlines()):
        if words[:1] == ["format"]:
            encoding = words[1]
        elif words[:1] == ["element"]:
            if int(words[2]) < 0:
                raise ValueError("a negative element count")
            elements.append((words[1], int(words[2]), []))
        elif words[:1] == ["property"]:  # (name, [type]) or, for a list, (name, [count type, item type])
            elements[-1][2].append((words[-1], [_PLY_TYPES[w] for w in words[1:-1] if w != "list"]))
    declared = {name: count for name, count, _ in elements if name in _MIN_TEXT_BYTES}
    _check_declared_counts(declared, len(data), binary=encoding != "ascii")
    if encoding == "ascii":
        read, body = _ply_ascii_element, body.split()
    else:
        read = partial(_ply_binary_element, order="<" if encoding == "binary_little_endian" else ">")
    position, found = 0, {}
    for name, count, properties in elements:
        found[name], position = read(body, position, count, properties)
    vertices = np.column_stack([np.asarray(found["vertex"][axis], dtype=np.float64) for axis in "xyz"])
    face = found.get("face", {})
    polygons = next((face[n] for n in ("vertex_indices", "vertex_index") if n in face), [])
    _check_read_counts(declared, {"vertex": len(vertices), "face": len(polygons)})
    sides = np.array([len(p) for p in polygons], dtype=np.int64)
    corners = np.concatenate([np.asarray(p).ravel() for p in polygons]) if len(polygons) else np.empty(0)
    return vertices, corners.astype(np.int64), sides


def _ply_ascii_element(tokens: list, position: int, count: int, properties: list):
    """One element of an ASCII PLY: {property: values}, and where in ``tokens`` the next element starts."""
    if all(len(types) == 1 for _, types in properties):  # no lists: all rows alike
        width = len(properties)
        rows = np.array(tokens[position:position + count * width], dtype=np.float64).reshape(count, width)
        return {name: rows[:, k] for k, (name, _) in enumerate(properties)}, position + count * width
    values = {name: [] for name, _ in properties}
    for _ in range(count):
        for name, types in properties:
            size = int(tokens[position]) if len(types) == 2 else 1
            start = position + len(types) - 1
            if start + size > len(tokens):
                raise ValueError("the file ends inside an element")
            row = [float(t) for t in tokens[start:start + size]]
            values[name].append(row if len(types) == 2 else row[0])
            position = start + size
    return values, position


def _ply_binary_element(data: bytes, position: int, count: int, properties: list, order: str):
    """One element of a binary PLY: {property: values}, and the byte where the next element starts.

    Read at once as if every list had the length of the first row's; row by
    row where they do not (a mesh of triangles and quads)."""
    def take(dtype, n, at):
        return np.frombuffer(data, order + dtype, n, at), at + n * np.dtype(dtype).itemsize

    if count == 0:
        return {name: [] for name, _ in properties}, position
    fields, at = [], position
    for name, types in properties:  # the first row gives every list's length
        if len(types) == 2:
            size, at = take(types[0], 1, at)
            _, at = take(types[1], int(size[0]), at)
            fields += [(name + " size", order + types[0]), (name, order + types[1], (int(size[0]),))]
        else:
            _, at = take(types[0], 1, at)
            fields.append((name, order + types[0]))
    rows = np.dtype(fields)
    if position + count * rows.itemsize <= len(data):
        table = np.frombuffer(data, rows, count, position)
        if all((table[f[0]] == table[f[0]][0]).all() for f in fields if f[0].endswith(" size")):
            return {name: table[name] for name, _ in properties}, position + count * rows.itemsize
    values = {name: [] for name, _ in properties}
    for _ in range(count):
        for name, types in properties:
            if len(types) == 2:
                size, position = take(types[0], 1, position)
                row, position = take(types[1], int(size[0]), position)
            else:
                row, position = take(types[0], 1, position)
                row = row[0]
            values[name].append(row)
    return values, position


def _read_stl(path: Path):
    import trimesh

    loaded = trimesh.load(path, process=False, maintain_order=True, force="mesh")
    faces = np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    return np.asarray(loaded.vertices, dtype=np.float64).reshape(-1, 3), faces.ravel(), np.full(len(faces), 3, dtype=np.int64)


def _gltf_json(path: Path) -> dict:
    """The JSON part of a glTF (the whole file) or GLB (its first chunk) file."""
    data = path.read_bytes()
    if path.suffix.lower() == ".glb":
        length = int.from_bytes(data[12:16], "little")
        data = data[20:20 + length]
    return json.loads(data)


def _read_gltf(path: Path):
    """The triangles of a glTF/GLB scene in its node order, each mesh moved by its node's transform, and the shapes.

    The shapes: None where every mesh is placed once (the scene is one
    shape), else each triangle's placement (0, 1, ... in node order): a
    mesh placed twice is two objects, each segmented on its own.

    trimesh reads the buffers, primitives and transforms; its scene graph
    lists the nodes in another order (the last root first), so the order
    is taken from the file: the scene's root nodes as listed, each followed
    by its children, depth first; a mesh's primitives in the mesh's order.
    trimesh names a node by its ``name`` (or its index), made unique in
    node order; the same names are made here, and a scene whose placed
    meshes they do not all find is refused rather than read out of order.
    """
    import trimesh
    from trimesh.util import unique_name

    header = _gltf_json(path)
    scene = trimesh.load(path, process=False, maintain_order=True, force="scene")
    names, counts = {}, {}
    for i, node in enumerate(header.get("nodes", [])):
        names[unique_name(node.get("name", str(i)), names, counts=counts)] = i
    frame = {i: name for name, i in names.items()}
    nodes = header.get("nodes", [])
    order, visited, stack = [], set(), list(reversed(header.get("scenes", [{}])[header.get("scene", 0)].get("nodes", [])))
    while stack:
        i = stack.pop()
        if i not in visited:
            visited.add(i)
            order.append(i)
            stack += reversed(nodes[i].get("children", []))
    # a node whose mesh has several primitives holds them in child frames, one per primitive, in the order of scene.geometry
    rank = {name: k for k, name in enumerate(scene.geometry)}
    placed = []  # (trimesh's frame, the node's rank in scene order)
    for rank_of_node, i in enumerate(order):
        children = [f for f in scene.graph.transforms.children.get(frame[i], []) if f not in names]
        holders = [frame[i]] if frame[i] in scene.graph.nodes_geometry else children
        held = sorted((f for f in holders if f in scene.graph.nodes_geometry), key=lambda f: rank[scene.graph[f][1]])
        placed += [(f, rank_of_node) for f in held]
    if sorted(f for f, _ in placed) != sorted(scene.graph.nodes_geometry):
        raise MeshError("cannot tell the scene's node order")
    vertices, faces, node_of_face, seen, repeated = [], [], [], set(), False
    for node, rank_of_node in placed:
        transform, name = scene.graph[node]
        geometry = scene.geometry[name]
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue  # points and lines
        key = (geometry.vertices.tobytes(), geometry.faces.tobytes())
        repeated, _ = repeated or key in seen, seen.add(key)
        faces.append(np.asarray(geometry.faces, dtype=np.int64) + sum(len(v) for v in vertices))
        vertices.append(trimesh.transform_points(np.asarray(geometry.vertices, dtype=np.float64), transform))
        node_of_face.append(np.full(len(geometry.faces), rank_of_node))
    if not faces:
        return np.empty((0, 3)), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64), None
    faces = np.concatenate(faces)
    placement = np.unique(np.concatenate(node_of_face), return_inverse=True)[1] if repeated else None
    return np.concatenate(vertices), faces.ravel(), np.full(len(faces), 3, dtype=np.int64), placement


_READERS = {".obj": _read_obj, ".off": _read_off, ".ply": _read_ply, ".stl": _read_stl, ".glb": _read_gltf, ".gltf": _read_gltf}


# the fewest bytes a vertex or face can take in a file: "0 0 0\n" and "3 0 1 2\n" as text, 3 x 4 bytes in binary PLY
_MIN_TEXT_BYTES = {"vertex": 6, "face": 8}
_MIN_BINARY_BYTES = {"vertex": 12, "face": 13}


def _check_declared_counts(declared: dict[str, int], size: int, binary: bool) -> None:
    """Refuse a header that declares more vertices and faces than a file of ``size`` bytes can hold.

    An OFF or PLY reader calls it once it has the header and before it reads
    (and allocates for) the body, so a damaged count costs nothing.
    """
    minimum = _MIN_BINARY_BYTES if binary else _MIN_TEXT_BYTES
    if sum(minimum[kind] * n for kind, n in declared.items()) > size:
        counts = ", ".join(f"{n} {kind} elements" for kind, n in declared.items())
        raise MeshError(f"the header declares {counts}, more than its {size} bytes can hold (truncated or damaged)")


def _check_read_counts(declared: dict[str, int], read: dict[str, int]) -> None:
    """Refuse a file that holds fewer vertices or faces than its header declares: a reader may stop quietly at the end."""
    short = [f"{read[kind]} of the {n} {kind} elements" for kind, n in declared.items() if read[kind] < n]
    if short:
        raise MeshError(f"holds only {' and '.join(short)} its header declares (truncated?)")


def save_mesh(path: str | os.PathLike, mesh: Mesh, face_colors: np.ndarray | None = None) -> None:
    """Write a mesh in any of :data:`WRITABLE_SUFFIXES`; ``face_colors`` (F, 3 or 4) uint8 are kept in PLY.

    Only formats that keep vertex and face order are written, so that a
    per-face label file stays aligned with what was saved. Coordinates are
    written in full float64 precision (17 significant digits in OFF and
    OBJ, doubles in binary PLY): a scan far from the origin, say near 1e8,
    keeps its shape, where float32 would round its points together.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITABLE_SUFFIXES:
        raise MeshError(f"{path}: cannot write {path.suffix!r} (meshes are written as one of {', '.join(WRITABLE_SUFFIXES)})")
    if suffix == ".ply":
        _save_ply(path, mesh, face_colors)
        return
    with open(path, "w") as handle:
        if suffix == ".off":
            handle.write(f"OFF\n{mesh.n_vertices} {mesh.n_faces} 0\n")
            np.savetxt(handle, mesh.vertices, fmt="%.17g")
            np.savetxt(handle, np.column_stack([np.full(mesh.n_faces, 3), mesh.faces]), fmt="%d")
        else:
            np.savetxt(handle, mesh.vertices, fmt="v %.17g %.17g %.17g")
            np.savetxt(handle, mesh.faces + 1, fmt="f %d %d %d")


def _save_ply(path: Path, mesh: Mesh, face_colors: np.ndarray | None) -> None:
    """Binary little-endian PLY: vertices as doubles, faces as a list of 3 int32, then red, green, blue, alpha."""
    face = [("n", "u1"), ("index", "<i4", (3,))]
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {mesh.n_vertices}",
              "property double x", "property double y", "property double z",
              f"element face {mesh.n_faces}", "property list uchar int vertex_indices"]
    if face_colors is not None:
        face.append(("rgba", "u1", (4,)))
        header += [f"property uchar {channel}" for channel in ("red", "green", "blue", "alpha")]
    faces = np.zeros(mesh.n_faces, dtype=face)
    faces["n"], faces["index"] = 3, mesh.faces
    if face_colors is not None:
        colors = np.asarray(face_colors, dtype=np.uint8).reshape(mesh.n_faces, -1)
        faces["rgba"] = np.column_stack([colors[:, :3], colors[:, 3] if colors.shape[1] == 4 else np.full(mesh.n_faces, 255)])
    with open(path, "wb") as handle:
        handle.write(("\n".join(header + ["end_header"]) + "\n").encode("ascii"))
        handle.write(mesh.vertices.astype("<f8").tobytes())
        handle.write(faces.tobytes())
