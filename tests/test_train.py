"""Training: it learns (above chance and above a features-only baseline), it resumes, it is deterministic."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pytest
import torch
from sklearn.linear_model import LogisticRegression

from anseg import datasets, features
from anseg.configs import configuration
from anseg.hierarchy import pool
from anseg.metrics import pooled_accuracy
from anseg.pipeline import SegmentConfig
from anseg.study.store import Experiment
from anseg.train import TrainConfig, evaluate, feature_statistics, fit, fit_and_time

SMALL = SegmentConfig(cycles=2, clusters=4, patch_size=16)


@pytest.fixture(scope="module")
def split():
    torch.set_num_threads(1)  # two threads on a loaded 2-core machine run slower than one
    load = dict(category="figure", n_shapes=8, progress=False)
    return datasets.load("synthetic", split="train", **load), datasets.load("synthetic", split="test", **load)


def logistic_baseline(train_set, test_set) -> float:
    """Logistic regression on the same per-face features, scored like the model (unit-area Eq. 5)."""
    x_train = np.concatenate([features.compute(m.mesh) for m in train_set])
    mean, std = x_train.mean(0), x_train.std(0) + 1e-6
    classifier = LogisticRegression(max_iter=1000).fit((x_train - mean) / std, np.concatenate([m.labels for m in train_set]))
    predicted = [classifier.predict((features.compute(m.mesh) - mean) / std) for m in test_set]
    return pooled_accuracy(predicted, [m.labels for m in test_set], [m.mesh.face_areas for m in test_set])["unit_area"]


@pytest.mark.slow
def test_learns_above_chance_and_above_the_features_only_baseline(split):
    train_set, test_set = split
    model = fit(train_set, train_set[0].label_names, SMALL, TrainConfig(epochs=60), progress=False)
    ours = evaluate(model, test_set, progress=False)["smoothed"]["unit_area"]
    baseline = logistic_baseline(train_set, test_set)
    chance = 1.0 / len(train_set[0].label_names)
    assert ours > 3 * chance
    assert ours > baseline, f"ours {ours:.3f} vs logistic regression {baseline:.3f}"


def test_deterministic_for_a_seed(split):
    train_set, _ = split
    run = lambda: fit(train_set[:2], train_set[0].label_names, SMALL, TrainConfig(epochs=1, width=16), progress=False)
    first, second = run(), run()
    for a, b in zip(first.network.parameters(), second.network.parameters()):
        assert torch.equal(a, b)


def test_resumes_from_a_checkpoint(split, tmp_path):
    train_set, _ = split
    names, checkpoint = train_set[0].label_names, tmp_path / "run.ckpt"
    fit(train_set[:2], names, SMALL, TrainConfig(epochs=2, width=16), checkpoint=checkpoint, progress=False)
    assert torch.load(checkpoint, weights_only=True)["epoch"] == 2
    straight = fit(train_set[:2], names, SMALL, TrainConfig(epochs=2, width=16), progress=False)
    # the same settings find the finished checkpoint: nothing left to train, same weights as a straight run
    resumed = fit(train_set[:2], names, SMALL, TrainConfig(epochs=2, width=16), checkpoint=checkpoint, progress=False)
    for a, b in zip(straight.network.parameters(), resumed.network.parameters()):
        assert torch.equal(a, b)
    # other settings ignore it
    other = TrainConfig(epochs=1, width=16, seed=5)
    assert fit(train_set[:2], names, SMALL, other, checkpoint=checkpoint, progress=False) is not None
    assert torch.load(checkpoint, weights_only=True)["epoch"] == 1


def test_a_resumed_run_counts_the_seconds_of_the_sessions_before(split, tmp_path):
    train_set, _ = split
    names, checkpoint, settings = train_set[0].label_names, tmp_path / "run.ckpt", TrainConfig(epochs=1, width=16)
    _, seconds, cpu_seconds = fit_and_time(train_set[:2], names, SMALL, settings, checkpoint=checkpoint, progress=False)
    carried = torch.load(checkpoint, weights_only=True)["seconds_spent"]
    assert 0 < carried[0] <= seconds and 0 < carried[1] <= cpu_seconds
    # as if the finished epoch had taken an hour of an earlier session: the resumed run adds it
    payload = torch.load(checkpoint, weights_only=True)
    payload["seconds_spent"] = [3600.0, 1800.0]
    torch.save(payload, checkpoint)
    started = time.time()
    _, resumed, resumed_cpu = fit_and_time(train_set[:2], names, SMALL, settings, checkpoint=checkpoint, progress=False)
    assert 3600.0 < resumed <= 3600.0 + time.time() - started
    assert 1800.0 < resumed_cpu


def test_average_last_keeps_the_mean_of_the_last_epochs_weights(split):
    train_set, _ = split
    run = lambda **kw: fit(train_set[:2], train_set[0].label_names, SMALL, TrainConfig(width=16, **{"average_last": 0, **kw}),
                           progress=False)
    # at a constant rate a 2-epoch run is the first two epochs of a 3-epoch one
    second, third = run(epochs=2), run(epochs=3)
    averaged = run(epochs=3, average_last=2)
    for a, b, mean in zip(second.network.parameters(), third.network.parameters(), averaged.network.parameters()):
        torch.testing.assert_close(mean, (a.double() + b.double()).div(2).float(), rtol=0, atol=1e-7)
    for a, b in zip(third.network.parameters(), run(epochs=3, average_last=1).network.parameters()):
        assert torch.equal(a, b)
    for a, b in zip(run(epochs=2, average_last=5).network.parameters(), run(epochs=2, average_last=2).network.parameters()):
        assert torch.equal(a, b)  # a run shorter than average_last averages all its epochs
    with pytest.raises(ValueError, match="average_last"):
        TrainConfig(average_last=-1)


def test_feature_statistics_leave_the_level_column():
    groups = [{"a": np.array([[1.0, 2.0], [3.0, 2.0]])}]
    mean, std = feature_statistics(groups)
    assert mean.tolist() == [2.0, 2.0, 0.0]
    assert std[0] == pytest.approx(1.0) and std[1] == pytest.approx(1e-6) and std[2] == 1.0


def test_rejects_empty_training_set():
    with pytest.raises(ValueError, match="no training meshes"):
        fit([], ["a"], SMALL)


def _v1_human() -> Experiment:
    segment, train = configuration("v1")
    return Experiment("psb", "Human", 0, segment, replace(train, epochs=60, seed=0, device="auto"))


def test_experiment_keys_of_committed_results_stay_put():
    # results/runs/b1e98aa45e21a4b6.json is Table IV's nonuniform Human run, trained with the v1 defaults:
    # a key change would orphan it (and the new defaults are a new experiment, on purpose)
    experiment = _v1_human()
    assert experiment.key() == "b1e98aa45e21a4b6"
    assert Experiment("psb", "Human", 0, SegmentConfig(), TrainConfig(epochs=60, seed=0)).key() != experiment.key()
    changed = Experiment("psb", "Human", 0, SegmentConfig(once_per_pass=True), experiment.train)
    assert changed.key() != experiment.key()
    assert Experiment("psb", "Human", 1, experiment.segment, experiment.train).key() != experiment.key()


def test_trained_on_names_the_gpu_or_the_cpu_model_and_count():
    from anseg.study.store import trained_on

    assert trained_on({"environment": {"cuda": "NVIDIA H100 80GB HBM3", "cpus": 16}}) == "NVIDIA H100 80GB HBM3"
    assert trained_on({"environment": {"cuda": None, "cpus": 2, "cpu_model": "AMD EPYC 9R14"}}) == "AMD EPYC 9R14, 2 cores"
    # a record from before the model was kept
    assert trained_on({"environment": {"cuda": None, "cpus": 2}}) == "CPU, 2 cores"
    assert trained_on({"environment": {"cuda": None, "cpus": 2, "cpu_model": "AMD EPYC", "kernels": {"pin": "avx2-1"}}}) \
        == "AMD EPYC, 2 cores, kernels avx2-1"


def test_the_environment_names_the_cpu_model(monkeypatch, tmp_path):
    from anseg import kernels
    from anseg.study import store

    assert store.environment()["cpu_model"] == store.cpu_model() != ""
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nmodel name\t: Intel(R) Xeon(R) Processor\nflags\t\t: avx512f\n")
    real_path = kernels.Path
    monkeypatch.setattr(kernels, "Path", lambda p: cpuinfo if p == "/proc/cpuinfo" else real_path(p))
    assert store.cpu_model() == "Intel(R) Xeon(R) Processor"
    assert kernels.cpu_flags() == {"avx512f"}
    monkeypatch.setattr(kernels, "Path", lambda p: tmp_path / "absent")
    assert store.cpu_model() == (store.platform.processor() or store.platform.machine())


def test_settings_added_later_change_the_key_only_away_from_their_old_value():
    # at the old value they stay out of the key (the pinned key above); any other value is a new experiment
    base = _v1_human()
    assert replace(base, segment=replace(base.segment, local_scale="relative")).key() != base.key()
    assert replace(base, train=replace(base.train, embed_norm=True)).key() != base.key()


def test_depth_zero_trains_only_without_downsampling(split):
    train_set, _ = split
    with pytest.raises(ValueError, match="needs mode 'none'"):
        fit(train_set, train_set[0].label_names, SMALL, TrainConfig(depth=0, epochs=1), progress=False)
    model = fit(train_set[:2], train_set[0].label_names, replace(SMALL, mode="none"),
                TrainConfig(depth=0, epochs=1), progress=False)
    assert len(model.network.blocks) == 0


def test_learning_rate_schedules():
    from anseg.train import learning_rate

    constant, cosine = TrainConfig(lr=0.01), TrainConfig(lr=0.01, schedule="cosine")
    assert [learning_rate(constant, s, 10) for s in (0, 9)] == [0.01, 0.01]
    assert learning_rate(cosine, 0, 10) == 0.01 and learning_rate(cosine, 5, 10) == pytest.approx(0.005)
    assert 0 < learning_rate(cosine, 9, 10) < 0.0003
    with pytest.raises(ValueError, match="schedule"):
        TrainConfig(schedule="step")


def test_attention_loss_is_class_balanced_and_silent_without_a_boundary():
    from anseg.train import _attention_loss

    band = torch.tensor([1.0, 0.0, 0.0, 0.0])
    high_at_band = _attention_loss(torch.tensor([3.0, 0.5, 0.5, 0.5]), band)
    low_at_band = _attention_loss(torch.tensor([0.5, 3.0, 3.0, 3.0]), band)
    assert 0 < high_at_band < low_at_band
    attention = torch.tensor([1.0, 1.0, 1.0, 1.0], requires_grad=True)
    _attention_loss(attention, band).backward()
    assert attention.grad[0] < 0 < attention.grad[1]  # pushes the band up, the rest down
    for flat in (torch.zeros(4), torch.ones(4)):
        assert _attention_loss(torch.ones(4), flat) == 0


def test_a_change_of_feature_code_changes_every_key(monkeypatch):
    from functools import partial

    from anseg import features

    base = _v1_human()
    monkeypatch.setattr(features, "FEATURES_VERSION", features.FEATURES_VERSION + 1)
    assert base.key() != "b1e98aa45e21a4b6"
    monkeypatch.undo()
    assert base.key() == "b1e98aa45e21a4b6"
    monkeypatch.setattr(features, "FeatureSettings", partial(features.FeatureSettings, sdf_rays=24))
    assert base.key() != "b1e98aa45e21a4b6"
    monkeypatch.undo()
    monkeypatch.setitem(features.GROUP_VERSIONS, "sdf", 2)
    assert base.key() != "b1e98aa45e21a4b6"


def test_only_attention_makes_a_rebuild(split, monkeypatch):
    """A uniform hierarchy is built once; a nonuniform rebuild re-clusters the coarse levels, not the input level."""
    import anseg.pipeline as pipeline
    import anseg.train as train_module

    train_set, _ = split
    built, clustered = [], []
    real_examples, real_layout = train_module._examples, pipeline.layout
    monkeypatch.setattr(train_module, "_examples", lambda *a, **k: built.append(1) or real_examples(*a, **k))
    monkeypatch.setattr(pipeline, "layout", lambda mesh, *a, **k: clustered.append(mesh.n_faces) or real_layout(mesh, *a, **k))
    settings = TrainConfig(epochs=3, recollapse_every=1, width=16, depth=1)
    fit(train_set[:2], train_set[0].label_names, replace(SMALL, mode="uniform"), settings, progress=False)
    assert len(built) == 2
    built.clear(), clustered.clear()
    fit(train_set[:2], train_set[0].label_names, SMALL, settings, progress=False)
    assert len(built) == 6
    input_sizes = {m.mesh.n_faces for m in train_set[:2]}
    assert sum(n in input_sizes for n in clustered) == 2  # the input levels were clustered at the first build only


def test_new_layouts_lay_out_every_level_again_at_every_rebuild_with_another_seed(split, monkeypatch):
    import anseg.pipeline as pipeline

    train_set, _ = split
    seeds = []
    real_layout = pipeline.layout
    monkeypatch.setattr(pipeline, "layout", lambda mesh, *a, **k: seeds.append((mesh.n_faces, k["seed"], k["frame"]))
                        or real_layout(mesh, *a, **k))
    config = replace(SMALL, mode="uniform", layout_frame="random")
    fit(train_set[:1], train_set[0].label_names, config, TrainConfig(epochs=3, recollapse_every=1, width=16, depth=1,
                                                                     new_layouts=True), progress=False)
    on_input = [seed for n, seed, frame in seeds if n == train_set[0].mesh.n_faces]
    assert len(on_input) == 3 and len(set(on_input)) == 3  # a uniform hierarchy too, built again with a new seed each time
    assert {frame for *_, frame in seeds} == {"random"}


def test_spatial_context_trains_and_carries_the_eigenbasis_to_every_level(split):
    from anseg.pipeline import segment

    train_set, test_set = split
    model = fit(train_set[:2], train_set[0].label_names, SMALL,
                TrainConfig(diffusion_blocks=1, epochs=2, width=16, depth=1), progress=False)
    assert model.network.config.spectral_pairs == 64 and len(model.network.diffusion) == 1
    result = segment(test_set[0].mesh, model)
    assert result.labels.shape == (test_set[0].mesh.n_faces,)
    levels = result.levels
    for fine, coarse in zip(levels, levels[1:]):
        assert coarse.spectrum.basis.shape == (coarse.mesh.n_faces, 64)
        expected = pool(fine.record, fine.spectrum.basis, fine.mesh.face_areas)
        np.testing.assert_allclose(coarse.spectrum.basis, expected, rtol=1e-5, atol=1e-6)


def test_gradient_features_train_and_segment(split, tmp_path):
    from anseg.pipeline import Segmenter, segment

    train_set, test_set = split
    model = fit(train_set[:2], train_set[0].label_names, SMALL,
                TrainConfig(diffusion_blocks=1, diffusion_gradients=True, epochs=2, width=16, depth=1), progress=False)
    assert model.network.diffusion[0].rotate is not None
    labels = segment(test_set[0].mesh, model).labels
    model.save(tmp_path / "model.pt")
    assert np.array_equal(segment(test_set[0].mesh, Segmenter.load(tmp_path / "model.pt")).labels, labels)
    with pytest.raises(ValueError, match="diffusion_gradients need diffusion blocks"):
        fit(train_set[:2], train_set[0].label_names, SMALL, TrainConfig(diffusion_blocks=0, diffusion_gradients=True, epochs=1),
            progress=False)


def test_spatial_context_switches_leave_the_keys_alone_at_zero():
    base = _v1_human()
    assert replace(base, train=replace(base.train, diffusion_blocks=0)).key() == base.key()
    assert replace(base, train=replace(base.train, diffusion_blocks=1)).key() != base.key()


@pytest.mark.parametrize("canonical", [False, True])
def test_evaluate_scores_match_an_independent_count(split, canonical):
    from anseg.pipeline import segment

    train_set, test_set = split
    config = replace(SMALL, canonical=canonical, layout_frame="principal" if canonical else SMALL.layout_frame)
    model = fit(train_set[:2], train_set[0].label_names, config, TrainConfig(epochs=1, width=16, depth=1),
                progress=False)
    scores = evaluate(model, test_set[:2], progress=False)
    results = [segment(m.mesh, model) for m in test_set[:2]]
    for item, result, per_mesh in zip(test_set, results, scores["per_mesh"]):
        right = item.mesh.face_areas[result.labels == item.labels].sum()
        assert per_mesh["accuracy"] == pytest.approx(right / item.mesh.face_areas.sum())
    # Eq. 5 with unit area: every mesh weighs the same, each face by its share of its mesh's area
    for key, chosen in (("smoothed", [r.labels for r in results]), ("unsmoothed", [r.unsmoothed_labels for r in results])):
        shares = [float(m.mesh.face_areas[c == m.labels].sum() / m.mesh.face_areas.sum()) for m, c in zip(test_set, chosen)]
        assert scores[key]["unit_area"] == pytest.approx(np.mean(shares))
        faces = sum(int((c == m.labels).sum()) for m, c in zip(test_set, chosen)) / sum(m.mesh.n_faces for m in test_set[:2])
        assert scores[key]["faces"] == pytest.approx(faces)
