"""The second stage: anchor features read where a face sits relative to the first stage's parts; the refiner learns them."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import grid_mesh

from anseg import datasets
from anseg.pipeline import SegmentConfig, Segmenter, segment
from anseg.refine import DIFFUSION_TIMES, FAR, anchor_features, fit_refiner
from anseg.train import TrainConfig, fit


def halves(n: int = 5):
    """A closed sphere, its faces labelled by the sign of z, as sure one-hot probabilities of three classes (none of
    the third)."""
    mesh = grid_mesh(n, closed=True)
    labels = (mesh.face_centroids[:, 2] > 0).astype(int)
    return mesh, labels, np.eye(3)[labels]


def test_anchor_features_hold_the_log_probabilities_their_diffusions_and_the_distances_to_each_class():
    mesh, labels, probabilities = halves()
    x = anchor_features(mesh, probabilities)
    n = len(DIFFUSION_TIMES)
    assert x.shape == (mesh.n_faces, 3 * (2 + n)) and x.dtype == np.float32
    assert np.allclose(np.exp(x[:, :3]), probabilities, atol=1e-5)
    for k in range(n):  # diffusion keeps the probabilities summing to one, and blurs the boundary, not the poles
        diffused = x[:, 3 * (1 + k) : 3 * (2 + k)]
        assert np.allclose(diffused.sum(axis=1), 1.0, atol=0.05)
    distances = x[:, -3:]
    assert np.all(distances[labels == 0, 0] == 0) and np.all(distances[labels == 1, 1] == 0)
    assert np.all(distances[:, 2] == FAR)  # a class no face took
    south = labels == 0  # the farther south, the farther from the northern half
    assert np.corrcoef(distances[south, 1], -mesh.face_centroids[south, 2])[0, 1] > 0.9


def test_the_refiner_learns_labels_that_only_the_anchors_tell_apart():
    mesh, labels, probabilities = halves()
    blurred = 0.5 * probabilities + 0.5 / 3  # the first stage was unsure; the distances still tell the halves apart
    own = np.zeros((mesh.n_faces, 1))  # the faces' own features say nothing
    examples = [(own, anchor_features(mesh, blurred), labels, mesh.face_areas)]
    refiner = fit_refiner(examples, 3, steps=200)
    assert (refiner.probabilities(own, examples[0][1]).argmax(axis=1) == labels).mean() > 0.95


def test_second_stage_is_off_by_default_and_refuses_one_fold():
    assert TrainConfig().second_stage_folds == 0
    with pytest.raises(ValueError, match="second_stage_folds"):
        TrainConfig(second_stage_folds=1)


def test_a_model_with_a_second_stage_trains_cross_fitted_segments_and_survives_its_file(tmp_path):
    torch.set_num_threads(1)
    load = dict(category="figure", n_shapes=6, progress=False)
    train_set, test_set = datasets.load("synthetic", split="train", **load), datasets.load("synthetic", split="test", **load)
    config = SegmentConfig(cycles=1, clusters=4, patch_size=16)
    model = fit(train_set, train_set[0].label_names, config,
                TrainConfig(epochs=2, width=16, depth=1, second_stage_folds=2), progress=False)
    assert model.refiner is not None
    first = segment(test_set[0].mesh, model)
    assert first.labels.shape == (test_set[0].mesh.n_faces,) and np.allclose(first.probabilities.sum(axis=1), 1.0)
    model.save(tmp_path / "model.pt")
    again = Segmenter.load(tmp_path / "model.pt")
    assert again.refiner is not None
    assert np.array_equal(segment(test_set[0].mesh, again).labels, first.labels)
