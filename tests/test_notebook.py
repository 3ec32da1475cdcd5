"""anseg.study.notebook: the one call that sets a notebook up, its planned runs and its run record."""

from __future__ import annotations

import json

import pytest

from anseg.study.notebook import NotebookRun, percent, start
from anseg.study.plan import COMMON, PLANS, notebook_runs


def smoke_parameters(name: str, out) -> dict:
    return {**COMMON["smoke"], **PLANS[f"{name}.ipynb"].parameters["smoke"], "output_dir": str(out)}


def test_start_reads_the_parameter_cell_and_records_the_run(tmp_path, capsys):
    namespace = {**smoke_parameters("table4_ablation", tmp_path), "unrelated": 1}
    nb = start("table4_ablation", namespace)
    assert nb.results_dir.is_dir() and nb.figures_dir.is_dir()
    assert nb.record["parameters"] == smoke_parameters("table4_ablation", tmp_path)
    assert [d["dataset"] for d in nb.record["data"]] == ["synthetic"]
    assert "Synthetic data" in nb.notice() and "Smoke settings" in nb.notice()
    printed = capsys.readouterr().out
    assert printed.startswith("**Synthetic data")  # outside a notebook the notice is printed, then the record
    summary = printed[printed.index("| run record"):]  # a few lines, not the record's JSON
    assert len(summary.splitlines()) == 7 and "`default` (2 epochs, seed 0)" in summary and "{" not in summary
    assert nb.record["environment"]["code_revision"][:12] in summary or "not recorded" in summary
    assert nb.record["environment"]["cpu_model"] in summary  # the machine row names the CPU model
    # the planned runs are the plan's, not a loop of the notebook's own
    assert nb.planned == notebook_runs("table4_ablation.ipynb", nb.parameters)
    assert {run.row["mode"] for run in nb.planned} == {"nonuniform", "uniform", "none", "none, transformer"}
    with pytest.raises(FileNotFoundError, match="not on this machine"):
        nb.load_model({"key": "0123456789abcdef"})
    path = nb.finish()
    assert json.loads(path.read_text())["wall_seconds"] >= 0


def test_start_names_a_missing_parameter_and_an_unknown_notebook(tmp_path):
    namespace = smoke_parameters("table1_psb", tmp_path)
    del namespace["splits"]
    with pytest.raises(ValueError, match="does not define splits"):
        start("table1_psb", namespace)
    with pytest.raises(ValueError, match="no notebook 'table9'"):
        NotebookRun("table9", namespace)


def test_the_recorded_data_follows_the_plan(tmp_path):
    """explore.ipynb with a user's mesh and model trains nothing and reads no data set."""
    parameters = {**smoke_parameters("explore", tmp_path), "mesh_path": "m.off", "model_path": "m.pt"}
    nb = NotebookRun("explore", parameters)
    assert nb.planned == [] and nb.record["data"] == []


def test_the_record_names_the_data_read_outside_the_plan_and_the_model(tmp_path, capsys):
    """explore.ipynb with a shipped model plans no run, yet reads a test mesh: both are in its record."""
    parameters = {**smoke_parameters("explore", tmp_path), "model_path": "m.pt"}
    nb = NotebookRun("explore", parameters)
    assert nb.record["data"] == []
    nb.test_meshes("synthetic", parameters["category"])
    nb.test_meshes("synthetic", parameters["category"])
    assert [d["dataset"] for d in nb.record["data"]] == ["synthetic"]  # once, however often read
    nb.note_model(pretrained="psb/Human", card={"run": "0123456789abcdef"})
    assert '"pretrained": "psb/Human"' in capsys.readouterr().out
    assert json.loads(nb.finish().read_text())["model"] == {"pretrained": "psb/Human", "card": {"run": "0123456789abcdef"}}


def test_real_categories_none_means_every_psb_category(tmp_path):
    from anseg import datasets

    parameters = {**COMMON["real"], **PLANS["table1_psb.ipynb"].parameters["real"], "output_dir": str(tmp_path)}
    runs = notebook_runs("table1_psb.ipynb", parameters)
    # every category on every split, then the paper's method as written on the first split
    assert len(runs) == len(datasets.PSB_CATEGORIES) * (len(parameters["splits"]) + 1)
    assert runs[0].row == {"category": datasets.PSB_CATEGORIES[0], "split": 0}
    assert {run.category for run in runs if run.row.get("configuration") == "paper"} == set(datasets.PSB_CATEGORIES)


def test_percent():
    assert percent({"unit_area": 0.5, "faces": 0.25}) == {"unit_area": 50.0, "faces": 25.0}


def test_the_record_column_reads_the_first_studys_stored_run_and_never_repeats_ours(tmp_path):
    from anseg.study.plan import RECORD_CONFIGURATIONS, planned_experiment

    nb = start("table3_human", smoke_parameters("table3_human", tmp_path))
    (run,) = nb.planned
    assert nb.for_the_record(run) == {}  # not stored: read, never trained
    (first, *_) = RECORD_CONFIGURATIONS
    experiment, options = planned_experiment(run, {**nb.parameters, "config": first})
    nb.store.put({"key": experiment.key(options), "accuracy": {"unit_area": 0.5}})
    assert nb.for_the_record(run)[first]["accuracy"] == {"unit_area": 0.5}
    own = start("table3_human", {**smoke_parameters("table3_human", tmp_path), "config": first})
    assert first not in own.for_the_record(run)  # the column would repeat ours


def test_beside_a_table_a_notebook_says_which_machines_trained_its_runs(tmp_path):
    nb = NotebookRun("table1_psb", smoke_parameters("table1_psb", tmp_path))
    assert nb.machines() == "No stored run is read here."
    cpu = {"environment": {"cuda": None, "cpus": 2}, "train_seconds": 60.0}
    nb.read = {"a": cpu, "b": cpu}
    assert nb.machines().startswith("Trained on one kind of machine: CPU, 2 cores (2 runs). CPU models, from the run "
                                    "records: CPU model not recorded (2). A record made before")
    nb.read["c"] = {"environment": {"cuda": "NVIDIA H100", "cpus": 16}, "train_seconds": 60.0}
    assert nb.machines().startswith("**These runs mix machines:** CPU, 2 cores (2 runs), NVIDIA H100 (1 run).")
    assert "GPU: NVIDIA H100 (1)" in nb.machines()


def test_the_record_names_each_runs_cpu_model_and_says_where_a_record_lacks_it(tmp_path):
    from anseg.study.store import NOT_RECORDED, cpu_of

    assert cpu_of({"environment": {"cuda": None, "machine": "x86_64", "processor": "x86_64"}}) == NOT_RECORDED
    epyc = {"environment": {"cuda": None, "cpus": 2, "cpu_model": "AMD EPYC 9R14"}, "train_seconds": 1.0}
    xeon = {"environment": {"cuda": None, "cpus": 2, "cpu_model": "Intel(R) Xeon(R) Processor"}, "train_seconds": 1.0}
    nb = NotebookRun("table1_psb", smoke_parameters("table1_psb", tmp_path))
    nb.read = {"a": epyc}
    assert "AMD EPYC 9R14 (1)" in nb.machines() and "mix CPUs" not in nb.machines()
    nb.read["b"] = xeon
    assert "**These runs mix CPUs.**" in nb.machines()
    assert nb._runs_read()["cpu_models"] == {"AMD EPYC 9R14": 1, "Intel(R) Xeon(R) Processor": 1}


def test_a_figure_shows_the_median_mesh_and_of_an_even_count_the_lower_middle_one():
    from anseg.study.notebook import median_mesh

    per_mesh = [{"name": name, "accuracy": a} for name, a in (("a", 0.9), ("b", 0.5), ("c", 0.7), ("d", 0.99))]
    assert median_mesh(per_mesh)["name"] == "c"
    assert median_mesh(per_mesh[:3])["name"] == "c" and median_mesh(per_mesh[1:2])["name"] == "b"
