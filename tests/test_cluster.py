"""K-means face clusters, the space-filling-curve sequence and the patch layout."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import grid_mesh

from anseg.cluster import cluster_faces, curve_keys, layout, patches, sequence
from anseg.mesh import Mesh


def blobs(n_per_blob: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Three tight blobs at (0, 0), (1, 0), (0, 1), with feature 0 in units 1e4 times smaller."""
    rng = np.random.default_rng(seed)
    truth = np.repeat(np.arange(3), n_per_blob)
    rng.shuffle(truth)
    centres = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    points = centres[truth] + rng.normal(scale=0.05, size=(len(truth), 2))
    return points * [1e-4, 1.0], truth


def same_partition(a: np.ndarray, b: np.ndarray) -> bool:
    pairs = np.unique(np.stack([a, b], axis=1), axis=0)
    return len(pairs) == len(np.unique(a)) == len(np.unique(b))


def sphere() -> Mesh:
    """A closed icosphere of 5120 faces."""
    return grid_mesh(7, closed=True)


# ---------------------------------------------------------------- curve keys
def test_hilbert_visits_every_cell_by_unit_steps():
    cells = np.stack(np.meshgrid(*[np.arange(8)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    keys = curve_keys(cells, bits=3, curve="hilbert")
    assert np.array_equal(np.sort(keys), np.arange(512))
    steps = np.abs(np.diff(cells[np.argsort(keys)], axis=0)).sum(axis=1)
    assert (steps == 1).all()


def test_morton_interleaves_bits():
    cells = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 0, 0], [3, 3, 3], [2, 0, 1]])
    assert curve_keys(cells, bits=2, curve="morton").tolist() == [0, 1, 2, 4, 63, 33]
    full = (1 << 21) - 1
    assert curve_keys(np.array([[full] * 3]), bits=21, curve="morton")[0] == (1 << 63) - 1


@pytest.mark.parametrize(
    "cells, kwargs, message",
    [
        (np.zeros((4, 3), int), {"curve": "peano"}, "curve"),
        (np.zeros((4, 3), int), {"bits": 22}, "bits"),
        (np.zeros((4, 2), int), {}, "shape"),
        (np.full((4, 3), 8), {"bits": 3}, "lie in"),
    ],
)
def test_curve_keys_rejects_bad_input(cells, kwargs, message):
    with pytest.raises(ValueError, match=message):
        curve_keys(cells, **kwargs)


# ---------------------------------------------------------------- clustering
def test_clusters_are_standardised_and_deterministic():
    features, truth = blobs(200)
    labels = cluster_faces(features, k=3, seed=0)
    # without standardisation feature 0 would be invisible and two blobs would merge
    assert same_partition(labels, truth)
    assert np.array_equal(labels, cluster_faces(features, k=3, seed=0))
    assert labels.dtype == np.int64 and set(labels.tolist()) == {0, 1, 2}


def test_kmeans_runs_on_one_openmp_thread_whatever_the_process_allows(monkeypatch):
    # more threads sum the Lloyd updates in another order, which moved a real mesh's clusters
    from sklearn.cluster import KMeans
    from threadpoolctl import threadpool_info, threadpool_limits

    seen, fit = [], KMeans.fit

    def recording_fit(self, *args, **kwargs):
        seen.extend(pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "openmp")
        return fit(self, *args, **kwargs)

    monkeypatch.setattr(KMeans, "fit", recording_fit)
    features, _ = blobs(200)
    with threadpool_limits(limits=2, user_api="openmp"):
        cluster_faces(features, k=3, seed=0)
    assert seen and set(seen) == {1}


def test_large_inputs_fit_on_a_subset_and_assign_all():
    features, truth = blobs(400, seed=1)
    labels = cluster_faces(features, k=3, seed=5, max_fit_faces=100)
    assert same_partition(labels, truth)
    assert np.array_equal(labels, cluster_faces(features, k=3, seed=5, max_fit_faces=100))


def test_fewer_faces_or_distinct_rows_than_k():
    assert sorted(cluster_faces(np.arange(3.0)[:, None], k=16).tolist()) == [0, 1, 2]
    repeated = np.repeat([[0.0, 1.0], [5.0, 2.0]], 10, axis=0)
    labels = cluster_faces(repeated, k=8)
    assert set(labels.tolist()) == {0, 1} and same_partition(labels, np.repeat([0, 1], 10))


@pytest.mark.parametrize(
    "features, k, message",
    [(np.zeros(5), 2, "shape"), (np.zeros((0, 3)), 2, "shape"),
     (np.full((5, 2), np.nan), 2, "NaN"), (np.zeros((5, 2)), 0, "k must")],
)
def test_cluster_faces_rejects_bad_input(features, k, message):
    with pytest.raises(ValueError, match=message):
        cluster_faces(features, k=k)


# ------------------------------------------------------------------ sequence
def test_sequence_is_a_permutation_with_contiguous_clusters():
    mesh = sphere()
    labels = cluster_faces(np.c_[mesh.face_normals, mesh.face_centroids], k=6)
    order = sequence(mesh, labels)
    assert np.array_equal(np.sort(order), np.arange(mesh.n_faces))
    runs = 1 + np.count_nonzero(np.diff(labels[order]))
    assert runs == len(np.unique(labels))
    assert np.array_equal(order, sequence(mesh.face_centroids, labels))


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
def test_consecutive_faces_are_close(curve):
    mesh = sphere()
    c = mesh.face_centroids
    order = sequence(mesh, np.zeros(mesh.n_faces, dtype=int), curve=curve)
    consecutive = np.linalg.norm(np.diff(c[order], axis=0), axis=1).mean()
    a, b = np.random.default_rng(0).integers(0, mesh.n_faces, (2, 5000))
    random_pairs = np.linalg.norm(c[a] - c[b], axis=1).mean()
    assert consecutive < 0.1 * random_pairs


def test_cluster_order_follows_position_not_label_values():
    mesh = sphere()
    halves = (mesh.face_centroids[:, 0] > 0).astype(int)
    order = sequence(mesh, halves)
    assert np.array_equal(order, sequence(mesh, 1 - halves))
    assert np.array_equal(order, sequence(mesh, halves * 1000 + 7))


def test_sequence_rejects_bad_input():
    mesh = grid_mesh(2)
    with pytest.raises(ValueError, match="cluster_labels"):
        sequence(mesh, np.zeros(3, dtype=int))
    with pytest.raises(ValueError, match="cluster_labels"):
        sequence(mesh, np.full(8, 0.5))
    with pytest.raises(ValueError, match="NaN"):
        sequence(np.full((4, 3), np.nan), np.zeros(4, dtype=int))


# ------------------------------------------------------------------- patches
@pytest.fixture(scope="module")
def sphere_layout():
    mesh = sphere()
    features = np.c_[mesh.face_normals, mesh.face_centroids]
    return mesh, layout(mesh, features, k=5, patch_size=16)


def test_patches_cover_every_face_once_and_stay_in_one_cluster(sphere_layout):
    mesh, lay = sphere_layout
    assert lay.mask.sum() == mesh.n_faces == lay.n_faces
    assert lay.mask.shape == (lay.n_patches, 16)
    slots = lay.patch_of_face * lay.patch_size + lay.slot_of_face
    assert len(np.unique(slots)) == mesh.n_faces
    sizes = np.bincount(lay.patch_cluster[lay.patch_of_face])
    assert lay.n_patches == int(np.ceil(sizes / 16).sum())  # exactly the patches that non-straddling needs
    # slots fill from the front, so padding sits only at the end of a cluster's last patch
    assert (np.diff(lay.mask.astype(int), axis=1) <= 0).all()
    assert (lay.mask.sum(axis=1) < 16).sum() <= len(sizes)


def test_tokens_hold_the_sequence_in_order(sphere_layout):
    mesh, lay = sphere_layout
    tokens = lay.to_tokens(np.arange(mesh.n_faces), fill=-1)
    assert np.array_equal(tokens[lay.mask], lay.order)
    assert (tokens[~lay.mask] == -1).all()
    cluster_tokens = lay.to_tokens(lay.patch_cluster[lay.patch_of_face], fill=-1)
    assert all(set(row[row >= 0].tolist()) == {c} for row, c in zip(cluster_tokens, lay.patch_cluster))


def test_round_trip_numpy_and_torch(sphere_layout):
    mesh, lay = sphere_layout
    x = np.random.default_rng(0).normal(size=(mesh.n_faces, 3, 2)).astype(np.float32)
    tokens = lay.to_tokens(x)
    assert tokens.shape == (lay.n_patches, 16, 3, 2) and tokens.dtype == np.float32
    assert np.array_equal(lay.to_faces(tokens), x)

    xt = torch.from_numpy(x).requires_grad_()
    tokens_t = lay.to_tokens(xt)
    assert torch.equal(tokens_t, torch.from_numpy(tokens))
    assert torch.equal(lay.to_faces(tokens_t), xt)
    (tokens_t * 2).sum().backward()
    assert torch.equal(xt.grad, torch.full_like(xt, 2.0))


def test_layout_shape_errors(sphere_layout):
    mesh, lay = sphere_layout
    with pytest.raises(ValueError, match="one per face"):
        lay.to_tokens(np.zeros((mesh.n_faces + 1, 2)))
    with pytest.raises(ValueError, match="tokens must have shape"):
        lay.to_faces(np.zeros((lay.n_patches, 8, 2)))
    with pytest.raises(ValueError, match="one row per face"):
        layout(mesh, np.zeros((3, 2)))


def test_patches_reject_bad_order():
    labels = np.array([0, 0, 1, 1])
    with pytest.raises(ValueError, match="contiguous"):
        patches(np.array([0, 2, 1, 3]), labels, 2)
    with pytest.raises(ValueError, match="permutation"):
        patches(np.array([0, 0, 1, 3]), labels, 2)
    with pytest.raises(ValueError, match="patch_size"):
        patches(np.arange(4), labels, 0)


def test_small_patch_counts_by_hand():
    # clusters of 5 and 2 faces with patches of 2: 3 + 1 patches, one padded slot
    labels = np.array([1, 1, 0, 0, 0, 0, 0])
    lay = patches(np.array([2, 3, 4, 5, 6, 0, 1]), labels, 2)
    assert lay.n_patches == 4
    assert lay.patch_cluster.tolist() == [0, 0, 0, 1]
    assert lay.mask.tolist() == [[True, True], [True, True], [True, False], [True, True]]
    assert lay.patch_of_face.tolist() == [3, 3, 0, 0, 1, 1, 2]
    assert lay.slot_of_face.tolist() == [0, 1, 0, 1, 0, 1, 0]


def bumpy_blob() -> tuple[Mesh, np.ndarray]:
    """A stretched, skewed, bumpy sphere with per-face features that move with the faces (no symmetry to tie on)."""
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=3)
    v = ball.vertices * [2.0, 1.0, 0.6]
    v = v + 0.15 * v[:, :1] ** 2 + 0.05 * np.sin(5 * v)
    mesh = Mesh(v, ball.faces)
    features = np.stack([mesh.face_areas, np.linalg.norm(mesh.face_centroids - mesh.face_centroids.mean(0), axis=1)], 1)
    return mesh, features


def same_layout(a, b, b_face_of_a: np.ndarray) -> bool:
    """The same clusters and the same patches, face for face, after ``b``'s faces are matched to ``a``'s."""
    patch_a, patch_b = a.patch_of_face, b.patch_of_face[b_face_of_a]
    slot_a, slot_b = a.slot_of_face, b.slot_of_face[b_face_of_a]
    return np.array_equal(patch_a, patch_b) and np.array_equal(slot_a, slot_b)


@pytest.mark.parametrize("transform", ["rotation", "scale and shift", "face order", "mirror"])
def test_the_principal_frame_layout_does_not_depend_on_the_pose_or_the_face_order(transform):
    from scipy.spatial.transform import Rotation

    mesh, features = bumpy_blob()
    faces, order = mesh.faces, np.arange(mesh.n_faces)
    vertices = mesh.vertices
    if transform == "rotation":
        vertices = vertices @ Rotation.random(random_state=3).as_matrix().T
    elif transform == "scale and shift":
        vertices = 1000 * vertices + [5e3, -2e3, 7e3]
    elif transform == "face order":
        order = np.random.default_rng(4).permutation(mesh.n_faces)
        faces = faces[order]
    else:
        vertices = vertices * [-1, 1, 1]
        faces = faces[:, ::-1]
    moved = Mesh(vertices, faces)
    here = layout(mesh, features, k=6, patch_size=16, frame="principal")
    there = layout(moved, features[order], k=6, patch_size=16, frame="principal")
    assert same_layout(here, there, np.argsort(order))
    if transform != "scale and shift":  # the coordinates' own frame moves with the mesh
        assert not same_layout(layout(mesh, features, k=6, patch_size=16),
                               layout(moved, features[order], k=6, patch_size=16), np.argsort(order))


def test_a_random_frame_layout_is_fixed_by_its_seed_and_moves_with_it():
    mesh, features = bumpy_blob()
    first = layout(mesh, features, k=6, patch_size=16, seed=1, frame="random")
    assert same_layout(first, layout(mesh, features, k=6, patch_size=16, seed=1, frame="random"), np.arange(mesh.n_faces))
    assert not same_layout(first, layout(mesh, features, k=6, patch_size=16, seed=2, frame="random"),
                           np.arange(mesh.n_faces))


@pytest.mark.parametrize("change", ["face order", "vertex order", "flip", "rotation", "scale and shift", "mirror"])
def test_the_canonical_mesh_is_the_same_whatever_the_pose_the_file_order_or_the_orientation(change):
    from scipy.spatial.transform import Rotation

    from anseg.cluster import canonical_mesh

    mesh, _ = bumpy_blob()
    rng = np.random.default_rng(5)
    if change == "face order":
        moved = Mesh(mesh.vertices, mesh.faces[rng.permutation(mesh.n_faces)])
    elif change == "vertex order":
        p = rng.permutation(mesh.n_vertices)
        moved = Mesh(mesh.vertices[p], np.argsort(p)[mesh.faces])
    elif change == "flip":
        moved = Mesh(mesh.vertices, mesh.faces[:, ::-1])
    elif change == "rotation":
        moved = Mesh(Rotation.random(random_state=3).apply(mesh.vertices), mesh.faces)
    elif change == "scale and shift":
        moved = Mesh(mesh.vertices * 1000.0 + [1e4, -2e4, 3e4], mesh.faces)
    else:
        moved = Mesh(mesh.vertices * [-1.0, 1.0, 1.0], mesh.faces[:, ::-1])
    here, here_input, here_pose = canonical_mesh(mesh)
    there, there_input, there_pose = canonical_mesh(moved)
    # equal to the last bit, so that nothing downstream can tell the two apart
    assert np.array_equal(here.vertices, there.vertices) and np.array_equal(here.faces, there.faces)
    # each canonical face is the input face it says it is, back in the input's pose
    for original, canonical, input_face, pose in ((mesh, here, here_input, here_pose), (moved, there, there_input, there_pose)):
        assert np.allclose(np.sort(original.vertices[original.faces[input_face]], axis=1),
                           np.sort(pose.undo(canonical.vertices)[canonical.faces], axis=1), atol=1e-5 * pose.scale)
    assert np.isclose(here.face_areas.sum(), 1.0)