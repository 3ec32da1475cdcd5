"""K-means face clusters and the cluster-ordered patch sequence (section III-A).

A unit turns a mesh into transformer tokens in three steps:

1. :func:`cluster_faces`: K-means on the standardised per-face features.
2. :func:`sequence`: the faces ordered cluster by cluster; inside a cluster
   along a 3D Hilbert curve through the face centroids, so that consecutive
   faces are close in space. Clusters come in the order of their mean
   position along the same curve (ties by label), so that neighbouring
   clusters tend to sit next to each other in the sequence too.
3. :func:`patches`: consecutive faces of the sequence grouped into patches
   of ``patch_size`` faces, the tokens. A patch never straddles two
   clusters: every token is semantically pure (one cluster), at the price of
   at most ``patch_size - 1`` padding slots per cluster (under 2 % of the
   slots at 25K faces with the defaults).

:class:`PatchLayout` scatters per-face arrays into a padded
``(n_patches, patch_size, ...)`` token tensor and gathers them back, for
numpy arrays and torch tensors alike. :func:`layout` does all three steps.
The frames the curve can run in (:data:`FRAMES`) and the canonical pose
and order a mesh can be segmented in (:func:`canonical_mesh`) live here too.
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass

import numpy as np
from numba import njit

from anseg.mesh import Mesh, degenerate_faces

DEFAULT_K = 16
DEFAULT_PATCH_SIZE = 32
CURVES = ("hilbert", "morton")
# the frame the ordering curve runs in: the coordinates as given, the surface's own principal axes, or the coordinates
# turned by a rotation drawn from the layout's seed
FRAMES = ("xyz", "principal", "random")
# 16 bits per axis: 65536 cells along the longest side, far finer than any mesh we segment
CURVE_BITS = 16


def cluster_faces(
    features, k: int = DEFAULT_K, seed: int = 0, max_iter: int = 50, max_fit_faces: int = 50_000
) -> np.ndarray:
    """K-means cluster label (F,) int64 of every face, from features (F, D).

    Each feature column is standardised (zero mean, unit variance; constant
    columns are left at zero) so that no descriptor dominates by its units.
    Uses scikit-learn's Lloyd K-means with one k-means++ start, deterministic
    for a given ``seed`` and run on one OpenMP thread whatever the
    process allows: scikit-learn's threads sum the Lloyd updates in another
    order, and on one PSB Human test mesh two threads moved 63 faces to
    other clusters, and with them the patches, the attention and the whole
    hierarchy. On more than ``max_fit_faces`` faces the centres are
    fitted on a random subset of that size and every face is then assigned
    to its nearest centre: the centres barely move and the cost stops growing
    with the mesh (MiniBatchKMeans was slower). The clusters only shape the
    token sequence, so ``max_iter`` is modest. With fewer faces (or distinct
    feature rows) than ``k`` there are fewer clusters. Labels are
    0..n_clusters-1 with none empty.
    """
    from sklearn.cluster import KMeans
    from sklearn.exceptions import ConvergenceWarning
    from threadpoolctl import threadpool_limits

    x = np.asarray(features, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] == 0 or x.shape[1] == 0:
        raise ValueError(f"features must have shape (F>=1, D>=1), got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError(f"features have {int((~np.isfinite(x)).sum())} NaN or infinite entries")
    if int(k) != k or k < 1:
        raise ValueError(f"k must be a positive integer, got {k}")
    spread = x.std(axis=0)
    x = ((x - x.mean(axis=0)) / np.where(spread > 0, spread, 1.0)).astype(np.float32)
    fit = x
    if len(x) > max_fit_faces:
        fit = x[np.sort(np.random.default_rng(seed).choice(len(x), max_fit_faces, replace=False))]
    kmeans = KMeans(n_clusters=min(int(k), len(fit)), n_init=1, max_iter=max_iter, random_state=seed)
    with warnings.catch_warnings(), threadpool_limits(limits=1, user_api="openmp"):
        # fewer distinct rows than k: sklearn warns and returns fewer clusters, which is what we want
        warnings.simplefilter("ignore", ConvergenceWarning)
        labels = kmeans.fit(fit).predict(x)
    return np.unique(labels, return_inverse=True)[1].astype(np.int64)


def curve_keys(cells, bits: int = CURVE_BITS, curve: str = "hilbert") -> np.ndarray:
    """Position (N,) uint64 of integer cells (N, 3) in [0, 2**bits) along a space-filling curve.

    ``hilbert``: consecutive keys are face-adjacent cells (Skilling's
    transpose algorithm, vectorised over cells). ``morton``: plain bit
    interleaving (Z-order), cheaper but with long jumps between octants.
    """
    if curve not in CURVES:
        raise ValueError(f"curve must be one of {CURVES}, got {curve!r}")
    if not 1 <= bits <= 21:
        raise ValueError(f"bits must be in [1, 21] so that three axes fit in 64 bits, got {bits}")
    cells = np.asarray(cells)
    if cells.ndim != 2 or cells.shape[1] != 3:
        raise ValueError(f"cells must have shape (N, 3), got {cells.shape}")
    if len(cells) and (cells.min() < 0 or cells.max() >= 1 << bits):
        raise ValueError(f"cells must lie in [0, {1 << bits}), got [{cells.min()}, {cells.max()}]")
    x = [cells[:, axis].astype(np.uint64) for axis in range(3)]
    if curve == "hilbert":
        _hilbert_transpose(*x, bits)
    return (_spread_bits(x[0]) << np.uint64(2)) | (_spread_bits(x[1]) << np.uint64(1)) | _spread_bits(x[2])


@njit(cache=True)
def _hilbert_transpose(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, bits: int) -> None:
    """Skilling (2004) AxesToTranspose, in place: coordinates -> Hilbert index in transposed form.

    A loop over cells in numba: the same bit operations as a vectorised
    version, without its dozens of temporary arrays (4x faster at 25K cells).
    """
    zero, one = np.uint64(0), np.uint64(1)
    top = one << np.uint64(bits - 1)
    x = np.empty(3, dtype=np.uint64)
    for i in range(len(x0)):
        x[0], x[1], x[2] = x0[i], x1[i], x2[i]
        q = top
        while q > one:  # undo the excess work of the per-level rotations
            low = q - one
            for axis in range(3):
                if x[axis] & q:
                    x[0] ^= low
                else:
                    swap = (x[0] ^ x[axis]) & low
                    x[0] ^= swap
                    x[axis] ^= swap
            q >>= one
        x[1] ^= x[0]  # Gray encode
        x[2] ^= x[1]
        flip = zero
        q = top
        while q > one:
            if x[2] & q:
                flip ^= q - one
            q >>= one
        x0[i], x1[i], x2[i] = x[0] ^ flip, x[1] ^ flip, x[2] ^ flip


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """Move bit b of each (<= 21-bit) value to bit 3b."""
    v = v & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                        (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def sequence(mesh_or_centroids, cluster_labels, curve: str = "hilbert") -> np.ndarray:
    """Face order (F,) int64: cluster by cluster, each cluster along a space-filling curve.

    Centroids are quantised on the cube around the bounding box (the same
    step on every axis, so that curve distance follows true distance).
    Clusters are placed by the mean rank of their faces along the curve,
    ties by label; faces in the same curve cell keep their index order.
    """
    centroids = (mesh_or_centroids.face_centroids if isinstance(mesh_or_centroids, Mesh)
                 else np.asarray(mesh_or_centroids, dtype=np.float64))
    if centroids.ndim != 2 or centroids.shape[1] != 3:
        raise ValueError(f"centroids must have shape (F, 3), got {centroids.shape}")
    if not np.isfinite(centroids).all():
        raise ValueError("centroids have NaN or infinite entries")
    labels = _check_labels(cluster_labels, len(centroids))
    if len(centroids) == 0:
        return np.zeros(0, dtype=np.int64)
    labels = np.unique(labels, return_inverse=True)[1]  # compact, so that label values can be sparse

    keys = _curve_position(centroids, curve)
    rank = np.empty(len(keys), dtype=np.float64)
    rank[np.argsort(keys, kind="stable")] = np.arange(len(keys))
    n_clusters = labels.max() + 1
    size = np.bincount(labels, minlength=n_clusters)
    mean_rank = np.bincount(labels, weights=rank, minlength=n_clusters) / np.maximum(size, 1)
    cluster_position = np.empty(n_clusters, dtype=np.int64)
    cluster_position[np.lexsort((np.arange(n_clusters), mean_rank))] = np.arange(n_clusters)
    return np.lexsort((keys, cluster_position[labels])).astype(np.int64)


@dataclass(frozen=True, eq=False)  # arrays inside: compare fields explicitly
class PatchLayout:
    """Where every face sits in the padded token tensor (n_patches, patch_size, ...).

    ``order`` (F,): the face sequence; ``patch_of_face`` and ``slot_of_face``
    (F,): each face's token and its slot inside it; ``mask`` (n_patches,
    patch_size) bool: True at slots holding a face; ``patch_cluster``
    (n_patches,): the cluster of each token.
    """

    order: np.ndarray
    patch_of_face: np.ndarray
    slot_of_face: np.ndarray
    n_patches: int
    patch_size: int
    mask: np.ndarray
    patch_cluster: np.ndarray

    @property
    def n_faces(self) -> int:
        return len(self.order)

    @property
    def flat_slot(self) -> np.ndarray:
        """(F,) each face's row in the tokens flattened to (n_patches * patch_size, ...)."""
        return self.patch_of_face * self.patch_size + self.slot_of_face

    def to_tokens(self, x, fill: float = 0.0):
        """Per-face ``x`` (F, ...) -> tokens (n_patches, patch_size, ...), padding slots set to ``fill``.

        Works on numpy arrays and torch tensors (differentiable in ``x``).
        """
        if x.shape[0] != self.n_faces:
            raise ValueError(f"x must have {self.n_faces} rows (one per face), got shape {tuple(x.shape)}")
        rows, rest = self.n_patches * self.patch_size, tuple(x.shape[1:])
        if _is_torch(x):
            index = _torch_index(self.flat_slot, x.device)
            tokens = x.new_full((rows, *rest), fill).index_copy(0, index, x)
        else:
            tokens = np.full((rows, *rest), fill, dtype=np.asarray(x).dtype)
            tokens[self.flat_slot] = x
        return tokens.reshape(self.n_patches, self.patch_size, *rest)

    def to_faces(self, tokens):
        """Tokens (n_patches, patch_size, ...) -> per-face (F, ...); the exact inverse of :meth:`to_tokens`."""
        if tuple(tokens.shape[:2]) != (self.n_patches, self.patch_size):
            raise ValueError(f"tokens must have shape ({self.n_patches}, {self.patch_size}, ...), got {tuple(tokens.shape)}")
        flat = tokens.reshape(self.n_patches * self.patch_size, *tuple(tokens.shape[2:]))
        if _is_torch(tokens):
            return flat.index_select(0, _torch_index(self.flat_slot, tokens.device))
        return flat[self.flat_slot]


def patches(order, cluster_labels, patch_size: int = DEFAULT_PATCH_SIZE) -> PatchLayout:
    """Group the face sequence ``order`` into patches of ``patch_size`` faces that never straddle clusters.

    ``order`` must keep each cluster of ``cluster_labels`` contiguous (as
    :func:`sequence` does). The last patch of each cluster is padded.
    """
    order = np.asarray(order)
    n_faces = len(order)
    labels = _check_labels(cluster_labels, n_faces)
    if int(patch_size) != patch_size or patch_size < 1:
        raise ValueError(f"patch_size must be a positive integer, got {patch_size}")
    patch_size = int(patch_size)
    if order.ndim != 1 or not np.issubdtype(order.dtype, np.integer):
        raise ValueError(f"order must be a 1-D integer array, got {order.dtype} {order.shape}")
    if n_faces and (order.min() < 0 or order.max() >= n_faces or (np.bincount(order, minlength=n_faces) != 1).any()):
        raise ValueError("order must be a permutation of the faces")

    in_order = labels[order]
    starts = np.flatnonzero(np.r_[True, in_order[1:] != in_order[:-1]]) if n_faces else np.zeros(0, dtype=np.int64)
    run_labels = in_order[starts]
    if len(np.unique(run_labels)) != len(run_labels):
        raise ValueError("order splits a cluster into several runs; patches need each cluster contiguous")
    run_lengths = np.diff(np.r_[starts, n_faces])
    patches_per_run = -(-run_lengths // patch_size)
    first_patch = np.r_[0, np.cumsum(patches_per_run)[:-1]].astype(np.int64)

    run = np.repeat(np.arange(len(starts)), run_lengths)
    rank_in_run = np.arange(n_faces) - starts[run]
    patch_of_face = np.empty(n_faces, dtype=np.int64)
    slot_of_face = np.empty(n_faces, dtype=np.int64)
    patch_of_face[order] = first_patch[run] + rank_in_run // patch_size
    slot_of_face[order] = rank_in_run % patch_size
    n_patches = int(patches_per_run.sum())
    mask = np.zeros((n_patches, patch_size), dtype=bool)
    mask[patch_of_face, slot_of_face] = True
    return PatchLayout(
        order=order.astype(np.int64),
        patch_of_face=patch_of_face,
        slot_of_face=slot_of_face,
        n_patches=n_patches,
        patch_size=patch_size,
        mask=mask,
        patch_cluster=np.repeat(run_labels, patches_per_run).astype(np.int64),
    )


def layout(
    mesh: Mesh,
    features,
    k: int = DEFAULT_K,
    patch_size: int = DEFAULT_PATCH_SIZE,
    seed: int = 0,
    curve: str = "hilbert",
    frame: str = "xyz",
) -> PatchLayout:
    """Cluster the faces of ``mesh`` on ``features`` (F, D), order them and cut the sequence into patches.

    ``frame="principal"`` makes the layout independent of the pose and of the
    file's face order: the curve runs in :func:`principal_frame`, and K-means
    sees the faces in their order along that curve (its seeding follows the
    order of the rows), the labels then put back in the mesh's order.
    ``frame="random"`` runs the curve in the coordinates turned by a rotation
    drawn from ``seed`` (:func:`random_frame`), K-means as for ``principal``:
    each seed gives another token order of the same mesh, which is what a
    training that varies its layouts, or a test-time average over layouts,
    needs.
    """
    if len(features) != mesh.n_faces:
        raise ValueError(f"features must have one row per face ({mesh.n_faces}), got {len(features)}")
    if frame not in FRAMES:
        raise ValueError(f"frame must be one of {FRAMES}, got {frame!r}")
    if frame == "xyz":
        labels = cluster_faces(features, k=k, seed=seed)
        return patches(sequence(mesh, labels, curve=curve), labels, patch_size)
    if frame == "principal":
        centroids = principal_frame(mesh.face_centroids, mesh.frame_areas)
    else:
        centroids = random_frame(mesh.face_centroids, seed)
    canonical = np.lexsort((np.arange(mesh.n_faces), _curve_position(centroids, curve)))
    labels = np.empty(mesh.n_faces, dtype=np.int64)
    labels[canonical] = cluster_faces(np.asarray(features)[canonical], k=k, seed=seed)
    return patches(sequence(centroids, labels, curve=curve), labels, patch_size)


def principal_frame(centroids, areas) -> np.ndarray:
    """Face centroids (F, 3) in the surface's own frame: a pose that the mesh's placement does not change.

    Centred on the area-weighted mean and rotated onto the principal axes of
    the area-weighted covariance, longest first; each axis points where the
    area-weighted third moment along it is positive. A rotated, moved,
    scaled or mirrored mesh lands on the same coordinates (up to the scale,
    which the curve's quantisation divides out). Where two principal axes are
    equal, or a shape is symmetric along one, rounding picks the direction.
    """
    centre, axes = _principal_axes(centroids, areas)
    return (np.asarray(centroids, dtype=np.float64) - centre) @ axes


def _principal_axes(centroids, areas) -> tuple[np.ndarray, np.ndarray]:
    """The area-weighted centre (3,) and the principal axes (3, 3, one per column) of :func:`principal_frame`."""
    weights = np.asarray(areas, dtype=np.float64) / np.sum(areas)
    centred = np.asarray(centroids, dtype=np.float64) - weights @ centroids
    _, axes = np.linalg.eigh((centred * weights[:, None]).T @ centred)
    axes = axes[:, ::-1]
    return weights @ centroids, axes * np.where(weights @ (centred @ axes) ** 3 < 0, -1.0, 1.0)


CANONICAL_STEP = 2.0 ** -20  # the canonical pose's coordinates are rounded to this step (the surface has area 1)


@dataclass(frozen=True)
class Pose:
    """Where :func:`canonical_mesh` put a mesh: canonical = (input - centre) @ axes / scale."""

    centre: np.ndarray
    axes: np.ndarray
    scale: float

    def undo(self, vertices: np.ndarray) -> np.ndarray:
        """Canonical coordinates back in the input's frame."""
        return np.asarray(vertices) * self.scale @ self.axes.T + self.centre


def canonical_mesh(mesh: Mesh) -> tuple[Mesh, np.ndarray, Pose]:
    """``mesh`` in a pose and an order fixed by the surface alone, each face's input face, and the pose it was put in.

    The coordinates go to :func:`principal_frame`'s frame at unit area and
    are rounded to :data:`CANONICAL_STEP`: a rotated, moved, scaled or
    mirrored copy lands there too, and the rounding makes the copies'
    coordinates equal to the last bit (the collapse turns differences in
    the last bits into other labels). The rounding is skipped where it
    would make a face degenerate. Vertices follow in the order of their
    coordinates; each face's corners start at its lowest vertex, all faces
    reversed where the signed volume about the centre is negative (the
    outward side as :mod:`anseg.features` reads it); faces in the order of
    their corners. A file that lists its faces or vertices in another
    order, or its faces the other way round, gives the same mesh too.
    """
    centre, axes = _principal_axes(mesh.face_centroids, mesh.frame_areas)
    pose = Pose(centre, axes, float(np.sqrt(mesh.frame_areas.sum())))
    exact = (mesh.vertices - centre) @ axes / pose.scale
    posed = Mesh(np.round(exact / CANONICAL_STEP) * CANONICAL_STEP, mesh.faces)
    if degenerate_faces(posed).any():
        posed = Mesh(exact, mesh.faces)
    vertex_order = np.lexsort(posed.vertices.T[::-1])
    new_id = np.empty(mesh.n_vertices, dtype=np.int64)
    new_id[vertex_order] = np.arange(mesh.n_vertices)
    faces = new_id[mesh.faces]
    if (posed.face_normals * posed.frame_areas[:, None] * posed.face_centroids).sum() < 0:  # about the centre, at 0
        faces = faces[:, ::-1]
    first = faces.argmin(axis=1)
    faces = np.take_along_axis(faces, (first[:, None] + np.arange(3)) % 3, axis=1)
    input_face = np.lexsort(faces.T[::-1])
    return Mesh(posed.vertices[vertex_order], faces[input_face]), input_face, pose


def random_frame(centroids, seed: int) -> np.ndarray:
    """Face centroids (F, 3) turned by a rotation drawn uniformly from ``seed`` (scipy's ``Rotation.random``)."""
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=seed).apply(np.asarray(centroids, dtype=np.float64))


def _curve_position(centroids: np.ndarray, curve: str) -> np.ndarray:
    """Each centroid's key along the curve, quantised on the cube around their bounding box (one step for every axis,
    so that curve distance follows true distance)."""
    low = centroids.min(axis=0)
    side = float((centroids.max(axis=0) - low).max())
    n_cells = 1 << CURVE_BITS
    cells = np.floor((centroids - low) * (n_cells / side if side > 0 else 0.0))
    return curve_keys(np.clip(cells, 0, n_cells - 1).astype(np.int64), CURVE_BITS, curve)


def _check_labels(cluster_labels, n_faces: int) -> np.ndarray:
    labels = np.asarray(cluster_labels)
    if labels.shape != (n_faces,) or not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"cluster_labels must be an integer array of shape ({n_faces},), got {labels.dtype} {labels.shape}")
    if n_faces and labels.min() < 0:
        raise ValueError(f"cluster_labels must be non-negative, got {labels.min()}")
    return labels


def _is_torch(x) -> bool:
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(x, torch.Tensor)


def _torch_index(index: np.ndarray, device):
    import torch

    return torch.from_numpy(index).to(device)
