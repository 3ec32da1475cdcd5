"""The committed result tables are what the committed runs say: recomputed from results/runs/, never edited by hand."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

RESULTS = Path(__file__).resolve().parent.parent / "results"
TABLES_WITH_KEYS = sorted(p.name for p in RESULTS.glob("*.csv") if "key" in pd.read_csv(p, nrows=0).columns)


def stored(key: str) -> dict:
    return json.loads((RESULTS / "runs" / f"{key}.json").read_text())


@pytest.mark.parametrize("table", TABLES_WITH_KEYS)
def test_every_row_of_a_run_table_is_its_stored_run(table):
    rows = pd.read_csv(RESULTS / table)
    for row in rows.itertuples():
        run = stored(row.key)
        for reading in ("unit_area", "raw_area", "faces"):
            assert getattr(row, reading) == pytest.approx(100 * run["accuracy"][reading], abs=1e-9), (table, row.key, reading)
        if "train_seconds" in rows:
            assert row.train_seconds == pytest.approx(run["train_seconds"], abs=0.05), (table, row.key)
        if "evaluate_seconds_per_mesh" in rows:
            assert row.evaluate_seconds_per_mesh == pytest.approx(run["evaluate_seconds"] / run["n_test"], abs=0.005)


def test_table_one_is_the_mean_and_spread_of_its_runs():
    if not (RESULTS / "table1_psb.csv").is_file():
        pytest.skip("no committed Table I")
    runs = pd.read_csv(RESULTS / "table1_psb_runs.csv")
    table = pd.read_csv(RESULTS / "table1_psb.csv", index_col=0)
    over = next(c for c in table.columns if c.startswith("ours, unit area, mean of"))
    split0 = runs[runs.split == 0].set_index("category").unit_area
    per_category = runs.groupby("category").unit_area
    for category in split0.index:
        assert table.loc[category, "ours, unit area (split 0)"] == pytest.approx(split0[category], abs=0.005)
        assert table.loc[category, over] == pytest.approx(per_category.mean()[category], abs=0.005)
        assert table.loc[category, "ours, std over splits"] == pytest.approx(per_category.std()[category], abs=0.006)
    # the mean row: the 16-category mean of every split, then their mean and spread
    split_means = runs.groupby("split").unit_area.mean()
    assert table.loc["mean", "ours, unit area (split 0)"] == pytest.approx(split_means[0], abs=0.005)
    assert table.loc["mean", over] == pytest.approx(split_means.mean(), abs=0.005)
    assert table.loc["mean", "ours, std over splits"] == pytest.approx(np.std(split_means, ddof=1), abs=0.006)
