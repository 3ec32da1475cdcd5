"""The claims ledger: one rule for every row, checked on synthetic evidence (ties, wins, losses) and on the committed results."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from anseg import configs, datasets
from anseg.study import figure_effects, ledger, reference

RESULTS = Path(__file__).resolve().parent.parent / "results"
UNTESTABLE = {"COSEG accuracy", "Better than MeshCNN and Guo et al.", "Cost"}
CATEGORIES, SPLITS, MESHES = ("Airplane", "Human", "Teddy"), range(4), [f"Human/{i}" for i in range(8)]
ABLATION_RUNS = ("table4_ablation_runs.csv", "table4_every_category_runs.csv", "fig11_cycles_ratio.csv",
                 "fig12_features.csv")  # read two ways
ABLATION_CLAIMS = {"Downsampling order", "Order, every category", "More cycles help", "N = 4, ratio 0.5",
                   "All four feature groups"}
TWO_READINGS = ABLATION_CLAIMS | {"Attention at junctions", "Labels survive"}
HUMAN_PARAMETERS = {"dataset": "human_seg", "config": "default", "epochs": 60, "seed": 0, "device": "auto", "smoke": False,
                    "category": None, "output_dir": ".."}


@pytest.fixture
def results(tmp_path) -> Path:
    """A copy of the committed results that a test may change."""
    if not (RESULTS / "table1_psb.csv").is_file():
        pytest.skip("no committed results in this checkout")
    shutil.copytree(RESULTS, tmp_path / "results", ignore=shutil.ignore_patterns("runs"))
    return tmp_path / "results"


def verdicts(results: Path) -> pd.Series:
    return ledger.ledger(results).set_index("claim").verdict


# --- synthetic evidence: every row's arm against its baseline, with a chosen effect per unit -----------------------------

def unit_effect(favour: float, noise: float):
    """The effect in the claim's favour of a unit: ``favour`` plus noise symmetric around 0 (+1, -1, +2, -2 times ``noise``)."""
    pattern = (1.0, -1.0, 2.0, -2.0)
    return lambda index: favour + noise * pattern[index % 4]


def write_evidence(folder: Path, claim: str, favour: float, noise: float, papers_method: bool = True,
                   literal: float | None = None) -> Path:
    """Small result files with the columns of the real ones, in which ``claim``'s arm minus its baseline is the unit effect.

    Each (category, split) and each test mesh gets its own effect; every
    category and split has its own difficulty too, which the pairing cancels.
    With ``papers_method`` the ablations' runs of the paper's configuration
    (their literal reading) are written too, with the effect ``literal``
    (default: ``favour``, the two readings agree); Fig. 4's table holds both
    models, the paper's with ``literal`` too.
    """
    folder.mkdir(parents=True, exist_ok=True)
    if papers_method:
        write_ablations(folder, claim, unit_effect(favour if literal is None else literal, noise))
        for name in ABLATION_RUNS:
            (folder / name).rename(folder / ledger.papers_method_file(name))
    write_ablations(folder, claim, unit_effect(favour, noise), unit_effect(favour if literal is None else literal, noise))
    delta = unit_effect(favour, noise)
    units = [(c, s, delta(s + i)) for i, c in enumerate(CATEGORIES) for s in SPLITS]
    paper = reference.TABLE_I["methods"]["Ours (paper)"]
    best_peer = {c: max(reference.TABLE_I["methods"][p][c] for p in ("ShapePFCN", "MeshCNN", "MeshWalker")) for c in CATEGORIES}
    baseline = best_peer if claim == "PSB, best in most categories" else paper
    pd.DataFrame([{"category": c, "split": s, "unit_area": baseline[c] + d, "train_seconds": 300.0,
                   "evaluate_seconds_per_mesh": 0.5, "trained_on": "CPU, 2 cores", "key": f"{c}{s}"}
                  for c, s, d in units]).to_csv(folder / "table1_psb_runs.csv", index=False)
    pd.DataFrame({"ours, unit area": [97.0], "ours, faces": [96.0]},
                 index=pd.Index(["coseg_vases"], name="set")).to_csv(folder / "table2_coseg.csv")

    human = pd.Series({mesh: reference.TABLE_III["methods"]["Ours (paper)"] + delta(i) for i, mesh in enumerate(MESHES)})
    pd.DataFrame([{"method": "ours", "accuracy": round(human.mean(), 2), "metric": "Eq. 5, unit area (primary)",
                   "data": "human_seg", "source": "this run"}]).to_csv(folder / "table3_human.csv", index=False)
    (folder / "table3_human.json").write_text(json.dumps({"notebook": "table3_human", "parameters": HUMAN_PARAMETERS,
                                                           "configuration": "default"}))
    run = ledger._table3_run_path(folder)
    run.parent.mkdir(exist_ok=True)
    run.write_text(json.dumps({"key": run.stem, "n_train": 381, "n_test": len(MESHES),
                               "accuracy": {"unit_area": human.mean() / 100},
                               "per_mesh": [{"name": m, "faces": 1500, "accuracy": a / 100} for m, a in human.items()]}))
    return folder


def write_ablations(folder: Path, claim: str, delta, literal=None) -> None:
    """The ablations' runs tables (Table IV, Fig. 11, Fig. 12) with the unit effect ``delta``, and with ``literal``
    Fig. 4's table, the paper's model with that effect and ours with ``delta``."""
    units = [(c, s, delta(s + i)) for i, c in enumerate(CATEGORIES) for s in SPLITS]
    level = lambda c, s: 80.0 + 3 * CATEGORIES.index(c) + s  # a unit's own difficulty

    # Table IV: none, then uniform one effect above it, then nonuniform one effect above uniform
    pd.DataFrame([{"category": c, "split": s, "mode": mode, "unit_area": level(c, s) + steps * d}
                  for c, s, d in units for mode, steps in (("none", 0), ("uniform", 1), ("nonuniform", 2))]
                 ).to_csv(folder / "table4_ablation_runs.csv", index=False)
    # and on split 0 of every PSB category, one unit each
    pd.DataFrame([{"category": c, "split": 0, "mode": mode, "unit_area": 80.0 + i + steps * delta(i)}
                  for i, c in enumerate(datasets.PSB_CATEGORIES) for mode, steps in (("none", 0), ("uniform", 1),
                                                                                  ("nonuniform", 2))]
                 ).to_csv(folder / "table4_every_category_runs.csv", index=False)

    # Fig. 4: AUC 0.5 + effect on the coarse levels (in hundredths); labels kept, nonuniform = uniform + effect
    if literal is not None:
        of = {"ours": delta, "paper": literal}
        pd.DataFrame([{"model": who, "downsampling": mode, "mesh": mesh, "level": lv,
                       "attention AUC, near vs elsewhere": 0.5 + (lv > 0) * of[who](i) / 100,
                       "labels kept (%)": 100.0 - 3 * lv + (mode == "nonuniform") * (lv == 2) * of[who](i)}
                      for who in of for mode in ("uniform", "nonuniform") for i, mesh in enumerate(MESHES)
                      for lv in range(3)]).to_csv(folder / "fig4_test_meshes.csv", index=False)

    # Fig. 11: the compared point (N = 4 removing 0.5 against the best other, or N = 4 against N = 1) at 90 + effect
    choice = reference.FIG11_CHOICE
    grid = [(r, n) for r in (0.3, choice["removed"]) for n in (1, 2, choice["cycles"])]

    def fig11(r, n, d):
        if claim == "More cycles help":
            return 90.0 + d if n == choice["cycles"] else 90.0 if n == 1 else 85.0
        return 90.0 + d if (r, n) == (choice["removed"], choice["cycles"]) else 90.0 if (r, n) == (0.3, 2) else 85.0
    pd.DataFrame([{"category": c, "split": s, "removed": r, "cycles": n, "unit_area": fig11(r, n, d) + level(c, s) - 80}
                  for c, s, d in units for r, n in grid]).to_csv(folder / "fig11_cycles_ratio.csv", index=False)

    # Fig. 12: the full set one effect above the set without AGD, the two smaller sets far below
    sets = {"edge": -30.0, "edge+gc": -20.0, "edge+gc+sdf": 0.0, "configuration's own": 5.0}
    pd.DataFrame([{"category": c, "split": s, "features": f, "unit_area": level(c, s) + (d if f == "edge+gc+sdf+agd" else shift)}
                  for c, s, d in units for f, shift in {**sets, "edge+gc+sdf+agd": None}.items()]
                 ).to_csv(folder / "fig12_features.csv", index=False)


CASES = [pytest.param(0.0, 0.0, ledger.TIED, id="tie, identical numbers"),
         pytest.param(0.0, 1.0, ledger.TIED, id="tie, symmetric noise"),
         pytest.param(3.0, 1.0, ledger.REPRODUCED, id="clear win"),
         pytest.param(-3.0, 1.0, ledger.NOT_REPRODUCED, id="clear loss")]


@pytest.mark.parametrize("favour, noise, expected", CASES)
def test_every_row_reads_ties_wins_and_losses_by_the_one_rule(tmp_path, favour, noise, expected):
    """Both readings of the ablation rows given the same effect: they agree, and the row reads it."""
    for claim in ledger.CLAIMS:
        folder = write_evidence(tmp_path / claim.name.replace(" ", "_").replace(",", ""), claim.name, favour, noise)
        row = ledger.ledger(folder).set_index("claim").loc[claim.name]
        assert row.verdict == (ledger.UNTESTED if claim.name in UNTESTABLE else expected), (claim.name, row["our evidence"])
        if claim.name in TWO_READINGS:
            assert row["in short"].startswith("literal (`paper`): ") and "; strongest (" in row["in short"]


READINGS = [pytest.param(3.0, -3.0, ledger.DEPENDS, id="literal loses, strongest wins"),
            pytest.param(-3.0, 3.0, ledger.DEPENDS, id="literal wins, strongest loses"),
            pytest.param(0.0, 3.0, ledger.DEPENDS, id="literal wins, strongest ties"),
            pytest.param(3.0, 0.0, ledger.DEPENDS, id="literal ties, strongest wins"),
            pytest.param(-3.0, -3.0, ledger.NOT_REPRODUCED, id="both lose"),
            pytest.param(3.0, 3.0, ledger.REPRODUCED, id="both win")]


@pytest.mark.parametrize("strongest, literal, expected", READINGS)
def test_the_two_readings_agree_or_the_row_depends_on_the_reading(tmp_path, strongest, literal, expected):
    """Each reading judged by the one rule (a tie, a win or a loss each); the row reads them where they agree."""
    for claim in sorted(TWO_READINGS):
        folder = write_evidence(tmp_path / claim.replace(" ", "_").replace(",", ""), claim, strongest, 1.0,
                                literal=literal)
        row = ledger.ledger(folder).set_index("claim").loc[claim]
        assert row.verdict == expected, (claim, row["our evidence"])
        verdict = {3.0: ledger.REPRODUCED, 0.0: ledger.TIED, -3.0: ledger.NOT_REPRODUCED}
        literal_part, strongest_part = row["in short"].split("; strongest (")
        assert literal_part.endswith(f"({verdict[literal]})") and f"({verdict[strongest]})" in strongest_part, claim
        assert row.configuration == "paper"  # the synthetic folder holds no notebook record: the literal one named


def test_a_claim_of_several_parts_needs_every_part(tmp_path):
    assert ledger.combined(*[ledger.effect(pd.Series([1.0, 2.0, 3.0], name="x").rename_axis("mesh"), "a")] * 2) \
        == ledger.REPRODUCED
    folder = write_evidence(tmp_path, "Downsampling order", 3.0, 1.0)

    def change(name: str, how) -> None:  # both readings' runs alike, so that the readings agree
        for path in (folder / name, folder / ledger.papers_method_file(name)):
            runs = pd.read_csv(path)
            how(runs)
            runs.to_csv(path, index=False)

    def tie(runs):  # uniform ties none
        runs.loc[runs["mode"] == "uniform", "unit_area"] = runs.loc[runs["mode"] == "none", "unit_area"].to_numpy()

    change("table4_ablation_runs.csv", tie)
    assert verdicts(folder)["Downsampling order"] == ledger.TIED  # nonuniform > uniform, but uniform ties none
    change("table4_ablation_runs.csv", lambda runs: runs.__setitem__(  # uniform far above nonuniform: one part lost
        "unit_area", runs.unit_area + 12.0 * (runs["mode"] == "uniform")))
    assert verdicts(folder)["Downsampling order"] == ledger.NOT_REPRODUCED
    change("fig12_features.csv", lambda runs: runs.__setitem__(  # the smallest set now best: part one lost, AGD still adds
        "unit_area", runs.unit_area + 100.0 * (runs.features == "edge")))
    assert verdicts(folder)["All four feature groups"] == ledger.NOT_REPRODUCED


def test_the_ablations_need_both_readings_and_are_untested_without_the_literal_one(tmp_path):
    """Part of the literal reading's runs must not stand for all: without them the row judges nothing."""
    folder = write_evidence(tmp_path / "ours_only", "Downsampling order", 3.0, 1.0, papers_method=False)
    (folder / "table4_ablation.json").write_text(json.dumps({"notebook": "table4_ablation", "configuration": "default"}))
    table = ledger.ledger(folder).set_index("claim")
    for claim in ABLATION_CLAIMS:
        assert table.loc[claim, "verdict"] == ledger.UNTESTED, claim
        assert "the paper's method as written (paper configuration) not all run here yet" in table.loc[claim, "our evidence"]
    assert "strongest (default), not judged alone: nonuniform − uniform +3.00 [" in table.loc["Downsampling order",
                                                                                               "our evidence"]
    assert table.loc["Downsampling order", "configuration"] == "default"
    # the paper's runs tie where ours win: the row depends on the reading, and names both
    folder = write_evidence(tmp_path / "both", "Downsampling order", 3.0, 1.0)
    (folder / "table4_ablation.json").write_text(json.dumps({"notebook": "table4_ablation", "configuration": "default"}))
    paper = pd.read_csv(folder / ledger.papers_method_file("table4_ablation_runs.csv"))
    paper["unit_area"] = paper.category.map({c: 80.0 + i for i, c in enumerate(CATEGORIES)}) + paper.split
    paper.to_csv(folder / ledger.papers_method_file("table4_ablation_runs.csv"), index=False)
    row = ledger.ledger(folder).set_index("claim").loc["Downsampling order"]
    assert row.verdict == ledger.DEPENDS and row.configuration == "paper, default"
    assert row["our evidence"].startswith("literal (`paper`): nonuniform − uniform +0.00 ")
    assert "; strongest (default): nonuniform − uniform +3.00 [" in row["our evidence"]


def test_the_two_stage_bootstrap_resamples_categories_then_splits():
    values = pd.Series({("a", 0): 1.0, ("a", 1): 3.0, ("b", 0): -1.0, ("b", 1): 0.0, ("b", 2): 4.0, ("c", 0): 2.0})
    found = ledger.effect(values.rename_axis(["category", "split"]), "x")
    assert found.mean == pytest.approx(np.mean([2.0, 1.0, 2.0]))  # the mean of the category means
    assert found.units == "3 categories × 1-3 splits"
    # the same interval from a plain loop over draws (its own generator: the two agree up to the Monte Carlo error)
    rng, groups = np.random.default_rng(1), [np.array([1.0, 3.0]), np.array([-1.0, 0.0, 4.0]), np.array([2.0])]
    draws = [np.mean([rng.choice(groups[g], len(groups[g])).mean() for g in rng.integers(3, size=3)])
             for _ in range(ledger.DRAWS)]
    low, high = np.percentile(draws, [2.5, 97.5])
    assert (found.low, found.high) == pytest.approx((low, high), abs=0.1)
    assert ledger.effect(values.rename_axis(["category", "split"]), "x").low == found.low  # the seed is fixed


def test_fig4_with_a_model_per_split_resamples_models_then_their_meshes():
    # two splits' models on two meshes each; the second model is worse on both, so its spread must widen the interval
    rows = [{"model": "ours", "downsampling": mode, "split": split, "mesh": f"Human/{m}", "level": level,
             "attention AUC, near vs elsewhere": 0.5 + (0.2 if split == 0 else -0.1) + 0.01 * m,
             "labels kept (%)": 90.0 + (mode == "nonuniform") * (2.0 if split == 0 else -1.0)}
            for split in (0, 1) for m in (1, 2) for mode in ("uniform", "nonuniform") for level in (0, 1)]
    meshes = pd.DataFrame(rows)
    attention, labels = figure_effects.fig4_effects(meshes, "ours")
    assert list(attention.values.index.names) == ["split", "mesh"]
    assert attention.units == "2 models (one per split) × 2 test meshes"
    assert attention.mean == pytest.approx(np.mean([0.215, -0.085]))  # the mean of the models' means
    assert (labels.low, labels.high) == pytest.approx((-1.0, 2.0))  # a draw of one model twice reaches either end
    # one model: its meshes, one stage, as before the split column
    alone = figure_effects.fig4_effects(meshes[meshes.split == 0].drop(columns="split"), "ours")[0]
    assert alone.values.index.name == "mesh" and alone.units == "2 test meshes"
    same = figure_effects.fig4_effects(meshes[meshes.split == 0], "ours")[0]
    assert (same.low, same.high, same.units) == (alone.low, alone.high, alone.units)


def test_one_unit_has_no_interval_and_decides_nothing():
    alone = ledger.effect(pd.Series([5.0], index=pd.Index(["the table's number"], name="mesh")), "x")
    assert alone.verdict == ledger.TIED and "one unit, no interval" in str(alone)


def test_human_falls_back_to_the_single_number_without_the_run(tmp_path):
    folder = write_evidence(tmp_path, "Human body accuracy", -3.0, 1.0)
    assert verdicts(folder)["Human body accuracy"] == ledger.NOT_REPRODUCED
    ledger._table3_run_path(folder).unlink()
    row = ledger.ledger(folder).set_index("claim").loc["Human body accuracy"]
    assert row.verdict == ledger.TIED and "per-mesh numbers not reachable" in row["our evidence"]


def test_the_cost_row_quotes_a_stored_end_to_end_run_and_still_judges_nothing(tmp_path):
    folder = write_evidence(tmp_path, "Cost", 0.0, 1.0)
    cached_only = ledger.ledger(folder).set_index("claim").loc["Cost"]
    assert "end to end" not in cached_only["our evidence"]
    stored = folder / ledger.END_TO_END
    stored.parent.mkdir(parents=True)
    stored.write_text(json.dumps({
        "ours": {"mesh": "PSB Teddy/171", "faces": 24000,
                 "stages": {"total": 21.25, "features (level 0)": 15.5, "spectrum": 3.25}},
        "environment": {"cpus": 2, "cuda": None, "code_revision": "0123456789abcdef"}}))
    row = ledger.ledger(folder).set_index("claim").loc["Cost"]
    assert row.verdict == ledger.UNTESTED
    assert ("end to end, descriptors and eigenbasis computed: 21.2 s for PSB Teddy/171 (24000 faces) on CPU, 2 cores, "
            "of which descriptors 15.5 s and the network's eigenbasis 3.2 s (revision 0123456") in row["our evidence"]


# --- the committed results -----------------------------------------------------------------------------------------------

def test_every_claim_gets_one_of_five_verdicts_from_the_committed_results(results):
    table = ledger.ledger(results)
    assert list(table.claim) == [claim.name for claim in ledger.CLAIMS]
    assert "Manifold input" not in set(table.claim)  # a limitation, stated above the table
    assert set(table.verdict) <= {ledger.REPRODUCED, ledger.NOT_REPRODUCED, ledger.TIED, ledger.UNTESTED, ledger.DEPENDS}
    assert set(table[~table.claim.isin(TWO_READINGS)].verdict) <= {ledger.REPRODUCED, ledger.NOT_REPRODUCED, ledger.TIED,
                                                                     ledger.UNTESTED}  # one reading: no reading to depend on
    assert set(table[table.claim.isin(UNTESTABLE)].verdict) == {ledger.UNTESTED}
    markdown = ledger.markdown(table)
    assert markdown.startswith(ledger.RULE) and ledger.LIMITATION in markdown
    assert markdown.count("\n| ") == len(table) + 1 + len(configs.departures()) + 1
    # what the default changes from the paper's method, each setting from the code, the two that decide ablations among them
    changed = {name for name, *_ in configs.departures()}
    assert {"combine", "train.attention_weight"} <= changed and all(what for *_, what in configs.departures())


def test_the_committed_verdicts_are_their_effects_intervals(results):
    """Each verdict recomputed from the committed numbers with the public helpers the notebooks use."""
    table = verdicts(results)
    def judged(name):  # the ablations are judged on the paper's configuration's runs, where they are stored
        path = results / ledger.papers_method_file(name)
        return pd.read_csv(path) if path.is_file() else None

    runs = judged("table4_ablation_runs.csv")
    order = None if runs is None else [figure_effects.paired_over_splits(runs, "nonuniform", "uniform"),
                                       figure_effects.paired_over_splits(runs, "uniform", "none")]
    ours = pd.read_csv(results / "table4_ablation_runs.csv")
    strongest = ledger.combined(figure_effects.paired_over_splits(ours, "nonuniform", "uniform"),
                                figure_effects.paired_over_splits(ours, "uniform", "none"))
    assert table["Downsampling order"] == (ledger.UNTESTED if order is None else
                                           ledger.across_readings(ledger.combined(*order), strongest))
    meshes = pd.read_csv(results / "fig4_test_meshes.csv")
    attention, labels = figure_effects.fig4_effects(meshes, "paper")
    attention_ours, labels_ours = figure_effects.fig4_effects(meshes, "ours")
    assert (table["Attention at junctions"], table["Labels survive"]) == (
        ledger.across_readings(attention.verdict, attention_ours.verdict), ledger.across_readings(labels.verdict,
                                                                                                  labels_ours.verdict))
    runs = judged("fig12_features.csv")
    features = ledger.combined(*figure_effects.feature_effects(pd.read_csv(results / "fig12_features.csv")))
    assert table["All four feature groups"] == (ledger.UNTESTED if runs is None else ledger.across_readings(
        ledger.combined(*figure_effects.feature_effects(runs)), features))
    psb = pd.read_csv(results / "table1_psb_runs.csv")
    gap = psb.unit_area - psb.category.map(reference.TABLE_I["methods"]["Ours (paper)"])
    units = pd.MultiIndex.from_frame(psb[["category", "split"]])
    assert table["PSB accuracy"] == ledger.effect(gap.set_axis(units), "x").verdict


def test_the_human_row_reads_the_stored_runs_test_meshes(results):
    path = ledger._table3_run_path(results)
    if path is None or not (RESULTS / "runs" / path.name).is_file():
        pytest.skip("the Table III run is not stored in this checkout")
    path.parent.mkdir(exist_ok=True)
    shutil.copy(RESULTS / "runs" / path.name, path)
    run = json.loads(path.read_text())
    per_mesh = pd.Series([100 * m["accuracy"] for m in run["per_mesh"]], name="x").rename_axis("mesh")
    expected = ledger.effect(per_mesh - reference.TABLE_III["methods"]["Ours (paper)"], "ours − the paper")
    row = ledger.ledger(results).set_index("claim").loc["Human body accuracy"]
    assert row.verdict == expected.verdict and str(expected) in row["our evidence"]
    assert f"over {run['n_test']} test meshes" in row["our evidence"]


def test_a_missing_result_or_synthetic_data_cannot_decide(results):
    (results / "fig12_features.csv").unlink()
    table = ledger.ledger(results).set_index("claim")
    assert table.loc["All four feature groups", "verdict"] == ledger.UNTESTED
    assert "fig12_features.csv is not written yet" in table.loc["All four feature groups", "our evidence"]
    assert set(ledger.ledger(results, benchmark=False).verdict) == {ledger.UNTESTED}


def test_a_strongest_reading_kept_for_the_record_gives_its_own_table_i_accuracy(results):
    # an ablation notebook run under a configuration kept for the record (as when a replaced default's runs stand in)
    record = json.loads((results / "fig12_features.json").read_text())
    (results / "fig12_features.json").write_text(json.dumps({**record, "configuration": "v1"}))
    mean = pd.read_csv(results / "table1_psb.csv", index_col=0).loc["mean"]
    table = ledger.ledger(results).set_index("claim")
    assert (f"; strongest (v1, {mean['v1 (for the record), unit area (split 0)']:.2f}; paper 95.29): "
            in table.loc["All four feature groups", "in short"])
    assert (f"; strongest (default, {mean['ours, unit area (split 0)']:.2f}; paper 95.29): "
            in table.loc["Downsampling order", "in short"])


def test_each_row_names_the_configuration_its_notebooks_ran(results):
    record = json.loads((results / "table4_ablation.json").read_text())
    (results / "table4_ablation.json").write_text(json.dumps({**record, "configuration": "default"}))
    (results / "fig4_attention.json").write_text(json.dumps({"notebook": "fig4_attention", "configuration": "default"}))
    (results / "fig11_cycles_ratio.json").write_text(json.dumps({"notebook": "fig11_cycles_ratio"}))  # a record from before
    table = ledger.ledger(results).set_index("claim")
    # judged on the paper's method once its runs are stored, the notebook's own beside
    assert table.loc["Downsampling order", "configuration"] == "paper, default"
    (results / "table4_ablation_runs_paper.csv").unlink()
    table = ledger.ledger(results).set_index("claim")
    assert table.loc["Downsampling order", "configuration"] == "default"
    assert table.loc["Attention at junctions", "configuration"] == "paper, default"  # judged on the paper's model, ours beside
    assert table.loc["More cycles help", "configuration"] == "paper, not recorded"  # judged on the paper's runs
    assert table.loc["Better than MeshCNN and Guo et al.", "configuration"] == ""  # no run of ours reads it
    assert "| default | **" in ledger.markdown(table.reset_index())


def test_a_paired_difference_cancels_each_units_difficulty():
    # each (category, split) has its own difficulty; only the difference of the two rows is read
    per_unit = {("a", 0): 2.0, ("a", 1): 2.5, ("a", 2): 1.5, ("b", 0): 1.0, ("b", 1): 3.0, ("b", 2): 2.0}
    runs = pd.DataFrame([{"category": c, "split": s, "mode": mode, "unit_area": 80.0 + 5 * s + 7 * (c == "b")
                          + (d if mode == "nonuniform" else 0.0)}
                         for (c, s), d in per_unit.items() for mode in ("nonuniform", "uniform")])
    paired = figure_effects.paired_over_splits(runs, "nonuniform", "uniform")
    assert paired.values.to_dict() == pytest.approx(per_unit)
    assert paired.verdict == ledger.REPRODUCED and str(paired).startswith("nonuniform − uniform +2.00 [")


def test_fig11_readings_and_the_ledger_read_the_same_per_split_effects(tmp_path):
    folder = write_evidence(tmp_path, "N = 4, ratio 0.5", -3.0, 1.0)
    runs = pd.read_csv(folder / "fig11_cycles_ratio.csv")
    readings = figure_effects.fig11_readings(runs)
    assert [r.category for r in readings] == list(CATEGORIES)
    for reading in readings:
        assert reading.rivals == {s: (0.3, 2) for s in SPLITS} and reading.choice.verdict == ledger.NOT_REPRODUCED
        assert f"the paper's choice − the best other point {reading.choice.mean:+.2f} [" in str(reading)
        assert "picked on the other splits (N = 2, removing 0.3 (splits 0, 1, 2, 3))" in str(reading)
        assert f"({ledger.NOT_REPRODUCED})" in str(reading)
    pooled = pd.concat({r.category: r.choice.values for r in readings}, names=["category", "split"])
    evidence = ledger.ledger(folder).set_index("claim").loc["N = 4, ratio 0.5", "our evidence"]
    pooled_effect = ledger.effect(pooled, "the paper's point − the best other")
    assert evidence.startswith(f"literal (`paper`): {pooled_effect}")


def test_the_readmes_rows_are_short_and_say_what_they_read(results):
    """About 60 words a row in the README (the whole evidence in the notebook and the CSV); a number said once."""
    table = ledger.ledger(RESULTS)  # with the run store (read only): the rows that name mixed revisions, as the README
    rows = ledger.markdown(table).splitlines()[-len(table):]
    assert all(len(row.split()) <= 75 for row in rows), [(len(r.split()), r[:60]) for r in rows if len(r.split()) > 75]
    short = table.set_index("claim")["in short"]
    # splits 1-4 read: the share of their test meshes the settings were chosen on, counted from the splits file
    selected, tested = ledger.selection.overlap((c, s) for c in reference.TABLE_I["methods"]["Ours (paper)"] for s in range(5))
    assert (selected, tested) == (336, 512)
    assert f"selection 66 % ({selected} of {tested})" in short["PSB accuracy"] and "split 0, the clean test" in short[
        "PSB accuracy"]
    assert "rival picked on the other splits" in short["N = 4, ratio 0.5"]  # no winner's curse: said
    features = short["All four feature groups"]
    assert features.count("edge+gc+sdf+agd − ") == 1 or "best other set" in features.split("−")[1]
    evidence = table.set_index("claim")["our evidence"]
    for claim in ("Downsampling order", "More cycles help", "N = 4, ratio 0.5", "All four feature groups"):
        assert "CPU" in evidence[claim], claim  # the readings' CPUs, in full (the README's Table IV says it once)
    for claim in ("Downsampling order", "More cycles help"):  # the drift, between revisions and machines, in full
        if "revision_drift.csv" in evidence[claim]:
            assert "of the 7 moved from the accuracy stored" in evidence[claim]


def test_selection_counts_the_test_meshes_the_settings_were_chosen_on():
    from anseg.study import selection

    assert selection.note([("Human", 0), ("Teddy", 0)]) == ""  # split 0 alone: the clean test
    selected, tested = selection.overlap([("Human", 1), ("Human", 1)])  # a unit counted once
    assert tested == 8 and 0 <= selected <= 8
    assert selection.brief([("Human", 1)]) == f"selection {selection.percent(selected, tested)} ({selected} of 8)"


def test_a_table_whose_readings_differ_in_cpu_says_so(tmp_path):
    from anseg.study.revisions import cpus as _cpus

    (tmp_path / "runs").mkdir()
    for key, model in (("a", "AMD EPYC 9R14"), ("b", "Intel(R) Xeon(R) Processor"), ("c", None)):
        env = {"cuda": None, "machine": "x86_64", "processor": "x86_64", **({"cpu_model": model} if model else {})}
        (tmp_path / "runs" / f"{key}.json").write_text(json.dumps({"environment": env}))
    one = pd.DataFrame({"key": ["a"]})
    assert _cpus([("default", one), ("`paper`", one)], tmp_path) == " Every run trained on AMD EPYC 9R14."
    assert "**These runs mix CPUs:** default: AMD EPYC 9R14; `paper`: Intel(R) Xeon(R) Processor" in _cpus(
        [("default", one), ("`paper`", pd.DataFrame({"key": ["b"]}))], tmp_path)
    assert "The run records name no CPU model" in _cpus([("default", pd.DataFrame({"key": ["c"]}))], tmp_path)
