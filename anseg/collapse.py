"""Edge-collapse downsampling and its exact record (chains of records, pooling and upsampling: :mod:`anseg.hierarchy`).

The paper's attentive edge collapse (section III-B, Fig. 3): take the alive face with the least
score, collapse the edge it shares with its least-score neighbour to the midpoint (both faces
vanish) and repeat until ``round(ratio * faces in)`` faces are left (or one more). Where the paper is silent:

* **Valid collapses only**, so the coarse mesh stays a sound surface: the link condition (no closed
  component below four faces), no normal turning past ``max_normal_flip_deg``, no face pushed below
  ``MIN_FACE_QUALITY``. Only edges shared by two faces collapse (the paper's rule): boundaries stay.
* **Selection** (``nonuniform``): one walk over the faces by rising score (ties by face index),
  each trying its neighbours by rising score; faces keep their score. Passes repeat while they
  make progress; one without progress stops with a ``CollapseWarning`` and ``reached_target = False``.
* ``uniform``: shortest edge first (a lazily updated heap), which evens out edge lengths: the
  attention-free baseline. ``priority="weighted"``: the same heap keyed by squared length times the
  face's score, so a low-score region thins out to edge lengths of about 1/sqrt(score) instead of
  merging into a few giant faces; the paper's ``"score"`` walk is the default. ``random``: a control.

The :class:`CollapseRecord` stores every collapse, so undoing them in reverse gives back the input
mesh exactly (:meth:`CollapseRecord.replay`), maps every input face to its coarse face
(:attr:`CollapseRecord.fine_to_coarse`) and carries probabilities back (:func:`upsample`: a face
that reappears takes the normalised sum of the faces across its two outer edges, the paper's vote).
The loops run in numba over flat arrays (:mod:`anseg.collapse_engine`).
Why the flip limit defaults to 60 degrees: ``docs/decisions.md``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from anseg.collapse_engine import (
    build_incidence,
    downsample_core,
    first_overshared_edge_face,
    resolve_fine_to_coarse,
    undo_connectivity,
    vote_reappearing,
)
from anseg.mesh import Mesh, MeshError

# how a collapse picks its edges (the engine's modes; "random" is a control), and the nonuniform mode's orders
COLLAPSE_MODES = ("nonuniform", "uniform", "random")
PRIORITIES = ("score", "weighted")
MIN_FACE_QUALITY = 1e-3
"""A collapse may not push a face's ``2 * area / longest_edge**2`` below this
(equilateral: 0.87), unless the face was already worse before the collapse."""
_NO_BOUNDARY_RINGS = 1e6  # rings assigned when a mesh has a single label


class CollapseWarning(UserWarning):
    """Downsampling stopped above its target because no valid collapse was left."""


# --------------------------------------------------------------------------- the record
@dataclass(eq=False, repr=False)
class CollapseRecord:
    """Every collapse of one :func:`downsample` call, enough to undo them exactly.

    Collapse ``t`` merged ``removed_vertex[t]`` into ``kept_vertex[t]`` (which
    moved to the midpoint), removed the faces ``removed_faces[t]`` whose
    vertices were ``removed_face_vertices[t]``, and re-pointed the corners
    ``repointed_corners[repointed_ptr[t]:repointed_ptr[t+1]]`` (corner
    ``3 * f + k`` is fine face f's k-th vertex). ``outer_neighbors[t, j]`` are
    the faces across the two other edges of ``removed_faces[t, j]`` (-1 on
    the boundary). All indices are fine (input) face and vertex indices:
    faces keep their identity, and coarse face i *is* fine face
    ``coarse_face_ids[i]`` (coarse vertex i likewise ``coarse_vertex_ids[i]``).
    """

    coarse: Mesh
    n_fine_faces: int
    n_fine_vertices: int
    target_faces: int
    reached_target: bool
    coarse_face_ids: np.ndarray
    coarse_vertex_ids: np.ndarray
    kept_vertex: np.ndarray
    removed_vertex: np.ndarray
    removed_faces: np.ndarray
    removed_face_vertices: np.ndarray
    old_positions: np.ndarray
    outer_neighbors: np.ndarray
    repointed_ptr: np.ndarray
    repointed_corners: np.ndarray
    unused_vertex_ids: np.ndarray
    unused_vertex_positions: np.ndarray

    def __repr__(self) -> str:
        return (f"CollapseRecord({self.n_fine_faces} -> {self.n_coarse_faces} faces, {self.n_collapses} collapses, "
                f"target {self.target_faces}{'' if self.reached_target else ' not reached'})")

    @property
    def n_collapses(self) -> int:
        return len(self.kept_vertex)

    @property
    def n_coarse_faces(self) -> int:
        return self.coarse.n_faces

    @cached_property
    def fine_to_coarse(self) -> np.ndarray:
        """(F_fine,) the coarse face that stands for each fine face.

        A surviving face maps to itself; a face removed by collapse t maps to
        where a face across one of its outer edges maps (that face is alive
        after step t), resolved from the last collapse back to the first.
        """
        face_map = np.full(self.n_fine_faces, -1, np.int64)
        face_map[self.coarse_face_ids] = np.arange(self.n_coarse_faces)
        resolve_fine_to_coarse(face_map, self.removed_faces, self.outer_neighbors)
        return face_map

    def replay(self, coarse: Mesh | None = None) -> Mesh:
        """Undo the collapses in reverse, from ``coarse`` (default: the record's own coarse mesh).

        Returns the fine mesh: faces exactly as the input, vertices at their
        input positions. Raises ValueError when ``coarse`` does not match the record.
        """
        coarse = self.coarse if coarse is None else coarse
        if coarse.n_faces != len(self.coarse_face_ids) or coarse.n_vertices != len(self.coarse_vertex_ids):
            raise ValueError(
                f"coarse mesh has {coarse.n_faces} faces and {coarse.n_vertices} vertices; this record ends at "
                f"{len(self.coarse_face_ids)} faces and {len(self.coarse_vertex_ids)} vertices"
            )
        faces = np.full((self.n_fine_faces, 3), -1, np.int64)
        faces[self.coarse_face_ids] = self.coarse_vertex_ids[coarse.faces]
        vertices = np.zeros((self.n_fine_vertices, 3))
        vertices[self.coarse_vertex_ids] = coarse.vertices
        vertices[self.unused_vertex_ids] = self.unused_vertex_positions
        bad_step = undo_connectivity(faces, vertices, self.kept_vertex, self.removed_vertex, self.removed_faces,
                                      self.removed_face_vertices, self.old_positions, self.repointed_ptr,
                                      self.repointed_corners)
        if bad_step >= 0:
            raise ValueError(f"coarse mesh does not match this record (undoing collapse {bad_step} found other faces)")
        return Mesh(vertices, faces)


# --------------------------------------------------------------------------- downsampling
def downsample(mesh: Mesh, scores=None, ratio: float = 0.5, mode: str = "nonuniform", seed: int = 0,
               max_normal_flip_deg: float = 60.0, once_per_pass: bool = False,
               priority: str = "score") -> tuple[Mesh, CollapseRecord]:
    """Collapse edges until ``round(ratio * mesh.n_faces)`` faces are left (or one more).

    ``mode``: ``"nonuniform"`` (least ``scores`` first, the paper's attentive
    rule; ``scores`` (F,) finite, required), ``"uniform"`` (shortest edge
    first) or ``"random"`` (static random scores from ``seed``). See the
    module docstring (in full: ``_collapse_allowed``) for the validity rules. When no valid collapse is left
    before the target, a :class:`CollapseWarning` is issued and
    ``record.reached_target`` is False. ``once_per_pass`` (score-ordered
    modes): a face that a collapse changed (one around the kept vertex) takes
    part in no further collapse of the same pass, so a region of low scores
    thins out over several passes instead of being merged into a few large
    faces in one. ``priority`` (nonuniform): ``"score"``, faces in order of
    rising score (the paper), or ``"weighted"``, edges by squared length
    times score (scores must then be positive; module docstring). The input mesh must be edge-manifold
    (boundaries and several components are fine); it is not modified.
    Returns the coarse mesh (alive faces in fine-index order, used vertices
    compacted) and the :class:`CollapseRecord`.
    """
    if mode not in COLLAPSE_MODES:
        raise ValueError(f"mode must be one of {COLLAPSE_MODES}, got {mode!r}")
    if priority not in PRIORITIES:
        raise ValueError(f"priority must be one of {PRIORITIES}, got {priority!r}")
    if not 0.0 < ratio <= 1.0:
        raise ValueError(f"ratio must lie in (0, 1], got {ratio}")
    if not 0.0 < max_normal_flip_deg <= 180.0:
        raise ValueError(f"max_normal_flip_deg must lie in (0, 180], got {max_normal_flip_deg}")
    n_faces = mesh.n_faces
    if mode == "nonuniform":
        if scores is None:
            raise ValueError("nonuniform mode needs per-face scores")
        scores = np.asarray(scores, dtype=np.float64)
        if scores.shape != (n_faces,):
            raise ValueError(f"scores must have shape ({n_faces},), one per face, got {scores.shape}")
        if not np.isfinite(scores).all():
            raise ValueError(f"scores must be finite; {int((~np.isfinite(scores)).sum())} are NaN or infinite")
        if priority == "weighted" and (scores <= 0).any():
            raise ValueError(f"weighted priority needs positive scores; {int((scores <= 0).sum())} are not")
    elif scores is not None:
        raise ValueError(f"scores are only used in nonuniform mode, not {mode!r}")
    elif mode == "random":
        scores = np.random.default_rng(seed).random(n_faces)
    else:
        scores = np.ones(n_faces)  # every edge weighs its plain length
    _check_input(mesh)

    vertices = mesh.vertices.copy()
    faces = mesh.faces.copy()
    target = int(round(ratio * n_faces))
    (alive, kept, removed, removed_faces, removed_face_vertices, old_positions, neighbors, ptr, corners,
     refused) = downsample_core(vertices, faces, scores, mode == "uniform" or priority == "weighted", target,
                                 float(np.cos(np.radians(max_normal_flip_deg))), MIN_FACE_QUALITY, once_per_pass)

    coarse_face_ids = np.flatnonzero(alive)
    used = np.zeros(mesh.n_vertices, dtype=bool)
    used[faces[coarse_face_ids]] = True
    coarse_vertex_ids = np.flatnonzero(used)
    new_index = np.cumsum(used) - 1
    coarse = Mesh(vertices[coarse_vertex_ids], new_index[faces[coarse_face_ids]])
    used_in_input = np.zeros(mesh.n_vertices, dtype=bool)
    used_in_input[mesh.faces] = True
    unused_vertex_ids = np.flatnonzero(~used_in_input)

    reached = coarse.n_faces - target < 2
    if not reached:
        warnings.warn(
            f"downsample ({mode}) stopped at {coarse.n_faces} faces, target {target} (from {n_faces}): "
            f"no valid collapse left after {len(kept)} collapses and {refused} refused attempts",
            CollapseWarning, stacklevel=2,
        )
    record = CollapseRecord(
        coarse=coarse, n_fine_faces=n_faces, n_fine_vertices=mesh.n_vertices, target_faces=target,
        reached_target=reached, coarse_face_ids=coarse_face_ids, coarse_vertex_ids=coarse_vertex_ids,
        kept_vertex=kept, removed_vertex=removed, removed_faces=removed_faces,
        removed_face_vertices=removed_face_vertices, old_positions=old_positions, outer_neighbors=neighbors,
        repointed_ptr=ptr, repointed_corners=corners, unused_vertex_ids=unused_vertex_ids,
        unused_vertex_positions=mesh.vertices[unused_vertex_ids].copy(),
    )
    return coarse, record


def _check_input(mesh: Mesh) -> None:
    if mesh.n_faces == 0:
        raise MeshError("mesh has no faces")
    faces = mesh.faces
    if faces.min() < 0 or faces.max() >= mesh.n_vertices:
        raise MeshError(f"faces index vertices outside [0, {mesh.n_vertices})")
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    if repeated.any():
        raise MeshError(f"{int(repeated.sum())} faces repeat a vertex (first: {int(np.flatnonzero(repeated)[0])})")
    if not np.isfinite(mesh.vertices).all():
        raise MeshError("vertices have NaN or infinite coordinates")
    head, nxt = build_incidence(faces, mesh.n_vertices)
    bad = first_overshared_edge_face(faces, head, nxt)
    if bad >= 0:
        raise MeshError(f"face {bad} has an edge shared by more than two faces; downsample needs an edge-manifold mesh")


# --------------------------------------------------------------------------- carrying values back
def upsample(record: CollapseRecord, coarse_probs) -> np.ndarray:
    """Carry per-face class probabilities (F_coarse, C) back to the fine faces by replaying the record.

    A surviving face keeps its coarse face's row; a face that reappears in a
    vertex split takes the normalised sum of the rows of the faces across its
    two outer edges at that moment (ties are left as ties: argmax then
    picks the lowest class). Returns (F_fine, C).
    """
    coarse_probs = np.asarray(coarse_probs, dtype=np.float64)
    if coarse_probs.ndim != 2 or len(coarse_probs) != record.n_coarse_faces:
        raise ValueError(f"coarse_probs must have shape ({record.n_coarse_faces}, C), got {coarse_probs.shape}")
    if not np.isfinite(coarse_probs).all() or (coarse_probs < 0).any():
        raise ValueError("coarse_probs must be finite and non-negative")
    probs = np.zeros((record.n_fine_faces, coarse_probs.shape[1]))
    probs[record.coarse_face_ids] = coarse_probs
    vote_reappearing(probs, record.removed_faces, record.outer_neighbors)
    return probs


def rings_to_other_label(mesh, labels) -> np.ndarray:
    """(F,) face-graph distance, in rings, from each face to the nearest face with another label (1 = adjacent).

    Faces near label boundaries are where a collapse loses labels: the oracle score
    of the round-trip study and the attention target of training both derive from this.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    pairs = mesh.face_adjacency
    differ = labels[pairs[:, 0]] != labels[pairs[:, 1]]
    sources = np.unique(pairs[differ])
    if len(sources) == 0:
        return np.full(mesh.n_faces, _NO_BOUNDARY_RINGS)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(mesh.n_faces,) * 2)
    # faces touching another label are 1 ring away from it; each further ring adds one
    return 1.0 + dijkstra(graph, directed=False, indices=sources, unweighted=True, min_only=True)
