"""Algorithm 1 end to end on synthetic shapes: levels, segmentation, the saved model, training."""

from __future__ import annotations

import io
from dataclasses import replace

import numpy as np
import pytest
import torch
from conftest import grid_mesh

from anseg import datasets
from anseg.mesh import Mesh
from anseg.pipeline import SegmentConfig, Segmenter, build_levels, segment
from anseg.study.runner import run_experiment
from anseg.study.store import Experiment
from anseg.train import TrainConfig, fit

FAST = SegmentConfig(cycles=2, clusters=4, patch_size=16)


@pytest.fixture(scope="module")
def shapes():
    return datasets.load("synthetic", category="figure", split="all", n_shapes=8, progress=False)


@pytest.fixture(scope="module")
def model(shapes):
    torch.set_num_threads(1)  # two threads on a loaded 2-core machine run slower than one
    return fit(shapes[:3], shapes[0].label_names, FAST, TrainConfig(epochs=2, width=32), progress=False)


def test_levels_shrink_by_the_ratio_and_keep_attention(model, shapes):
    mesh = shapes[4].mesh
    levels = build_levels(mesh, model, FAST)
    assert len(levels) == FAST.cycles + 1
    for finer, coarser in zip(levels, levels[1:]):
        assert abs(coarser.mesh.n_faces - round(FAST.ratio * finer.mesh.n_faces)) <= 2
        assert finer.attention is not None and finer.attention.shape == (finer.mesh.n_faces,)
        assert finer.record.n_fine_faces == finer.mesh.n_faces
        assert set(coarser.groups) == set(FAST.groups)
        assert all(len(block) == coarser.mesh.n_faces for block in coarser.groups.values())


@pytest.mark.parametrize("mode, n_levels", [("nonuniform", 3), ("uniform", 3), ("none", 1)])
def test_segment_labels_every_original_face(model, shapes, mode, n_levels):
    mesh = shapes[5].mesh
    result = segment(mesh, model, replace(FAST, mode=mode))
    assert len(result.levels) == n_levels
    assert result.labels.shape == (mesh.n_faces,) and result.labels.dtype.kind == "i"
    assert np.allclose(result.probabilities.sum(axis=1), 1.0)
    assert result.labels.min() >= 0 and result.labels.max() < model.n_classes
    assert np.array_equal(result.unsmoothed_labels, result.probabilities.argmax(axis=1))


def test_saved_model_segments_identically(model, shapes, tmp_path):
    path = tmp_path / "model.pt"
    model.save(path)
    again = Segmenter.load(path)
    assert again.config == model.config and again.label_names == model.label_names
    mesh = shapes[6].mesh
    assert np.array_equal(segment(mesh, model).labels, segment(mesh, again).labels)


def test_a_model_file_older_than_a_setting_segments_with_the_value_it_was_trained_with(model, tmp_path):
    """A file written before ``priority`` or ``layout_frame`` existed ran with their first values, not today's
    defaults, so that a change of default never changes what a shipped or stored model does."""
    path = tmp_path / "older.pt"
    newer = replace(model, config=replace(model.config, priority="weighted", layout_frame="principal"))
    payload = torch.load(io.BytesIO(newer.to_bytes()), weights_only=True)
    for name in ("priority", "layout_frame", "density_range"):
        del payload["segment_config"][name]
    torch.save(payload, path)
    loaded = Segmenter.load(path).config
    assert (loaded.priority, loaded.layout_frame, loaded.density_range) == ("score", "xyz", float("inf"))
    assert loaded.cycles == model.config.cycles  # what the file holds, it keeps


def test_load_rejects_other_files(tmp_path):
    bogus = tmp_path / "bogus.pt"
    bogus.write_bytes(b"not a model")
    with pytest.raises(ValueError, match="not a model written by anseg"):
        Segmenter.load(bogus)


@pytest.mark.parametrize("bad", [{"mode": "sideways"}, {"ratio": 1.5}, {"cycles": -1}, {"combine": "some"}, {"passes": 0}])
def test_config_rejects_bad_values(bad):
    with pytest.raises(ValueError):
        SegmentConfig(**bad)


def test_standardize_checks_the_width(model):
    with pytest.raises(ValueError, match="feature columns"):
        model.standardize(np.zeros((3, 2)))


def test_experiment_result_is_stored_and_reused(tmp_path, monkeypatch):
    experiment = Experiment("synthetic", "vessel", 0, replace(FAST, cycles=1), TrainConfig(epochs=1, width=32))
    first = run_experiment(experiment, out_dir=tmp_path, progress=False, n_shapes=4)
    assert 0.0 <= first["accuracy"]["unit_area"] <= 1.0
    assert (tmp_path / "models" / f"{experiment.key({'n_shapes': 4})}.pt").is_file()
    assert experiment.key({"n_shapes": 4}) != experiment.key()
    monkeypatch.setattr("anseg.train.fit", lambda *a, **k: pytest.fail("a stored result must not be retrained"))
    assert run_experiment(experiment, out_dir=tmp_path, progress=False, n_shapes=4) == first


def test_relative_local_scale_puts_a_coarse_level_on_the_fine_scale():
    from anseg import features
    from anseg.pipeline import input_groups

    coarse, fine = (features.compute_groups(grid_mesh(n), ["edge", "angles"]) for n in (4, 8))
    assert not np.allclose(coarse["edge"], fine["edge"][: len(coarse["edge"])])  # unit-area lengths halve
    relative = [input_groups(g, "relative") for g in (coarse, fine)]
    np.testing.assert_allclose(relative[0]["edge"][0], relative[1]["edge"][0], atol=1e-9)
    np.testing.assert_array_equal(relative[0]["angles"], coarse["angles"])  # dimensionless groups stay
    assert input_groups(coarse, "unit_area") is coarse


def test_collapse_weights_clip_the_density_range_around_the_median():
    from anseg.pipeline import collapse_weights

    attention = np.array([1e-9, 0.01, 1.0, 1.0, 1.0, 50.0])
    clipped = collapse_weights(attention, 16.0)
    assert clipped.max() / clipped.min() == pytest.approx(16.0)
    assert clipped[2] == 1.0 and clipped[0] == pytest.approx(0.25) and clipped[-1] == pytest.approx(4.0)
    unclipped = collapse_weights(attention, float("inf"))
    assert (unclipped > 0).all() and unclipped[-1] == 50.0
    with pytest.raises(ValueError, match="density_range"):
        SegmentConfig(density_range=0.5)


def test_combine_rules_weigh_the_levels_as_documented(model, shapes):
    from anseg.hierarchy import upsample_through
    from anseg.pipeline import class_probabilities, model_inputs

    levels = build_levels(shapes[4].mesh, model, FAST)
    per_level = []
    with torch.no_grad():
        for index, level in enumerate(levels):
            probs = torch.softmax(model(**model_inputs(model, level, index, len(levels), "cpu")).logits, 1).double().numpy()
            records = [lv.record for lv in levels[:index]]  # by hand, as Hierarchy.upsample should
            per_level.append(upsample_through(records, probs) if records else probs)
    expected = {"coarsest": per_level[-1], "all": np.mean(per_level, axis=0),
                "decay": np.average(per_level, axis=0, weights=[1.0, 0.5, 0.25])}
    for rule, want in expected.items():
        np.testing.assert_allclose(class_probabilities(model, levels, replace(FAST, combine=rule)), want, rtol=1e-5, atol=1e-7)


def test_passes_average_the_probabilities_of_segmentations_with_other_seeds(model, shapes):
    from anseg.pipeline import PASS_SEED_STEP

    mesh = shapes[4].mesh
    single = [segment(mesh, model, replace(FAST, seed=i * PASS_SEED_STEP)).probabilities for i in range(2)]
    assert not np.allclose(single[0], single[1])  # another seed, other tokens: the passes differ
    ensemble = segment(mesh, model, replace(FAST, passes=2))
    np.testing.assert_allclose(ensemble.probabilities, (single[0] + single[1]) / 2, rtol=1e-12)
    assert np.array_equal(ensemble.unsmoothed_labels, ensemble.probabilities.argmax(axis=1))


def test_an_ensemble_averages_its_models_probabilities(model, shapes):
    other = fit(shapes[:3], shapes[0].label_names, FAST, TrainConfig(epochs=2, width=32, seed=1), progress=False)
    mesh = shapes[4].mesh
    alone = [segment(mesh, m, FAST).probabilities for m in (model, other)]
    assert not np.allclose(alone[0], alone[1])
    together = segment(mesh, model, FAST, ensemble=(other,))
    np.testing.assert_allclose(together.probabilities, (alone[0] + alone[1]) / 2, rtol=1e-12)
    assert np.array_equal(together.unsmoothed_labels, together.probabilities.argmax(axis=1))
    with pytest.raises(ValueError, match="share their classes"):
        segment(mesh, model, FAST, ensemble=(fit(shapes[:3], shapes[0].label_names, replace(FAST, groups=("edge",)),
                                                 TrainConfig(epochs=1, width=32), progress=False),))


def test_every_level_gets_labels_and_attention(model, shapes):
    from anseg.pipeline import fill_attention

    item = shapes[4]
    levels = build_levels(item.mesh, model, replace(FAST, mode="uniform"))
    assert all(level.attention is None for level in levels)  # a uniform collapse asks the model for nothing
    assert fill_attention(model, levels) is levels
    assert all(level.attention.shape == (level.mesh.n_faces,) for level in levels)
    labels = levels.labels_on_every_level(item.labels, model.n_classes)
    assert labels[0] is item.labels and [len(x) for x in labels] == [level.mesh.n_faces for level in levels]
    # a coarse face takes the area majority of the input faces it stands for: most of the area keeps its label
    back = labels[-1][levels.input_to_level(len(levels) - 1)]
    assert item.mesh.face_areas[back == item.labels].sum() > 0.8 * item.mesh.face_areas.sum()


def test_a_canonical_segmentation_does_not_hang_on_the_pose_the_file_order_or_the_orientation(model, shapes):
    from scipy.spatial.transform import Rotation

    mesh = shapes[0].mesh
    config = replace(model.config, canonical=True)
    base = segment(mesh, model, config)
    order = np.random.default_rng(2).permutation(mesh.n_faces)
    shuffled = segment(Mesh(mesh.vertices, mesh.faces[order]), model, config)
    assert np.array_equal(shuffled.labels, base.labels[order])
    assert np.allclose(shuffled.probabilities, base.probabilities[order])
    for moved in (Mesh(mesh.vertices, mesh.faces[:, ::-1]),
                  Mesh(Rotation.random(random_state=1).apply(mesh.vertices) * 30.0 + 7.0, mesh.faces),
                  Mesh(mesh.vertices * [1.0, -1.0, 1.0], mesh.faces[:, ::-1])):
        assert np.array_equal(segment(moved, model, config).labels, base.labels)
    # the levels come back in the input's pose, their faces in the canonical order, which level_faces leads back from
    assert np.allclose(base.levels[0].mesh.face_centroids, mesh.face_centroids[base.level_faces], atol=1e-5)
    assert not np.array_equal(base.level_faces, np.arange(mesh.n_faces))


def test_a_speck_far_from_the_shape_leaves_its_features_and_labels(model, shapes):
    """A stray facet sets no range of the shape's descriptors (before, agd_rel of the shape was squeezed towards 1) and
    changes none of its labels (before, they could all change)."""
    from anseg import features

    mesh = shapes[0].mesh
    far = mesh.vertices.max(axis=0) + 10.0
    speck = Mesh(np.vstack([mesh.vertices, far, far + [1e-3, 0, 0], far + [0, 1e-3, 0]]),
                 np.vstack([mesh.faces, [[mesh.n_vertices, mesh.n_vertices + 1, mesh.n_vertices + 2]]]))
    alone, beside = (features.compute(m, groups=model.config.groups, cache=False) for m in (mesh, speck))
    assert np.allclose(beside[: mesh.n_faces], alone, rtol=1e-5, atol=1e-6)
    # the shape is segmented as it is alone, and the speck takes the label of the shape's face nearest to it
    result, alone = segment(speck, model), segment(mesh, model)
    assert np.array_equal(result.labels[: mesh.n_faces], alone.labels)
    nearest = np.argmin(np.linalg.norm(mesh.face_centroids - speck.face_centroids[-1], axis=1))
    assert result.labels[-1] == alone.labels[nearest]
    assert np.array_equal(result.on_levels(result.labels), alone.on_levels(alone.labels))  # the levels are the shape's
