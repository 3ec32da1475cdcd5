"""The claims ledger: a verdict for every claim, read from the result files, and verdicts that follow the numbers."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from anseg.study import ledger

RESULTS = Path(__file__).resolve().parent.parent / "results"


@pytest.fixture
def results(tmp_path) -> Path:
    """A copy of the committed results that a test may change."""
    if not (RESULTS / "table1_psb.csv").is_file():
        pytest.skip("no committed results in this checkout")
    shutil.copytree(RESULTS, tmp_path / "results", ignore=shutil.ignore_patterns("runs"))
    return tmp_path / "results"


def test_every_claim_gets_one_of_three_verdicts_from_the_committed_results(results):
    table = ledger.ledger(results)
    assert list(table.claim) == [claim.name for claim in ledger.CLAIMS]
    assert set(table.verdict) <= {ledger.HOLDS, ledger.FAILS, ledger.UNTESTED}
    assert table.loc[table.claim == "PSB accuracy", "our evidence"].item().startswith("ours ")
    markdown = ledger.markdown(table)
    assert markdown.count("\n") == len(table) + 1


def test_verdicts_follow_the_numbers(results):
    verdict = lambda name: ledger.ledger(results).set_index("claim").loc[name, "verdict"]
    # two test meshes, levels 0-2 of each model's two hierarchies: AUC on the nonuniform ones, labels kept on all
    rows = [{"model": who, "downsampling": mode, "mesh": mesh, "level": level,
             "attention AUC, near vs elsewhere": 0.5 if level == 0 else (0.8 if who == "ours" else 0.7),
             "labels kept (%)": 100.0 - 3 * level}
            for who in ("ours", "paper") for mode in ("uniform", "nonuniform") for mesh in ("Human/2", "Human/5")
            for level in range(3)]
    meshes = pd.DataFrame(rows)
    meshes.to_csv(results / "fig4_test_meshes.csv", index=False)
    assert verdict("Attention at junctions") == ledger.HOLDS and verdict("Labels survive") == ledger.HOLDS
    paper_coarse = (meshes.model == "paper") & (meshes.downsampling == "nonuniform") & (meshes.level == 2)
    meshes.loc[paper_coarse & (meshes.mesh == "Human/2"), "attention AUC, near vs elsewhere"] = 0.2  # mean 0.45
    meshes.loc[paper_coarse, "labels kept (%)"] = 80.0  # the paper's own hierarchy loses labels that uniform keeps
    meshes.to_csv(results / "fig4_test_meshes.csv", index=False)
    assert verdict("Attention at junctions") == ledger.FAILS and verdict("Labels survive") == ledger.FAILS

    table1 = pd.read_csv(results / "table1_psb.csv", index_col=0)
    over = next(c for c in table1.columns if c.startswith("ours, unit area, mean of"))
    table1.loc["mean", over] = 95.29 - table1.loc["mean", "ours, std over splits"] / 2  # short by less than the spread
    table1.to_csv(results / "table1_psb.csv")
    assert verdict("PSB accuracy") == ledger.HOLDS
    table1["paper configuration, unit area (split 0)"] = 50.0  # the plain reading's column, every category run
    table1.to_csv(results / "table1_psb.csv")
    evidence = ledger.ledger(results).set_index("claim").loc["PSB accuracy", "our evidence"]
    assert evidence.endswith("the paper's method as written (paper configuration, unit area (split 0)): 50.00")


def test_a_missing_result_or_synthetic_data_cannot_decide(results):
    (results / "fig12_features.csv").unlink()
    table = ledger.ledger(results).set_index("claim")
    assert table.loc["All four feature groups", "verdict"] == ledger.UNTESTED
    assert "fig12_features.csv is not written yet" in table.loc["All four feature groups", "our evidence"]
    assert set(ledger.ledger(results, benchmark=False).verdict) == {ledger.UNTESTED}


def test_each_row_names_the_configuration_its_notebooks_ran(results):
    import json

    record = json.loads((results / "table4_ablation.json").read_text())
    (results / "table4_ablation.json").write_text(json.dumps({**record, "configuration": "default"}))
    (results / "fig4_attention.json").write_text(json.dumps({"notebook": "fig4_attention", "configuration": "default"}))
    (results / "fig11_cycles_ratio.json").write_text(json.dumps({"notebook": "fig11_cycles_ratio"}))  # a record from before
    table = ledger.ledger(results).set_index("claim")
    assert table.loc["Downsampling order", "configuration"] == "default"
    assert table.loc["Attention at junctions", "configuration"] == "default, paper"  # it reads the paper's model too
    assert table.loc["More cycles help", "configuration"] == "not recorded"
    assert table.loc["Manifold input", "configuration"] == ""  # decided by the code, not by runs
    assert "| default | **" in ledger.markdown(table.reset_index())


@pytest.mark.parametrize("per_split, reading", [((2.0, 2.5, 1.5), ledger.HOLDS), ((2.0, -1.0, 0.5), "within the spread"),
                                                ((-2.0, -2.5, -1.5), ledger.FAILS), ((0.1,), ledger.HOLDS)])
def test_a_paired_difference_is_a_finding_only_outside_its_spread(per_split, reading):
    # two categories per split; each split's own difficulty (its offset) must cancel in the pairing
    runs = pd.DataFrame([{"category": category, "split": split, "mode": mode,
                          "unit_area": 80.0 + 5 * split + (difference if mode == "nonuniform" else 0.0) + (category == "b")}
                         for split, difference in enumerate(per_split) for category in ("a", "b")
                         for mode in ("nonuniform", "uniform")])
    paired = ledger.paired_over_splits(runs, "nonuniform", "uniform")
    assert paired.per_split == pytest.approx(per_split)
    assert paired.reading == reading
    assert str(paired).startswith(f"nonuniform − uniform {sum(per_split) / len(per_split):+.2f}")


def fig11_runs(effect) -> pd.DataFrame:
    """A Fig. 11 run table over 3 splits whose own difficulty differs by 10 points: ``effect(removed, cycles, split)``."""
    return pd.DataFrame([{"category": "Airplane", "split": split, "removed": removed, "cycles": cycles,
                          "unit_area": 80.0 + 10 * split + effect(removed, cycles, split)}
                         for split in range(3) for removed in (0.3, 0.5) for cycles in (1, 2, 4, 6)])


def test_fig11_is_read_from_differences_paired_over_the_splits(results):
    verdict = lambda name: ledger.ledger(results).set_index("claim").loc[name, "verdict"]
    # removing 0.5 climbs by 2 points at N = 4 on every split (the splits' 10-point spread cancels); 0.3 stays flat
    runs = fig11_runs(lambda removed, cycles, split: 2.0 * (removed == 0.5 and cycles == 4) + 0.01 * split * cycles)
    (reading,) = ledger.fig11_readings(runs)
    assert reading.best == (0.5, 4) and reading.choice_gap.reading == "within the spread"  # the choice is the best
    assert reading.climbs[0.5].reading == ledger.HOLDS and reading.climbs[0.5].mean == pytest.approx(2.03)
    assert reading.climbs[0.3].better == "N = 6" and reading.climbs[0.3].reading == "within the spread"
    runs.to_csv(results / "fig11_cycles_ratio.csv", index=False)
    assert verdict("N = 4, ratio 0.5") == ledger.HOLDS
    evidence = ledger.ledger(results).set_index("claim").loc["N = 4, ratio 0.5", "our evidence"]
    assert "(92.04; the 8 points within 90.01-92.04)" in evidence  # how flat the grid is, beside its best point
    assert verdict("More cycles help") == ledger.FAILS  # 1 of 2 curves is not most
    # N = 2 removing 0.3 beats the paper's choice by 1 point on every split: a finding against it
    runs = fig11_runs(lambda removed, cycles, split: 2.0 * (removed == 0.5 and cycles == 4)
                      + 3.0 * (removed == 0.3 and cycles == 2))
    runs.to_csv(results / "fig11_cycles_ratio.csv", index=False)
    assert verdict("N = 4, ratio 0.5") == ledger.FAILS and verdict("More cycles help") == ledger.HOLDS
