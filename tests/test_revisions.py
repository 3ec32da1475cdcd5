"""A paired comparison never mixes code revisions silently: the ledger names them and their drift beside the verdict."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from anseg.study import ledger, revisions
from anseg.study.store import REPO


def store_runs(folder, revision_of: dict) -> None:
    (folder / "runs").mkdir(parents=True, exist_ok=True)
    for key, revision in revision_of.items():
        (folder / "runs" / f"{key}.json").write_text(json.dumps({"environment": {"code_revision": revision,
                                                                                "code_clean": True}}))


def test_arms_of_one_revision_say_nothing_and_mixed_ones_are_named(tmp_path):
    runs = pd.DataFrame({"mode": ["a", "a", "b", "b"], "key": ["k1", "k2", "k3", "k4"]})
    store_runs(tmp_path, {"k1": "1111111aaa", "k2": "2222222bbb", "k3": "1111111aaa", "k4": "2222222bbb"})
    assert revisions.mix(runs, "mode", tmp_path) is None
    store_runs(tmp_path, {"k4": "3333333ccc"})
    sentence = revisions.mix(runs, "mode", tmp_path)
    assert "a: 1111111, 2222222" in sentence and "b: 1111111, 3333333" in sentence and "not measured" in sentence


def store_drift(folder, accuracy_at: dict, machine="Some CPU, 2 cores") -> None:
    """``results/replay/revision_drift.csv`` with run k1 trained at each revision of ``accuracy_at``."""
    (folder / "replay").mkdir(parents=True, exist_ok=True)
    pd.DataFrame([{"key": "k1", "at": f"{at}00000", "replayed": value, "replayed_on": machine}
                  for at, value in accuracy_at.items()]).to_csv(folder / revisions.DRIFT, index=False)


def test_the_drift_measured_between_the_mixed_revisions_is_shown_beside_them(tmp_path):
    runs = pd.DataFrame({"mode": ["a", "b"], "key": ["k1", "k2"]})
    store_runs(tmp_path, {"k1": "1111111aaa", "k2": "2222222bbb"})
    store_drift(tmp_path, {"1111111": 0.9})
    assert "not measured (no run of results/replay/revision_drift.csv was trained at 2222222)" in revisions.mix(
        runs, "mode", tmp_path)
    store_drift(tmp_path, {"1111111": 0.9, "2222222": 0.9})
    assert revisions.mix(runs, "mode", tmp_path).endswith(
        "the 1 runs of results/replay/revision_drift.csv trained at each of them on one machine (Some CPU, 2 cores) "
        "gave the same accuracy at every one, to the last digit")
    store_drift(tmp_path, {"1111111": 0.9, "2222222": 0.8875})
    assert "moved by up to 1.25 points between them (mean 1.25; unit area)" in revisions.mix(runs, "mode", tmp_path)


PAIRED = {"Downsampling order": ("table4_ablation_runs.csv", "mode"),
          "All four feature groups": ("fig12_features.csv", "features"),
          "More cycles help": ("fig11_cycles_ratio.csv", "cycles")}


@pytest.mark.parametrize("claim", sorted(PAIRED))
def test_every_committed_paired_row_that_mixes_revisions_says_so(claim):
    name, arm = PAIRED[claim]
    if not (REPO / "results" / name).is_file():
        pytest.skip(f"results/{name} is not written")
    runs = pd.read_csv(REPO / "results" / name)
    sentence = revisions.mix(runs, arm, REPO / "results")
    evidence = ledger.ledger(REPO / "results").set_index("claim").loc[claim, "our evidence"]
    if sentence is None:
        assert "code revisions" not in evidence
    else:  # shown beside the verdict, with the drift measured between those revisions
        assert sentence in evidence and "not measured" not in sentence
