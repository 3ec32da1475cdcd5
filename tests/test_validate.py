"""Validation: folds of training meshes only, keyed and resumable cells, the paired comparison."""

from __future__ import annotations

import json
from functools import partialmethod

import numpy as np
import pytest
import torch

from anseg.configs import parse_overrides
from anseg.pipeline import SegmentConfig
from anseg.study import comparison, validate
from anseg.study.comparison import paired_difference
from anseg.study.store import Experiment
from anseg.study.validate import Arm, Cell, fold_of

SMALL = {"cycles": 2, "clusters": 4}
SYNTHETIC = dict(dataset="synthetic", options=(("n_shapes", 8),))


def test_overrides_are_typed_like_the_defaults():
    segment, train = parse_overrides("once_per_pass=true,ratio=0.4,groups=edge+sdf,train.width=128")
    assert segment == {"once_per_pass": True, "ratio": 0.4, "groups": ("edge", "sdf")}
    assert train == {"width": 128}
    with pytest.raises(ValueError, match="unknown setting"):
        parse_overrides("no_such_field=1")
    with pytest.raises(ValueError, match="not a int"):
        parse_overrides("train.width=wide")
    assert Arm.parse("default") == Arm("default")


def test_an_arm_named_config_slash_variant_starts_from_that_configuration():
    plain, variant = Arm.parse("paper"), Arm.parse("paper/weighted:priority=weighted")
    assert variant.name == "paper/weighted" and plain.segment["priority"] == "score"
    assert variant.segment == {**plain.segment, "priority": "weighted"}
    assert variant.train == plain.train and plain.train["attention_weight"] == 0.0
    assert Arm.parse("other/weighted:priority=weighted").segment == {"priority": "weighted"}


def test_folds_partition_the_training_meshes():
    fold = fold_of(12, 3)
    assert np.bincount(fold).tolist() == [4, 4, 4]
    with pytest.raises(ValueError):
        fold_of(12, 1)


def test_keys_separate_cells_and_inference_settings_share_a_model():
    base = Cell(Arm("default"), "Human", fold=0, seed=0)
    assert base.key() != Cell(Arm("default"), "Human", fold=1, seed=0).key()
    assert base.key() != Cell(Arm("default"), "Human", fold=0, seed=1).key()
    segment, train = base.configs()
    assert base.key() != Experiment("psb", "Human", 0, segment, train).key()  # never a table experiment's key
    cut = Cell(Arm("cut", {"smooth_weight": 3.0}), "Human", fold=0, seed=0)
    assert cut.key() != base.key() and cut.training_key() == base.training_key()
    wide = Cell(Arm("wide", train={"width": 128}), "Human", fold=0, seed=0)
    assert wide.training_key() != base.training_key()


def test_a_model_key_does_not_move_with_the_inference_defaults(monkeypatch):
    # a new default graph-cut weight must leave the stored models found, not orphan them
    cell = Cell(Arm("cut", {"smooth_weight": 2.0}), "Human", fold=0, seed=0)
    before = cell.training_key()
    monkeypatch.setattr(SegmentConfig, "__init__", partialmethod(SegmentConfig.__init__, smooth_weight=2.0))
    assert SegmentConfig().smooth_weight == 2.0
    assert cell.training_key() == before


def test_paired_difference_and_its_interval():
    table = {}
    for c, category in enumerate(["A", "B", "C"]):
        for fold in range(3):
            for seed in range(2):
                table[("base", category, fold, seed)] = 80.0 + c
                table[("plus", category, fold, seed)] = 82.0 + c
                table[("mixed", category, fold, seed)] = 80.0 + c + (1.0 if fold == 0 else -0.5)
    plus = paired_difference(table, "plus", "base", samples=500)
    assert plus["mean"] == pytest.approx(2.0) and plus["low"] == pytest.approx(2.0) and plus["high"] == pytest.approx(2.0)
    assert plus["categories"] == 3 and plus["cells"] == 9
    mixed = paired_difference(table, "mixed", "base", samples=2000)
    assert mixed["mean"] == pytest.approx(0.0)
    assert mixed["low"] < 0 < mixed["high"]
    assert np.isnan(paired_difference(table, "absent", "base")["mean"])


def test_report_names_the_verdict(tmp_path):
    results = [{"arm": arm, "category": cat, "fold": f, "seed": 0, "accuracy": {"unit_area": (70 + bonus + f) / 100}}
               for arm, bonus in (("default", 0), ("better", 3)) for cat in ("A", "B") for f in range(3)]
    text = comparison.write_report(results, "default", tmp_path, "demo")
    assert "better" in text and "no verdict on fewer than 3 categories" in text and "one seed" in text
    rows = (tmp_path / "demo_accuracy.csv").read_text().splitlines()
    assert rows[0] == "arm,category,mean,std,runs,train_mean"
    assert "default,suite mean,71.0000,1.0000,6,nan" in rows  # folds score 70, 71, 72: mean 71, spread 1; no fit recorded
    assert (tmp_path / "demo_paired.csv").is_file()
    more = [{**r, "category": f"{r['category']}{k}"} for r in results for k in range(2)]  # 4 categories
    assert "adopt" in comparison.write_report(more, "default", tmp_path, "demo4")


def test_report_sets_the_fit_on_training_meshes_beside_the_held_out_accuracy(tmp_path):
    results = [{"arm": "default", "category": cat, "fold": f, "seed": 0, "accuracy": {"unit_area": 0.8},
                "train_accuracy": {"unit_area": fit}} for cat, fit in (("A", 0.9), ("B", 0.99)) for f in range(3)]
    text = comparison.write_report(results, "default", tmp_path, "fit")
    assert "on its training meshes" in text
    rows = (tmp_path / "fit_accuracy.csv").read_text().splitlines()
    assert "default,A,80.0000,0.0000,3,90.0000" in rows and "default,suite mean,80.0000,0.0000,6,94.5000" in rows


def test_training_cost_compares_cpu_seconds_on_the_cells_both_trained(tmp_path):
    def result(arm, category, cpu, trained=True):
        return {"arm": arm, "category": category, "fold": 0, "seed": 0, "accuracy": {"unit_area": 0.8},
                "trained": trained, "train_cpu_seconds": cpu}

    results = [result("default", "A", 100.0), result("default", "B", 300.0), result("cheap", "A", 30.0),
               result("cheap", "B", 90.0), result("cheap", "C", 5.0),  # C: no baseline cell, left out
               result("cut", "A", 1.0, trained=False)]  # scored with a stored model: no training to count
    assert comparison.training_cost(results, "cheap", "default") == pytest.approx(0.3)
    assert np.isnan(comparison.training_cost(results, "cut", "default"))
    older = [{k: v for k, v in r.items() if k != "train_cpu_seconds"} for r in results]  # stored before CPU time was
    assert np.isnan(comparison.training_cost(older, "cheap", "default"))
    text = comparison.write_report(results, "default", tmp_path, "cost")
    assert "training costs 0.30x the baseline's CPU time" in text
    header = (tmp_path / "cost_paired.csv").read_text().splitlines()[0]
    assert header.endswith(",cost,revisions,baseline_revisions,purpose,verdict")


def test_the_report_says_when_the_arms_ran_other_code_revisions(tmp_path):
    def result(arm, category, revision, clean=True):
        return {"arm": arm, "category": category, "fold": 0, "seed": 0, "accuracy": {"unit_area": 0.8},
                "environment": {"code_revision": revision, "code_clean": clean}}

    same = [result(arm, c, "aaaaaaa1111") for arm in ("default", "new") for c in "ABC"]
    assert "trained at" not in comparison.write_report(same, "default", tmp_path, "same")
    mixed = same[:3] + [result("new", "A", "bbbbbbb2222"), result("new", "B", "aaaaaaa1111", clean=False),
                        result("new", "C", "aaaaaaa1111")]
    text = comparison.write_report(mixed, "default", tmp_path, "mixed")
    assert "trained at aaaaaaa aaaaaaa+ bbbbbbb, the baseline at aaaaaaa" in text
    row = (tmp_path / "mixed_paired.csv").read_text().splitlines()[1]
    assert row.endswith(",aaaaaaa aaaaaaa+ bbbbbbb,aaaaaaa,accuracy,no evidence")


def test_seed_spread_reads_each_cell_across_its_seeds(tmp_path):
    # cell (A, 0) moves by 4 from seed 0 to 1, (A, 1) by 2, (B, 0) by 0
    values = {("A", 0): (70, 74), ("A", 1): (80, 82), ("B", 0): (77, 77)}
    results = [{"arm": "default", "category": c, "fold": f, "seed": s, "accuracy": {"unit_area": v[s] / 100}}
               for (c, f), v in values.items() for s in (0, 1)]
    # one seed: left out
    results.append({"arm": "default", "category": "B", "fold": 1, "seed": 0, "accuracy": {"unit_area": 0.1}})
    (row,) = comparison.seed_spread(comparison.accuracy_table(results))
    assert row["cells"] == 3 and row["seeds"] == 2
    assert row["median_range"] == pytest.approx(2.0) and row["max_range"] == pytest.approx(4.0)
    assert row["suite_mean_range"] == pytest.approx(1.5)  # A: 75 then 78, B: 77 then 77 -> 76.0 and 77.5
    text = comparison.write_report(results, "default", tmp_path, "seeds")
    assert "from seed to seed" in text and (tmp_path / "seeds_seeds.csv").is_file()
    assert comparison.seed_spread(comparison.accuracy_table([r for r in results if r["seed"] == 0])) == []


@pytest.mark.slow
def test_a_study_stores_its_cells_and_resumes_without_training(tmp_path, monkeypatch):
    torch.set_num_threads(1)
    arms = [Arm("default", SMALL), Arm("no-cut", {**SMALL, "smooth_weight": 0.0})]
    cells = validate.study_cells(arms, ["figure"], folds=2, use_folds=[0], seeds=[0], epochs=2, **SYNTHETIC)
    assert [c.arm.name for c in cells] == ["default", "no-cut"]
    fits = []
    real_fit = validate.fit_and_time
    monkeypatch.setattr(validate, "fit_and_time", lambda *a, **k: fits.append(1) or real_fit(*a, **k))
    results = validate.run_study(cells, tmp_path, progress=False)
    assert len(results) == 2 and len(fits) == 1  # the inference-only arm reused the trained model
    assert [r["trained"] for r in results] == [True, False]
    assert not set(results[0]["held_out"]) & set(results[0]["train_meshes"])
    assert len(list((tmp_path / "runs").glob("*.json"))) == 2
    again = validate.run_study(cells, tmp_path, progress=False)
    assert len(fits) == 1 and [r["key"] for r in again] == [r["key"] for r in results]
    seed_one = validate.study_cells(arms, ["figure"], folds=2, use_folds=[0], seeds=[1], epochs=2, **SYNTHETIC)
    assert validate.run_study(seed_one, tmp_path, progress=False, train=False) == [] and len(fits) == 1


@pytest.mark.slow
def test_an_ensemble_scores_the_seeds_models_together_and_is_stored(tmp_path):
    torch.set_num_threads(1)
    cells = validate.study_cells([Arm("default", SMALL)], ["figure"], folds=2, use_folds=[0], seeds=[0, 1], epochs=2,
                                 **SYNTHETIC)
    assert validate.run_ensembles(cells, tmp_path, progress=False) == []  # no model stored yet: nothing scored
    results = validate.run_study(cells, tmp_path, progress=False)
    (ensemble,) = validate.run_ensembles(cells, tmp_path, progress=False)
    assert ensemble["seeds"] == [0, 1] and ensemble["held_out"] == results[0]["held_out"]
    assert (tmp_path / "ensembles" / f"{ensemble['key']}.json").is_file()
    assert validate.run_ensembles(cells, tmp_path, progress=False) == [ensemble]  # read back, not recomputed
    (alone,) = comparison.ensemble_comparisons([ensemble], results, "default")  # the baseline itself: one row
    singles = np.mean([100 * r["accuracy"]["unit_area"] for r in results])
    assert alone["arm"] == "default x2" and alone["cells"] == 1
    assert alone["mean"] == pytest.approx(100 * ensemble["accuracy"]["unit_area"] - singles)


def test_cli_refuses_bad_arms_in_one_line(capsys):
    with pytest.raises(SystemExit) as stop:
        validate.main(["--study", "x", "--arm", "a:train.width=wide"])
    assert stop.value.code == 2
    assert "train.width" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        validate.main(["--study", "x", "--arm", "a", "--arm", "a"])
    with pytest.raises(SystemExit):
        validate.main(["--study", "x", "--arm", "a", "--backend", "loky", "--scheduler", "tcp://host:8786"])
    assert "needs the dask backend" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        validate.main(["--study", "x", "--arm", "a", "--seeds", "0", "--ensemble"])
    assert "two seeds" in capsys.readouterr().err


@pytest.mark.realdata
def test_validation_never_reads_a_test_mesh(data_root, tmp_path, monkeypatch):
    from anseg.datasets import psb

    read = []
    real_read = psb.read_mesh
    monkeypatch.setattr(psb, "read_mesh", lambda path: read.append(path) or real_read(path))
    monkeypatch.setattr(validate, "fit_and_time", lambda *args, **kwargs: (_Stub(), 0.0, 0.0))
    monkeypatch.setattr(validate, "evaluate", lambda model, meshes, config, progress: _scores(meshes))
    cell = Cell(Arm("default"), "Vase", fold=1, seed=0)
    (result,) = validate.run_study([cell], tmp_path, root=data_root, progress=False)
    split = psb.psb_split("Vase", 0)
    ids = {int(p.stem) for p in read}
    assert ids == set(split["train"]) and not ids & set(split["test"])
    assert len(result["held_out"]) == 4 and len(result["train_meshes"]) == 8
    assert json.loads((tmp_path / "runs" / f"{cell.key()}.json").read_text())["held_out"] == result["held_out"]


class _Stub:
    def to_bytes(self):
        return b"a model"


def _scores(meshes):
    score = {"unit_area": 0.5, "raw_area": 0.5, "faces": 0.5}
    return {"smoothed": score, "unsmoothed": score, "per_mesh": [{"name": m.name} for m in meshes]}


def test_a_stored_cell_reads_back_under_the_arm_name_of_the_study(tmp_path, monkeypatch):
    """The key holds an arm's settings, not its name: a later study may call the same settings otherwise."""
    cell = validate.study_cells([Arm("first", SMALL)], ["figure"], folds=2, use_folds=[0], seeds=[0], epochs=2, **SYNTHETIC)[0]
    validate.validation_store(tmp_path).put({"key": cell.key(), "arm": "first", "trained": True})
    renamed = validate.study_cells([Arm("renamed", SMALL)], ["figure"], folds=2, use_folds=[0], seeds=[0], epochs=2,
                                   **SYNTHETIC)
    assert [r["arm"] for r in validate.read_results(tmp_path, renamed)] == ["renamed"]
    assert [r["arm"] for r in validate.run_study(renamed, tmp_path, progress=False)] == ["renamed"]


@pytest.mark.parametrize("low, high, purpose, expected", [
    (0.1, 2.0, "accuracy", "adopt"), (-0.1, 2.0, "accuracy", "no evidence"), (-2.0, -0.1, "accuracy", "worse"),
    (-0.15, 2.4, "fix", "adopt (non-inferior: lower end above -0.5)"), (-0.6, 2.0, "fix", "no evidence"),
    (-2.0, -0.6, "fix", "worse"), (-0.5, 1.0, "fix", "no evidence")])
def test_a_fix_of_a_defect_is_adopted_when_non_inferior_an_accuracy_lever_when_above_zero(low, high, purpose, expected):
    assert comparison.verdict({"low": low, "high": high, "categories": 9}, purpose) == expected
    assert comparison.verdict({"low": low, "high": high, "categories": 2}, purpose).startswith("no verdict")


def test_the_report_judges_the_arms_named_as_fixes_by_the_rule_for_fixes(tmp_path):
    results = [{"arm": arm, "category": f"C{c}", "fold": f, "seed": 0,
                "accuracy": {"unit_area": (80 + c + f + bonus[(c + f) % 3]) / 100}}
               for arm, bonus in (("default", (0, 0, 0)), ("pose", (-0.4, 0.1, 0.2))) for c in range(4) for f in range(3)]
    assert "accuracy: no evidence" in comparison.write_report(results, "default", tmp_path, "as-lever")
    assert "fix: adopt (non-inferior" in comparison.write_report(results, "default", tmp_path, "as-fix", ("pose",))
    paired = (tmp_path / "as-fix_paired.csv").read_text().splitlines()
    assert paired[0].endswith(",purpose,verdict") and ",fix,adopt (non-inferior" in paired[1]
