"""The notebooks: their parameters match the plan, and the smoke reproduction runs them all cleanly."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

from anseg import datasets
from anseg.study.headline import (
    HEADLINE_END,
    HEADLINE_START,
    LEDGER_END,
    LEDGER_START,
    headline,
)
from anseg.study.plan import COMMON, PLANS, planned_experiments
from anseg.study.reproduce import NOTEBOOKS
from anseg.study.store import REPO

SMOKE_TIMEOUT_S = 1800  # about 4 minutes on a 2-core CPU; the margin is for a loaded machine


def _parameter_names(notebook) -> set[str]:
    cells = [c for c in notebook.cells if "parameters" in c.metadata.get("tags", [])]
    assert len(cells) == 1, "exactly one cell must be tagged 'parameters'"
    tree = ast.parse(cells[0].source)
    return {target.id for node in tree.body if isinstance(node, ast.Assign) for target in node.targets}


@pytest.mark.parametrize("name", sorted(PLANS))
def test_notebook_takes_exactly_the_parameters_reproduce_passes(name):
    notebook = nbformat.read(NOTEBOOKS / name, as_version=4)
    names = _parameter_names(notebook)
    for kind in COMMON:
        assert names == set(COMMON[kind]) | set(PLANS[name].parameters[kind]) | {"output_dir"}, kind
    assert notebook.metadata["kernelspec"]["name"] == "python3"
    code = [c for c in notebook.cells if c.cell_type == "code"]
    assert all(not c.outputs and c.execution_count is None for c in code), "source notebooks are committed without outputs"


def _expected_files(out: Path) -> list[Path]:
    smoke = {name: {**COMMON["smoke"], **PLANS[name].parameters["smoke"]} for name in PLANS}
    results = ["table1_psb.csv", "table1_psb_runs.csv", "table2_coseg.csv", "table3_human.csv", "table4_ablation.csv",
               "table4_ablation_runs.csv", "fig11_cycles_ratio.csv", "fig12_features.csv", "fig4_attention.csv",
               "fig4_test_meshes.csv", "claims_ledger.csv"]
    results += [name.replace(".ipynb", ".json") for name in PLANS]
    figures = ["table3_human.png", "table4_ablation.png", "fig12_features.png", "fig12_renders.png", "fig4_attention.png",
               "fig4_attention_paper.png", "fig5_8_predictions.png", "fig10_modes.png", "explore_levels.png",
               "explore_labels.png",
               "explore_confidence.png"]
    figures += [f"table2_coseg_{c}.png" for c in smoke["table2_coseg.ipynb"]["categories"]]
    figures += [f"fig11_cycles_ratio_{c}.png" for c in smoke["fig11_cycles_ratio.ipynb"]["categories"]]
    return [out / "results" / f for f in results] + [out / "figures" / f for f in figures]


@pytest.mark.slow
def test_smoke_reproduction_runs_every_notebook(tmp_path):
    run = subprocess.run(
        [sys.executable, "-m", "anseg.study.reproduce", "--smoke", "--out", str(tmp_path)],
        cwd=REPO, env=os.environ.copy(), capture_output=True, text=True, timeout=SMOKE_TIMEOUT_S,
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]

    for name in PLANS:
        executed = nbformat.read(tmp_path / "notebooks" / name, as_version=4)
        code = [c for c in executed.cells if c.cell_type == "code"]
        errors = [o for c in code for o in c.outputs if o.output_type == "error"]
        assert not errors, f"{name}: {errors[0].ename}: {errors[0].evalue}"
        assert all(c.execution_count is not None for c in code), f"{name}: a cell did not run"

    missing = [str(p.relative_to(tmp_path)) for p in _expected_files(tmp_path) if not p.is_file()]
    assert not missing, f"not written: {missing}"
    record = json.loads((tmp_path / "results" / "table1_psb.json").read_text())
    assert record["parameters"]["smoke"] is True and record["wall_seconds"] > 0
    assert record["environment"]["torch"] and record["data"][0]["dataset"] == "synthetic"
    header = (tmp_path / "results" / "table1_psb.csv").read_text().splitlines()[0]
    assert "Ours (paper), Table I" in header and "ours, raw area (split 0)" in header

    # the plan that --train-only works through is exactly what the notebooks trained
    trained = {p.stem for p in (tmp_path / "results" / "runs").glob("*.json")}
    assert trained == {experiment.key(options) for experiment, options in planned_experiments("smoke")}


def test_real_plan_covers_every_table_once():
    plan = planned_experiments("real", config="default")  # one configuration throughout: the notebooks share runs
    keys = [experiment.key(options) for experiment, options in plan]
    assert len(keys) == len(set(keys))
    psb = [e for e, _ in plan if e.dataset == "psb"]
    # Table I 16 per split; Table IV's uniform and two "none" rows on 3 categories per split (its nonuniform row is
    # Table I's); Fig. 12's four paper sets on 3 categories per split (its fifth is Table I's); Fig. 11's grid on its
    # splits, less its points at N = 4 removing half (Table I's runs)
    splits = len(PLANS["table1_psb.ipynb"].parameters["real"]["splits"])
    table4_splits = len(PLANS["table4_ablation.ipynb"].parameters["real"]["splits"])
    fig12_splits = len(PLANS["fig12_features.ipynb"].parameters["real"]["splits"])
    fig11 = PLANS["fig11_cycles_ratio.ipynb"].parameters["real"]
    fig11_runs = sum(len(r) for r in fig11["removed"].values()) * len(fig11["cycles_list"]) * len(fig11["splits"])
    fig11_shared = len(fig11["removed"]) * len(fig11["splits"])
    # Table IV's three other rows on split 0 of the other 13 categories where it reads every category; Fig. 4's models
    # of the paper's method on its splits other than 0 (split 0's is Table I's)
    every = PLANS["table4_ablation.ipynb"].parameters["real"]["every_category"]
    fig4_splits = PLANS["fig4_attention.ipynb"].parameters["real"]["model_splits"]
    extra = 13 * 3 * every + len(set(fig4_splits) - {0})
    # and Table I's column of the paper's method as written, on its first split
    assert len(psb) == 16 * splits + 16 + 9 * table4_splits + 12 * fig12_splits + fig11_runs - fig11_shared + extra
    assert {e.dataset for e, _ in plan} == {"psb", "coseg_aliens", "coseg_chairs", "coseg_vases", "human_seg"}
    only = planned_experiments("real", only=["table4"], config="default")
    rows = [("nonuniform", 2), ("uniform", 2), ("none", 0), ("none", 2)]  # (mode, depth): depth 0 is the paper's "none"
    units = {(c, s) for c in ("Human", "Teddy", "Airplane") for s in range(table4_splits)}
    units |= {(c, 0) for c in datasets.PSB_CATEGORIES} if every else set()
    assert sorted((e.category, e.split_index, e.segment.mode, e.train.depth) for e, _ in only) == sorted(
        (c, s, m, d) for c, s in units for m, d in rows)


def test_a_named_configuration_is_the_start_of_every_planned_run():
    paper = planned_experiments("smoke", only=["table4"], config="paper")
    assert paper and all(e.segment.combine == "coarsest" and e.train.attention_weight == 0.0 for e, _ in paper)
    assert all(e.segment.cycles == 2 and e.train.width == 16 for e, _ in paper)  # the smoke settings on top
    default = planned_experiments("smoke", only=["table4"])
    assert {e.key(o) for e, o in paper}.isdisjoint(e.key(o) for e, o in default)
    # the paper's method as written runs the three rows the paper has; the default adds our transformer-only control
    assert sorted(e.segment.mode for e, _ in paper if e.category == "figure") == ["none", "nonuniform", "uniform"]
    assert len(default) == 8 and sum(e.segment.mode == "none" for e, _ in default) == 4  # smoke: every category too


def test_every_category_adds_split_0_of_the_others_once():
    from anseg.study.plan import PSB_ABLATION, notebook_parameters, notebook_runs

    p = notebook_parameters("table4_ablation.ipynb", "real")
    runs = notebook_runs("table4_ablation.ipynb", {**p, "every_category": True})
    cells = [(r.category, r.split, r.row["mode"]) for r in runs]
    assert len(cells) == len(set(cells))
    assert {(c, s) for c, s, _ in cells} == ({(c, s) for c in PSB_ABLATION for s in range(5)}
                                            | {(c, 0) for c in datasets.PSB_CATEGORIES})


def test_the_papers_method_runs_the_cross_of_fig11_through_its_choice():
    from anseg.study.reference import FIG11_CHOICE

    planned = planned_experiments("real", only=["fig11"], config="paper", splits=[0])
    points = {(round(1 - e.segment.ratio, 6), e.segment.cycles) for e, _ in planned}
    assert points and all(r == FIG11_CHOICE["removed"] or n == FIG11_CHOICE["cycles"] for r, n in points)
    assert len(planned) < len(planned_experiments("real", only=["fig11"], splits=[0]))  # the default runs the whole grid


def test_readme_is_a_short_entry_point_with_the_two_commands_first():
    """The README points to docs/ for the rest: under 200 lines, both commands in its first 40."""
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) < 200, f"README.md has {len(lines)} lines; move the detail to docs/"
    first = "\n".join(lines[:40])
    assert "make reproduce" in first and "make test" in first


def test_readme_headline_is_the_committed_results():
    if not (REPO / "results" / "table4_ablation.csv").is_file():
        pytest.skip("no real-run results committed yet (results/table4_ablation.csv)")
    text = (REPO / "README.md").read_text()
    block = text[text.index(HEADLINE_START) + len(HEADLINE_START):text.index(HEADLINE_END)]
    assert block.strip() == headline(REPO / "results").strip()


def test_readme_ledger_is_the_committed_results():
    from anseg.study import ledger

    text = (REPO / "README.md").read_text()
    block = text[text.index(LEDGER_START) + len(LEDGER_START) : text.index(LEDGER_END)]
    assert block.strip() == ledger.markdown(ledger.ledger(REPO / "results")).strip()


def test_headline_adds_the_mean_over_splits_when_there_are_several(tmp_path):
    import pandas as pd

    if not (REPO / "results" / "table4_ablation.csv").is_file():
        pytest.skip("no real-run results committed yet (results/table4_ablation.csv)")
    table1 = pd.read_csv(REPO / "results" / "table1_psb.csv", index_col=0)
    single = next(c for c in table1.columns if c.startswith("ours, unit area, mean of"))
    table1 = table1.rename(columns={single: "ours, unit area, mean of 3 split(s)"})
    table1["ours, unit area, mean of 3 split(s)"] = 50.0
    table1["ours, std over splits"] = 1.5
    table1.to_csv(tmp_path / "table1_psb.csv")
    (tmp_path / "table4_ablation.csv").write_text((REPO / "results" / "table4_ablation.csv").read_text())
    runs = pd.read_csv(REPO / "results" / "table4_ablation_runs.csv")
    pd.concat([runs.assign(split=s) for s in range(3)]).to_csv(tmp_path / "table4_ablation_runs.csv", index=False)
    lines = headline(tmp_path).splitlines()
    assert any(line.startswith("Table IV, downsampling ablation on PSB, the mean over 3 splits") for line in lines)
    assert any(line.startswith("Paired, per split") and "over 3 split(s)" in line for line in lines)
    header = next(line for line in lines if line.startswith("| category | ours |"))
    assert header.endswith("| ours, 3 splits | std |")
    assert next(line for line in lines if line.startswith("| **mean** |")).endswith("| 50.00 | 1.50 |")


def test_a_failed_notebook_never_replaces_its_executed_copy(tmp_path, monkeypatch, capsys):
    import papermill

    from anseg.study import reproduce

    name = next(iter(PLANS))
    executed = tmp_path / "notebooks" / name
    executed.parent.mkdir(parents=True)
    executed.write_text("the committed copy")

    def execute(source, target, **kwargs):
        Path(target).write_text("ends in an error cell")
        raise RuntimeError("the model of run x is not on this machine")

    monkeypatch.setattr(papermill, "execute_notebook", execute)
    assert reproduce.run("smoke", only=[name], out=tmp_path) == 1
    assert executed.read_text() == "the committed copy"
    assert (executed.parent / reproduce.failed_name(name)).read_text() == "ends in an error cell"
    assert "is left as it was" in capsys.readouterr().err

    monkeypatch.setattr(papermill, "execute_notebook", lambda source, target, **kwargs: Path(target).write_text("new run"))
    assert reproduce.run("smoke", only=[name], out=tmp_path) == 0
    assert executed.read_text() == "new run" and not (executed.parent / reproduce.failed_name(name)).exists()


def test_real_notebooks_run_on_one_thread_unless_told_otherwise(tmp_path, monkeypatch):
    import papermill

    from anseg.study import reproduce

    seen = []
    monkeypatch.setattr(papermill, "execute_notebook",
                        lambda source, target, **kwargs: seen.append(os.environ.get("OMP_NUM_THREADS")) or Path(target).touch())
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    reproduce.run("real", only=["explore"], out=tmp_path)
    assert seen == ["1"]
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    reproduce.run("real", only=["explore"], out=tmp_path)
    assert seen == ["1", "2"]


def test_chosen_splits_replace_the_plans_where_a_notebook_takes_several():
    everything = planned_experiments("real", ["fig11"], config="default")
    first = planned_experiments("real", ["fig11"], config="default", splits=[0])
    assert {e.split_index for e, _ in everything} == {0, 1, 2} and {e.split_index for e, _ in first} == {0}
    assert [e.key(x) for e, x in first] == [e.key(x) for e, x in everything if e.split_index == 0]
    # a notebook on one split (Fig. 4, Table III) is as planned
    assert planned_experiments("real", ["fig4", "table3"], splits=[3]) == planned_experiments("real", ["fig4", "table3"])


def test_a_real_run_on_chosen_splits_says_which_committed_outputs_it_narrows(monkeypatch, capsys):
    import papermill

    from anseg.study import reproduce

    def execute(source, target, **kwargs):
        raise RuntimeError("not run in this test")  # nothing is written: the committed copies stay

    monkeypatch.setattr(papermill, "execute_notebook", execute)
    monkeypatch.setenv("OMP_NUM_THREADS", "1")  # else the real run sets it for the rest of the test session
    assert reproduce.run("real", only=["fig11", "claims"], splits=[0]) == 2
    printed = capsys.readouterr().out
    assert "--splits 0: the committed outputs of fig11_cycles_ratio.ipynb will cover these splits alone" in printed
    assert "claims" not in printed.split("will cover")[0]


def test_a_split_the_data_lacks_is_refused_in_one_line(capsys):
    from anseg.study.reproduce import main

    with pytest.raises(SystemExit):
        main(["--data", "real", "--status", "--splits", "0", "5"])
    assert "--splits: the real data has splits 0 to 4" in capsys.readouterr().err


def test_status_counts_the_stored_runs_and_the_training_left(tmp_path, capsys):
    from anseg.study.plan import output_dirs
    from anseg.study.reproduce import main, status
    from anseg.study.store import ResultStore

    (before,) = status("smoke", ["table4"], out=tmp_path)
    assert before["stored"] == 0 and before["planned"] > 1 and before["hours_left"] is None
    experiment, extra = planned_experiments("smoke", ["table4"])[0]
    ResultStore(output_dirs("smoke", tmp_path)[1]).put({"key": experiment.key(extra), "train_seconds": 360.0})
    (after,) = status("smoke", ["table4"], out=tmp_path)
    assert after["stored"] == 1 and after["hours_left"] == pytest.approx(0.1 * (after["planned"] - 1))
    assert main(["--smoke", "--status", "--only", "table4", "claims", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("table4_ablation.ipynb") and f"1 of {after['planned']:>4} runs stored" in printed[0]
    assert printed[1].startswith("claims_ledger.ipynb") and printed[1].endswith("trains nothing")


@pytest.mark.parametrize("name", sorted(PLANS))
def test_an_executed_notebook_keeps_no_progress_bar(name):
    """An executed notebook is read, not watched: a bar's carriage returns in its outputs are noise."""
    executed = REPO / "notebooks" / "executed" / name
    if not executed.is_file():
        pytest.skip(f"no executed copy of {name} committed")
    streams = [output for cell in nbformat.read(executed, as_version=4).cells for output in cell.get("outputs", [])
               if output.get("output_type") == "stream"]
    assert not [s["text"][:80] for s in streams if "\r" in s["text"]]
