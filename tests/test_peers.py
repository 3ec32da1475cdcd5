"""Peers measured here: read from the stored outputs of benchmarks/diffusionnet.py, and nothing else."""

import json

import pandas as pd
import pytest

from anseg.study import peers
from anseg.study.store import REPO


def _write(folder, name, categories, dataset=None, cpu="AMD EPYC", device="cpu"):
    settings = {"category": categories, "split": 0, "input": "hks", "device": device}
    if dataset is not None:
        settings["dataset"] = dataset
    environment = {"cpu_model": cpu} if cpu else {}
    rows = [{"category": c, "unit_area": 80.0 + i, "raw_area": 0.0, "faces": 0.0} for i, c in enumerate(categories)]
    (folder / name).write_text(json.dumps({"settings": settings, "categories": rows, "environment": environment}))


def test_measured_here_reads_each_stored_run_by_data_set_and_category(tmp_path):
    _write(tmp_path, "a.json", ["Hand", "Vase"])
    _write(tmp_path, "b.json", ["Bird"], dataset="psb", cpu=None)  # an early output: no dataset, no CPU model
    _write(tmp_path, "c.json", ["human_seg"], dataset="human_seg", device="cuda")
    psb = peers.measured_here("psb", folder=tmp_path)
    assert list(psb) == ["DiffusionNet (hks)"]
    runs = psb["DiffusionNet (hks)"]
    assert {c: r.unit_area for c, r in runs.items()} == {"Hand": 80.0, "Vase": 81.0, "Bird": 80.0}
    assert runs["Hand"].cpu == "AMD EPYC" and "not recorded" in runs["Bird"].cpu
    human = peers.measured_here("human_seg", folder=tmp_path)["DiffusionNet (hks)"]["human_seg"]
    assert human.cpu == "a CUDA GPU"
    assert peers.measured_here("coseg_vases", folder=tmp_path) == {}
    assert peers.measured_here("psb", split=1, folder=tmp_path) == {}


def test_two_runs_of_one_method_on_one_category_are_refused(tmp_path):
    _write(tmp_path, "a.json", ["Hand"])
    _write(tmp_path, "b.json", ["Hand"])
    with pytest.raises(ValueError, match="a.json and b.json both hold DiffusionNet \\(hks\\) on Hand"):
        peers.stored_runs(tmp_path)


def test_every_stored_peer_number_in_table_i_is_its_stored_runs():
    """Table I's peer column holds the stored reruns and no other number (its mean only over all 16)."""
    table = pd.read_csv(REPO / "results" / "table1_psb.csv", index_col=0)
    measured = peers.measured_here("psb")
    columns = [c for c in table.columns if c.endswith("our data, split 0")]
    assert columns == [f"{method}, our data, split 0" for method in measured]
    for method, column in zip(measured, columns):
        stored = table[column].drop("mean").dropna()
        assert stored.to_dict() == {c: round(r.unit_area, 2) for c, r in measured[method].items()}
        assert pd.isna(table.loc["mean", column]) == (len(stored) < 16)
