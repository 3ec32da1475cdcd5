"""Training copies: stretched within bounds, tessellated anew, labelled as the faces they stand for, reproducible."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from anseg import datasets
from anseg.augment import KEEP, MAX_STRETCH, augmented, stretched
from anseg.pipeline import SegmentConfig
from anseg.train import TrainConfig, fit


def figures(n: int = 4):
    return datasets.load("synthetic", category="figure", split="train", n_shapes=n, progress=False)


def test_a_stretch_is_linear_and_bounded_per_axis():
    item = figures()[0]
    rng = np.random.default_rng(0)
    moved = stretched(item.mesh, rng)
    # the map is linear: solve for it from the vertices, and read its singular values
    linear, *_ = np.linalg.lstsq(item.mesh.vertices, moved.vertices, rcond=None)
    assert np.allclose(item.mesh.vertices @ linear, moved.vertices, atol=1e-9)
    singular = np.linalg.svd(linear, compute_uv=False)
    assert np.all(singular <= MAX_STRETCH + 1e-9) and np.all(singular >= 1 / MAX_STRETCH - 1e-9)
    assert not np.allclose(singular, 1.0)
    stronger = np.linalg.svd(np.linalg.lstsq(item.mesh.vertices, stretched(item.mesh, np.random.default_rng(0), 2.0).vertices,
                                             rcond=None)[0], compute_uv=False)
    assert stronger.max() > MAX_STRETCH and np.all(stronger <= 2.0 + 1e-9)  # train.augment_stretch sets the bound
    assert np.allclose(np.linalg.svd(np.linalg.lstsq(item.mesh.vertices, stretched(item.mesh, rng, 1.0).vertices,
                                                     rcond=None)[0], compute_uv=False), 1.0)


def test_copies_are_new_tessellations_whose_labels_keep_each_parts_share_of_the_area():
    item = figures()[0]
    copies = augmented(item, 2, seed=3)
    assert [c.name for c in copies] == [f"{item.name}+copy0", f"{item.name}+copy1"]
    for copy in copies:
        assert abs(copy.mesh.n_faces - KEEP * item.mesh.n_faces) <= 2 and copy.labels.shape == (copy.mesh.n_faces,)
        share = np.bincount(item.labels, item.mesh.face_areas, minlength=len(item.label_names)) / item.mesh.face_areas.sum()
        copy_share = np.bincount(copy.labels, copy.mesh.face_areas, minlength=len(item.label_names)) / copy.mesh.face_areas.sum()
        assert np.abs(share - copy_share).max() < 0.05  # stretching moves the shares a little; the labels do not scramble
    assert not np.array_equal(copies[0].mesh.vertices, copies[1].mesh.vertices)
    again = augmented(item, 2, seed=3)
    assert all(np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.labels, b.labels)
               for a, b in zip(copies, again))


def test_training_with_copies_sees_them_and_stays_off_by_default(monkeypatch):
    import anseg.train as train_module

    torch.set_num_threads(1)
    assert TrainConfig().augment_copies == 0
    with pytest.raises(ValueError, match="augment_stretch"):
        TrainConfig(augment_stretch=0.5)
    seen = []
    real = train_module.level_zero_features
    monkeypatch.setattr(train_module, "level_zero_features",
                        lambda meshes, *a, **k: seen.append(len(meshes)) or real(meshes, *a, **k))
    train_set = figures(4)[:2]
    fit(train_set, train_set[0].label_names, SegmentConfig(cycles=1, clusters=4, patch_size=16),
        TrainConfig(epochs=1, width=16, depth=1, augment_copies=2), progress=False)
    assert seen == [3 * len(train_set)]
