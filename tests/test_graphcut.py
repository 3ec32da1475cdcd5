"""Graph-cut smoothing: recovery of noisy regions, the concave-crease preference, energy, errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh

from anseg.graphcut import energy, smooth
from anseg.mesh import Mesh


def two_class_probs(class_one: np.ndarray, confidence: float) -> np.ndarray:
    """(F, 2) probabilities giving each face ``confidence`` in its class of ``class_one`` (bool)."""
    p_one = np.where(class_one, confidence, 1 - confidence)
    return np.stack([1 - p_one, p_one], axis=1)


def folded_grid(n: int, crease: int, angle: float) -> Mesh:
    """grid_mesh(n) with the part beyond x = crease rotated up by ``angle`` about that line.

    The fold is isometric, so faces keep their areas and edges their lengths.
    Upward (positive angle) makes the crease concave seen from the +z normals.
    """
    flat = grid_mesh(n)
    x = flat.vertices[:, 0]
    beyond = np.maximum(x - crease, 0.0)
    vertices = flat.vertices.copy()
    vertices[:, 0] = np.minimum(x, crease) + beyond * np.cos(angle)
    vertices[:, 2] = beyond * np.sin(angle)
    return Mesh(vertices, flat.faces)


def test_recovers_two_noisy_regions():
    mesh = grid_mesh(20)
    truth = mesh.face_centroids[:, 0] > 10
    rng = np.random.default_rng(0)
    flipped = rng.random(mesh.n_faces) < 0.25
    probs = two_class_probs(truth ^ flipped, 0.7)
    noisy_accuracy = (probs.argmax(1) == truth).mean()
    smoothed_accuracy = (smooth(mesh, probs) == truth).mean()
    assert noisy_accuracy < 0.8
    assert smoothed_accuracy > 0.98


def test_weight_zero_and_single_class_give_argmax():
    mesh = grid_mesh(6)
    probs = np.random.default_rng(1).dirichlet(np.ones(4), mesh.n_faces)
    labels = smooth(mesh, probs, weight=0)
    assert labels.dtype == np.int64
    assert np.array_equal(labels, probs.argmax(1))
    assert not np.array_equal(smooth(mesh, probs, weight=5), labels)
    assert np.array_equal(smooth(mesh, np.ones((mesh.n_faces, 1))), np.zeros(mesh.n_faces))


@pytest.mark.parametrize("fold, boundary_at", [(np.pi / 3, 8.0), (0.0, 9.0), (-np.pi / 3, 9.0)])
def test_cut_moves_onto_a_concave_crease_only(fold, boundary_at):
    # mild evidence puts the boundary one column right of the crease at x = 8;
    # only a concave fold makes the cut there cheap enough to pay for that column
    crease, n = 8, 16
    flat = grid_mesh(n)
    mesh = folded_grid(n, crease, fold)
    x = flat.face_centroids[:, 0]
    probs = two_class_probs(x > crease + 1, 0.95)
    column = (x > crease) & (x < crease + 1)
    probs[column] = [0.6, 0.4]
    labels = smooth(mesh, probs, weight=3.0)
    assert np.array_equal(labels, (x > boundary_at).astype(int))


def test_fold_sign_convention():
    flat = grid_mesh(16)
    crease_edges = np.isclose(flat.vertices[flat.edges][:, :, 0], 8).all(axis=1)
    for fold, sign in [(np.pi / 3, -1), (-np.pi / 3, 1)]:
        mesh = folded_grid(16, 8, fold)
        on_crease = crease_edges[mesh.interior_edges]
        assert np.allclose(mesh.dihedral_angles[on_crease], sign * np.pi / 3)
        assert np.allclose(mesh.dihedral_angles[~on_crease], 0, atol=1e-6)


@pytest.mark.parametrize("weight", [0.3, 1.0, 4.0])
def test_energy_never_above_argmax(weight):
    mesh = grid_mesh(5, closed=True)
    probs = np.random.default_rng(2).dirichlet(np.ones(5) * 0.5, mesh.n_faces)
    argmax = probs.argmax(1)
    labels = smooth(mesh, probs, weight=weight)
    e_argmax = energy(mesh, probs, argmax, weight=weight)
    e_smooth = energy(mesh, probs, labels, weight=weight)
    assert e_smooth <= e_argmax * (1 + 1e-6)
    assert e_smooth < 0.99 * e_argmax  # the cut found something better, not just the start


def test_energy_terms_by_hand():
    mesh = grid_mesh(1)  # two right triangles sharing the diagonal
    probs = np.array([[0.8, 0.2], [0.3, 0.7]])
    split = energy(mesh, probs, np.array([0, 1]), weight=2.0, eps=1e-12)
    same = energy(mesh, probs, np.array([0, 0]), weight=2.0, eps=1e-12)
    diagonal = np.sqrt(2) / ((4 + np.sqrt(2)) / 5)  # shared edge over the mean edge length
    assert split == pytest.approx(-np.log(0.8) - np.log(0.7) + 2.0 * diagonal)
    assert same == pytest.approx(-np.log(0.8) - np.log(0.3))


def test_components_are_independent_and_units_do_not_matter():
    a, b = grid_mesh(8), grid_mesh(8)
    both = Mesh(np.concatenate([a.vertices, b.vertices + [20, 0, 0]]), np.concatenate([a.faces, b.faces + a.n_vertices]))
    rng = np.random.default_rng(3)
    probs = rng.dirichlet(np.ones(3), both.n_faces)
    joint = smooth(both, probs)
    assert np.array_equal(joint[: a.n_faces], smooth(a, probs[: a.n_faces]))
    assert np.array_equal(joint[a.n_faces :], smooth(b, probs[a.n_faces :]))
    scaled = Mesh(both.vertices * 1000.0, both.faces)
    assert np.array_equal(smooth(scaled, probs), joint)


@pytest.mark.parametrize(
    "probs, kwargs, message",
    [
        (np.full((10, 2), 0.5), {}, "shape"),
        (np.full((32, 2, 1), 0.5), {}, "shape"),
        (np.zeros((32, 0)), {}, "shape"),
        (np.where(np.arange(64).reshape(32, 2) == 5, np.nan, 0.5), {}, "NaN"),
        (np.full((32, 2), -0.1), {}, "non-negative"),
        (np.full((32, 2), 0.5), {"weight": -1.0}, "weight"),
        (np.full((32, 2), 0.5), {"concave_discount": np.inf}, "concave_discount"),
        (np.full((32, 2), 0.5), {"eps": 0.0}, "eps"),
    ],
)
def test_bad_input_raises(probs, kwargs, message):
    with pytest.raises(ValueError, match=message):
        smooth(grid_mesh(4), probs, **kwargs)


def test_energy_rejects_bad_labels():
    mesh, probs = grid_mesh(2), np.full((8, 2), 0.5)
    with pytest.raises(ValueError, match="lie in"):
        energy(mesh, probs, np.full(8, 2))
    with pytest.raises(ValueError, match="shape"):
        energy(mesh, probs, np.zeros(7, dtype=int))
