"""Triangle meshes: the `Mesh` container, its checks and repair (files: :mod:`anseg.mesh_files`).

A `Mesh` is two arrays, ``vertices`` (V, 3) float64 and ``faces`` (F, 3)
int64, plus derived quantities computed on first use (areas, normals, the
edge table and the edge-sharing face adjacency). Face order is never changed
by loading (:mod:`anseg.mesh_files` reads and writes the formats; a polygon
becomes adjacent triangles), so per-face label files stay aligned with the file's faces.

Conventions used throughout the package:

* local edge ``k`` of face ``f`` joins ``faces[f, k]`` and ``faces[f, (k+1) % 3]``;
* ``edges`` holds each undirected edge once, as a sorted vertex pair, numbered
  in order of first appearance when walking faces and their local edges (the
  order MeshCNN uses for its per-edge labels);
* ``dihedral_angles`` are signed: positive across a convex edge, negative
  across a concave one, zero when the two faces are coplanar.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np


class MeshError(ValueError):
    """A mesh file or array that the package cannot work with, and why."""


# how the library's messages name the repair; the command line puts its flag, --repair, in its place
REPAIR_HINT = "anseg.repair(mesh)"
# a face is degenerate when its area is at most this times its longest edge squared (see degenerate_faces)
DEGENERATE_EPS = 1e-10
# a face has no area when its area is at most this many units of float64 rounding (see zero_area_faces)
ZERO_AREA_ROUNDING = 4.0
# repair refuses to drop more than this share of the faces (see repair)
REPAIR_MAX_DROP = 0.5
# a piece (faces joined by edges) with less than this share of the faces or the area of the piece with the most
# faces is a stray piece (see Mesh.stray_faces)
STRAY_PIECE_SHARE = 0.01
# the largest coordinate magnitude accepted: float32's largest finite value, so a file in any format can hold the
# mesh; a product of four coordinate differences (an area squared) stays finite in float64 below it
MAX_COORDINATE = float(np.finfo(np.float32).max)


class Mesh:
    """A triangle mesh with derived per-face and per-edge quantities.

    Construction converts and shape-checks the arrays but does not validate
    the geometry; call :meth:`validate` (``load_mesh`` does) for that.
    """

    def __init__(self, vertices, faces):
        vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise MeshError(f"vertices must have shape (V, 3), got {vertices.shape}")
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise MeshError(f"faces must have shape (F, 3) (triangles only), got {faces.shape}")
        self.vertices = vertices
        self.faces = faces

    def __repr__(self) -> str:
        return f"Mesh({self.n_vertices} vertices, {self.n_faces} faces)"

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    # ------------------------------------------------------------------ faces
    @cached_property
    def _face_cross(self) -> np.ndarray:
        v = self.vertices[self.faces]
        return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(F,) triangle areas."""
        return 0.5 * np.linalg.norm(self._face_cross, axis=1)

    @cached_property
    def face_normals(self) -> np.ndarray:
        """(F, 3) unit normals (right-hand rule on the vertex order); zero for degenerate faces."""
        norm = 2.0 * self.face_areas[:, None]
        return np.divide(self._face_cross, norm, out=np.zeros_like(self._face_cross), where=norm > 0)

    @cached_property
    def face_centroids(self) -> np.ndarray:
        """(F, 3) centroids."""
        return self.vertices[self.faces].mean(axis=1)

    # ------------------------------------------------------------------ edges
    @cached_property
    def _edge_table(self) -> tuple[np.ndarray, np.ndarray]:
        half = np.stack([self.faces, np.roll(self.faces, -1, axis=1)], axis=2).reshape(-1, 2)
        key = np.sort(half, axis=1)
        # one int64 per edge sorts as the rows do, several times faster than np.unique(axis=0)
        _, first, inverse = np.unique(key[:, 0] * np.int64(self.n_vertices) + key[:, 1], return_index=True, return_inverse=True)
        # renumber so that edges appear in order of first occurrence (MeshCNN's order)
        order = np.argsort(first, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        edges = key[first[order]]
        return edges, rank[inverse.reshape(-1)].reshape(-1, 3)

    @property
    def edges(self) -> np.ndarray:
        """(E, 2) undirected edges as sorted vertex pairs, in order of first appearance."""
        return self._edge_table[0]

    @property
    def face_edges(self) -> np.ndarray:
        """(F, 3) index into :attr:`edges` of each face's local edges."""
        return self._edge_table[1]

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        """(E,) edge lengths."""
        e = self.edges
        return np.linalg.norm(self.vertices[e[:, 0]] - self.vertices[e[:, 1]], axis=1)

    @cached_property
    def corner_fans(self) -> np.ndarray:
        """(F, 3) the fan of every face corner, numbered 0..n-1.

        The corners of one vertex are joined across the edges that exactly
        two faces share. A manifold vertex has one fan; where sheets of faces
        meet only at a vertex, or only along an edge of more than two faces,
        each sheet has a fan of its own.
        """
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        edge_of_corner = self.face_edges.ravel()  # corner 3f+k starts local edge k of face f
        shared = np.flatnonzero(self.edge_face_counts[edge_of_corner] == 2)
        paired = shared[np.argsort(edge_of_corner[shared], kind="stable")]  # each edge's two half-edges side by side
        a, b = paired[0::2], paired[1::2]
        a_end, b_end = 3 * (a // 3) + (a % 3 + 1) % 3, 3 * (b // 3) + (b % 3 + 1) % 3  # corners at the other end
        vertex = self.faces.ravel()
        agree = vertex[a] != vertex[b]  # consistently oriented faces run the shared edge in opposite directions
        left = np.concatenate([a, a_end])
        right = np.concatenate([np.where(agree, b_end, b), np.where(agree, b, b_end)])
        n = 3 * self.n_faces
        graph = coo_matrix((np.ones(len(left)), (left, right)), shape=(n, n))
        return connected_components(graph, directed=False)[1].reshape(-1, 3)

    @cached_property
    def edge_face_counts(self) -> np.ndarray:
        """(E,) number of faces on each edge: 1 boundary, 2 interior, >2 non-manifold."""
        return np.bincount(self.face_edges.ravel(), minlength=len(self.edges))

    @cached_property
    def edge_faces(self) -> np.ndarray:
        """(E, 2) the faces on each edge, -1 where a boundary edge has only one.

        Raises MeshError on non-manifold edges (more than two faces).
        """
        if (self.edge_face_counts > 2).any():
            raise MeshError(f"{int((self.edge_face_counts > 2).sum())} non-manifold edges (shared by more than two faces)")
        fe = self.face_edges.ravel()
        face_of = np.repeat(np.arange(self.n_faces), 3)
        order = np.argsort(fe, kind="stable")
        fe, face_of = fe[order], face_of[order]
        out = np.full((len(self.edges), 2), -1, dtype=np.int64)
        first = np.ones(len(fe), dtype=bool)
        first[1:] = fe[1:] != fe[:-1]
        out[fe[first], 0] = face_of[first]
        out[fe[~first], 1] = face_of[~first]
        return out

    @cached_property
    def face_neighbors(self) -> np.ndarray:
        """(F, 3) the face across each local edge, -1 on the boundary."""
        ef = self.edge_faces[self.face_edges]  # (F, 3, 2)
        own = np.arange(self.n_faces)[:, None]
        return np.where(ef[..., 0] == own, ef[..., 1], ef[..., 0])

    @cached_property
    def interior_edges(self) -> np.ndarray:
        """(P,) indices of edges shared by exactly two faces."""
        return np.flatnonzero(self.edge_faces[:, 1] >= 0)

    @property
    def face_adjacency(self) -> np.ndarray:
        """(P, 2) pairs of faces sharing an edge; row i shares ``edges[interior_edges[i]]``."""
        return self.edge_faces[self.interior_edges]

    @cached_property
    def dihedral_angles(self) -> np.ndarray:
        """(P,) signed angle between the normals of each adjacent face pair, in [-pi, pi].

        Positive across convex edges, negative across concave ones.
        """
        f0, f1 = self.face_adjacency.T
        n0, n1 = self.face_normals[f0], self.face_normals[f1]
        angle = np.arccos(np.clip((n0 * n1).sum(axis=1), -1.0, 1.0))
        # the vertex of f1 off the shared edge lies above f0's plane on a concave edge
        e = self.edges[self.interior_edges]
        tri = self.faces[f1]
        opposite = tri[np.arange(len(tri)), np.argmax((tri != e[:, :1]) & (tri != e[:, 1:]), axis=1)]
        height = ((self.vertices[opposite] - self.face_centroids[f0]) * n0).sum(axis=1)
        return np.where(height > 0, -angle, angle)

    @cached_property
    def boundary_loop_count(self) -> int:
        """Number of closed boundary loops (connected components of boundary edges)."""
        b = self.edges[self.edge_face_counts == 1]
        if len(b) == 0:
            return 0
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        verts, local = np.unique(b, return_inverse=True)
        local = local.reshape(-1, 2)
        graph = coo_matrix((np.ones(len(local)), (local[:, 0], local[:, 1])), shape=(len(verts),) * 2)
        return int(connected_components(graph, directed=False)[0])

    @property
    def euler_characteristic(self) -> int:
        """V - E + F over the vertices that faces use."""
        used = len(np.unique(self.faces))
        return used - len(self.edges) + self.n_faces

    @cached_property
    def vertex_components(self) -> np.ndarray:
        """(V,) the connected component of each vertex, joined through the faces' edges (0, 1, ...)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        f = self.faces
        graph = coo_matrix((np.ones(f.size), (f.ravel(), np.roll(f, 1, axis=1).ravel())), shape=(self.n_vertices,) * 2)
        return connected_components(graph, directed=False)[1]

    @cached_property
    def face_pieces(self) -> np.ndarray:
        """(F,) the piece of each face: its vertices' connected component (numbers as in :attr:`vertex_components`)."""
        return self.vertex_components[self.faces[:, 0]]

    @cached_property
    def stray_faces(self) -> np.ndarray | None:
        """(F,) True on the faces of stray pieces, or None where the mesh has none (every benchmark mesh).

        A stray piece holds less than :data:`STRAY_PIECE_SHARE` of the faces or
        of the area of the piece with the most faces: a speck, a far facet, a
        scanner's floater, a ground plane of two triangles. Faces decide which
        piece is the shape, as they say where the detail was put; a few large
        triangles can outweigh it in area. Such a
        piece never sets a scale, frame, range or basis of the rest of the
        mesh (:attr:`frame_areas`, and the descriptors' ranges in
        :mod:`anseg.features`), so a file with one more stray facet gets the
        same features on its shape's faces. A mesh without one is computed as
        if the rule did not exist, bit for bit.
        """
        piece = self.face_pieces
        if piece.max() == piece.min():
            return None
        piece_faces = np.bincount(piece)
        piece_area = np.bincount(piece, self.face_areas)
        main = np.argmax(piece_faces)
        stray = (piece_faces < STRAY_PIECE_SHARE * piece_faces[main]) | (piece_area < STRAY_PIECE_SHARE * piece_area[main])
        on_faces = stray[piece]  # (a component of unused vertices has no faces: it is no piece)
        return on_faces if on_faces.any() else None

    @cached_property
    def frame_areas(self) -> np.ndarray:
        """(F,) the face areas that set the mesh's frame (its area, centre and axes): zero on :attr:`stray_faces`."""
        return self.face_areas if self.stray_faces is None else np.where(self.stray_faces, 0.0, self.face_areas)

    # ------------------------------------------------------------- utilities
    def unit_area(self) -> "Mesh":
        """A copy scaled to unit surface area, centred at the area-weighted centroid, and without unreferenced
        vertices (they make Laplacians singular): the frame every descriptor is computed in. Area and centroid are
        those of the mesh without its :attr:`stray_faces`, which keep their place in that frame.

        Made once per mesh (a mesh is immutable), so that the descriptors, the
        eigenbasis and the gradient operator of one level share the copy and
        the tables it caches; with the same faces, it shares this mesh's
        connectivity tables too.
        """
        return self._unit_area_copy

    @cached_property
    def _unit_area_copy(self) -> "Mesh":
        areas = self.frame_areas
        area = areas.sum()
        if not area > 0:
            raise MeshError("mesh has zero total area")
        centre = (self.face_centroids * areas[:, None]).sum(axis=0) / area
        scaled = Mesh((self.vertices - centre) / np.sqrt(area), self.faces).without_unused_vertices()
        if scaled.faces is self.faces:
            scaled.__dict__.update({name: self.__dict__[name] for name in _TOPOLOGY & self.__dict__.keys()})
        scaled.__dict__["stray_faces"] = self.stray_faces  # the same faces, whatever rounding does to the shares
        return scaled

    def submesh(self, faces: np.ndarray) -> tuple["Mesh", np.ndarray]:
        """The mesh of the faces ``faces`` selects (a boolean mask), without the vertices they leave unused, and
        each of its vertices' index here."""
        used, inverse = np.unique(self.faces[faces], return_inverse=True)
        return Mesh(self.vertices[used], inverse.reshape(-1, 3)), used

    def without_unused_vertices(self) -> "Mesh":
        """The mesh without the vertices no face uses, the others in their order (``self`` when it has none)."""
        used, faces = np.unique(self.faces, return_inverse=True)
        return self if len(used) == self.n_vertices else Mesh(self.vertices[used], faces.reshape(-1, 3))

    def validate(self) -> "Mesh":
        """Raise MeshError unless the mesh is usable; return self for chaining.

        Checks, in order: not empty, finite coordinates no larger than
        :data:`MAX_COORDINATE` (beyond it the geometry overflows), face indices in
        range, no faces of zero area (:func:`zero_area_faces`: no normal, no
        angles), no repeated faces, no non-manifold edges, no non-manifold
        vertices. Slivers, faces with an area however thin
        (:func:`degenerate_faces`), pass: CAD exports and scans hold them, and
        the Laplacians turn intrinsic on such a mesh
        (:func:`anseg.geometry.spectral.cotan_laplacian`). A mesh is treated as immutable (its tables
        are cached), so one that passed is not checked again: segmenting a
        mesh asks several stages for a valid mesh, and only the first pays.
        """
        if self.__dict__.get("_valid"):
            return self
        if self.n_faces == 0 or self.n_vertices == 0:
            raise MeshError("mesh is empty (no faces or no vertices)")
        bad = ~np.isfinite(self.vertices).all(axis=1)
        if bad.any():
            raise MeshError(f"{int(bad.sum())} vertices have NaN or infinite coordinates (first: {int(np.flatnonzero(bad)[0])})")
        huge = (np.abs(self.vertices) > MAX_COORDINATE).any(axis=1)
        if huge.any():
            raise MeshError(f"{int(huge.sum())} vertices have coordinates beyond {MAX_COORDINATE:.1e} in magnitude "
                            f"(first: {int(np.flatnonzero(huge)[0])}); the file is damaged or its units are wrong")
        if self.faces.min() < 0 or self.faces.max() >= self.n_vertices:
            raise MeshError(
                f"faces index missing vertices: indices span [{self.faces.min()}, {self.faces.max()}] "
                f"but there are {self.n_vertices} vertices"
            )
        flat = np.flatnonzero(zero_area_faces(self))
        if len(flat):
            raise MeshError(f"{_faces(len(flat))} of zero area (first: {int(flat[0])}); "
                            f"{REPAIR_HINT} drops them and keeps a map to the input faces")
        repeated = self.n_faces - _count_distinct_rows(np.sort(self.faces, axis=1), self.n_vertices)
        if repeated:
            raise MeshError(f"{repeated} faces repeat another face's three vertices; "
                            f"{REPAIR_HINT} drops them and keeps a map to the input faces")
        nonmanifold = int((self.edge_face_counts > 2).sum())
        if nonmanifold:
            raise MeshError(f"{nonmanifold} non-manifold edges (shared by more than two faces); "
                            f"{REPAIR_HINT} cuts the mesh apart there and keeps a map to the input faces")
        pinched = self.corner_fans.max() + 1 - len(np.unique(self.faces))
        if pinched:
            raise MeshError(f"{pinched} non-manifold vertices (where sheets of faces meet at a single vertex); "
                            f"{REPAIR_HINT} cuts the sheets apart")
        self._valid = True
        return self


# the cached tables that depend on the faces alone, which a moved or scaled copy with the same faces shares
_TOPOLOGY = frozenset({"_edge_table", "edge_face_counts", "edge_faces", "face_neighbors", "interior_edges",
                       "corner_fans", "boundary_loop_count", "vertex_components", "face_pieces"})


def _count_distinct_rows(rows: np.ndarray, n_values: int) -> int:
    """Number of distinct rows of a (n, 3) array of integers in [0, n_values)."""
    if n_values < 2**21:  # each row as one int64 (base n_values): a 1-d unique, much faster than axis=0
        n = np.int64(n_values)
        return len(np.unique((rows[:, 0] * n + rows[:, 1]) * n + rows[:, 2]))
    return len(np.unique(rows, axis=0))


def degenerate_faces(mesh: Mesh) -> np.ndarray:
    """(F,) True where a face is degenerate: its area is at most :data:`DEGENERATE_EPS` times its longest edge squared.

    Each face is judged by its own edges, never by the size of the whole
    mesh: one facet far away (or a part in other units) must not turn every
    other face into a "zero-area" one. Area over longest edge squared is
    half the face's height over that edge, a shape measure that does not
    change with scale or position; it is 0 for a face whose corners are
    collinear or repeated and at most about 0.43 (equilateral).

    Why 1e-10: float64 rounding makes the computed area of a face with
    longest edge L and corners at distance R from the origin uncertain by
    about 2.2e-16 * R * L. The threshold lies far above that for any face
    smaller than its distance to the origin by less than about a hundred
    thousand times, so rounding alone does not make a face degenerate or
    keep it from being so; and it only takes faces whose height is below
    2e-10 of their longest edge, needles and caps that no scanner or
    modeller makes on purpose and whose normal and angles mean nothing.
    """
    corners = mesh.vertices[mesh.faces]
    longest_squared = ((np.roll(corners, -1, axis=1) - corners) ** 2).sum(axis=2).max(axis=1, initial=0.0)
    return mesh.face_areas <= DEGENERATE_EPS * longest_squared


def _faces(n: int) -> str:
    return f"{n} face{'s' if n != 1 else ''}"


def zero_area_faces(mesh: Mesh) -> np.ndarray:
    """(F,) True where a face has no area: its computed area lies within float64 rounding of zero.

    Three corners on one line or at one point give an area of exactly 0, or a
    few units of rounding: about ``eps * R * L`` for a face of longest edge L
    whose corners lie within R of the origin. Such a face has no normal and
    no angles. A thin face above that (:func:`degenerate_faces`, a sliver) has
    both, and a refusal names which of the two it found.
    """
    corners = mesh.vertices[mesh.faces]
    longest = np.sqrt(((np.roll(corners, -1, axis=1) - corners) ** 2).sum(axis=2).max(axis=1, initial=0.0))
    reach = np.abs(corners).max(axis=(1, 2), initial=0.0)
    return mesh.face_areas <= ZERO_AREA_ROUNDING * np.finfo(np.float64).eps * reach * longest


def merge_identical_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One vertex per distinct coordinate triple, in order of first appearance; faces re-indexed, their order kept."""
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    rank = np.empty_like(first)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return vertices[np.sort(first)], rank[inverse.reshape(-1)][faces]


def repair(mesh: Mesh, drop_slivers: bool = False) -> tuple[Mesh, np.ndarray]:
    """Merge duplicate vertices, drop faces of zero area and repeated faces, and cut non-manifold edges and vertices apart.

    Returns the repaired mesh and ``face_map``, the input index of every
    repaired face (so that ``labels[face_map]`` carries per-face input labels
    over, and :func:`labels_for_input_faces` carries labels back). Vertices
    that no face uses are dropped first; vertices with identical
    coordinates are merged; faces that then repeat a vertex, have no area
    (:func:`zero_area_faces`) or repeat another face's vertex set are dropped
    (the first copy is kept) and the
    vertices only they used are removed. Repair refuses (MeshError) to drop
    more than :data:`REPAIR_MAX_DROP` (half) of the faces: a mesh that is
    mostly degenerate or doubled is damaged or misread (e.g. coordinates
    rounded to float32 far from the origin), and what would be left is
    another mesh, not this one repaired. Slivers (:func:`degenerate_faces`)
    pass :meth:`Mesh.validate` and are kept, unless ``drop_slivers``: the data
    set readers drop them, as they did when validation refused them, so that
    the benchmark meshes stay those the stored runs read. Then every sheet of faces
    around a non-manifold edge or vertex gets its own copies of the vertices
    there (:attr:`Mesh.corner_fans`), so that the result is manifold and the
    faces keep their order. Non-finite or oversized coordinates of used vertices and bad
    indices are not repaired.
    """
    if mesh.n_faces == 0:
        raise MeshError("mesh is empty (no faces)")
    if mesh.faces.min() < 0 or mesh.faces.max() >= mesh.n_vertices:
        raise MeshError("cannot repair faces that index missing vertices")
    used, faces = np.unique(mesh.faces, return_inverse=True)  # sorted: the vertex order stays
    if not np.isfinite(mesh.vertices[used]).all():
        raise MeshError("cannot repair NaN or infinite coordinates")
    if (np.abs(mesh.vertices[used]) > MAX_COORDINATE).any():
        raise MeshError(f"cannot repair coordinates beyond {MAX_COORDINATE:.1e} in magnitude")
    vertices, faces = merge_identical_vertices(mesh.vertices[used], faces.reshape(-1, 3))
    merged = Mesh(vertices, faces)
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    keep &= ~(zero_area_faces(merged) | (degenerate_faces(merged) if drop_slivers else False))
    _, unique_first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    not_duplicate = np.zeros(len(faces), dtype=bool)
    not_duplicate[unique_first] = True
    face_map = np.flatnonzero(keep & not_duplicate)
    dropped = len(faces) - len(face_map)
    if dropped > REPAIR_MAX_DROP * len(faces):
        n_degenerate = int((~keep).sum())
        raise MeshError(f"{'no faces left after repair' if len(face_map) == 0 else 'repair would drop most faces'}: "
                        f"{n_degenerate} of {len(faces)} are degenerate and {dropped - n_degenerate} repeat another, "
                        f"more than {REPAIR_MAX_DROP:.0%}; so damaged a mesh is not repaired (was it read right?)")
    kept = Mesh(vertices, faces[face_map]).without_unused_vertices()
    # one vertex per fan: a vertex's first fan keeps its index, the others are copies appended at the end
    fans, corner_vertex = kept.corner_fans.ravel(), kept.faces.ravel()
    first_corner = np.full(kept.n_vertices, len(fans))
    np.minimum.at(first_corner, corner_vertex, np.arange(len(fans)))
    index_of_fan = np.full(fans.max() + 1, -1)
    index_of_fan[fans[first_corner]] = np.arange(kept.n_vertices)
    extra = np.flatnonzero(index_of_fan < 0)
    index_of_fan[extra] = kept.n_vertices + np.arange(len(extra))
    vertex_of_fan = np.empty_like(index_of_fan)
    vertex_of_fan[fans] = corner_vertex
    repaired = Mesh(np.vstack([kept.vertices, kept.vertices[vertex_of_fan[extra]]]), index_of_fan[fans].reshape(-1, 3))
    if (repaired.edge_face_counts > 2).any():
        raise MeshError("cutting at non-manifold edges left some edge with more than two faces")
    return repaired, face_map


def labels_for_input_faces(labels, face_map, input_mesh: Mesh, voters: int = 3) -> np.ndarray:
    """Per-face labels of a repaired mesh carried back to the faces of ``input_mesh`` (the one given to :func:`repair`).

    A face that repair dropped takes a label from the kept faces nearest to
    its centroid: a repeated face its twin's (the same centroid), a
    degenerate one the majority of its ``voters`` nearest (ties to the
    nearest). No face is left without a label.
    """
    from scipy.spatial import cKDTree

    labels, face_map = np.asarray(labels), np.asarray(face_map)
    out = np.empty(input_mesh.n_faces, dtype=labels.dtype)
    out[face_map] = labels
    dropped = np.setdiff1d(np.arange(input_mesh.n_faces), face_map)
    if len(dropped):
        centroids = input_mesh.vertices[input_mesh.faces].mean(axis=1)
        k = min(voters, len(face_map))
        distance, nearest = cKDTree(centroids[face_map]).query(centroids[dropped], k=k)
        distance, nearest = distance.reshape(len(dropped), k), nearest.reshape(len(dropped), k)
        for row, (face, near, gap) in enumerate(zip(dropped, nearest, distance)):
            if gap[0] == 0.0:  # a repeated face: its twin
                out[face] = labels[near[0]]
                continue
            values, counts = np.unique(labels[near], return_counts=True)
            best = values[counts == counts.max()]
            out[face] = labels[near[0]] if labels[near[0]] in best else best[0]
    return out
