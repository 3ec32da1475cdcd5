"""scripts/replay_run.py: a stored run retrained from its recorded revision gives the same accuracy, or says why not."""

from __future__ import annotations

import csv
import importlib.util
import json

import pytest
import torch

from anseg.pipeline import SegmentConfig
from anseg.study.runner import train_and_evaluate
from anseg.study.store import REPO, Experiment, code_revision, cpu_model
from anseg.train import TrainConfig

spec = importlib.util.spec_from_file_location("replay_run", REPO / "scripts" / "replay_run.py")
replay_run = importlib.util.module_from_spec(spec)
spec.loader.exec_module(replay_run)


def _record(**environment):
    return {"key": "k", "dataset": "synthetic", "category": "figure", "split_index": 0,
            "environment": {"code_revision": "a" * 40, "code_clean": True, "cuda": None, **environment}}


def test_a_run_that_cannot_be_replayed_says_why_in_one_line(tmp_path, capsys):
    assert replay_run.why_not(_record()) is None
    assert "no code revision" in replay_run.why_not(_record(code_revision=None))
    assert "uncommitted changes" in replay_run.why_not(_record(code_clean=False))
    assert "GPU" in replay_run.why_not(_record(cuda="NVIDIA H100"))
    path = tmp_path / "run.json"
    path.write_text(json.dumps(_record(code_clean=None)))
    assert replay_run.main([str(path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert replay_run.main([str(tmp_path / "absent.json")]) == 2
    path.write_text(json.dumps(_record(code_revision="f" * 40)))  # a revision this clone does not have
    assert replay_run.main([str(path)]) == 2
    assert "cannot be checked out" in capsys.readouterr().err


def test_a_sample_spans_the_revisions_and_leaves_out_runs_that_cannot_be_replayed():
    def run(revision, clean=True):
        return {"environment": {"code_revision": revision * 40, "code_clean": clean, "cuda": None}}

    runs = {**{f"a{i}": run("a") for i in range(6)}, **{f"b{i}": run("b") for i in range(2)}, "c0": run("c", clean=False)}
    drawn = replay_run.sample(runs, 3, seed=0)
    assert len(drawn) == 3 and {k[0] for k in drawn} == {"a", "b"} and "c0" not in drawn
    assert drawn == replay_run.sample(runs, 3, seed=0) and replay_run.sample(runs, 20, seed=0).count("c0") == 0
    assert len(replay_run.sample(runs, 20, seed=0)) == 8  # every replayable run, no more


def test_versions_and_a_cpu_model_that_differ_are_named():
    assert (replay_run.version_differences({"torch": "0.0.1", "numpy": None})
            == [f"torch 0.0.1 recorded, {torch.__version__} here"])
    assert replay_run.version_differences({"cpu_model": cpu_model()}) == []
    assert (replay_run.version_differences({"cpu_model": "Another CPU"})
            == [f"cpu_model Another CPU recorded, {cpu_model()} here"])


@pytest.mark.slow
def test_a_run_replays_to_the_last_digit_at_its_revision(tmp_path, capsys, monkeypatch):
    if code_revision()["code_clean"] is not True:
        pytest.skip("the package has uncommitted changes: a run trained now records no revision to replay")
    torch.set_num_threads(1)
    experiment = Experiment("synthetic", "figure", 0, SegmentConfig(cycles=2, clusters=4), TrainConfig(epochs=2, width=32))
    result, _ = train_and_evaluate(experiment, {"n_shapes": 6})
    path = tmp_path / "run.json"
    path.write_text(json.dumps(result))
    temporary = tmp_path / "temporary"
    temporary.mkdir()
    monkeypatch.setattr(replay_run.tempfile, "tempdir", str(temporary))
    assert replay_run.main([str(path)]) == 0, capsys.readouterr()
    assert "replay holds" in capsys.readouterr().out
    assert not list(temporary.iterdir())  # the worktree and its folder are gone


def test_a_replay_reads_an_empty_feature_cache_of_its_own(tmp_path, monkeypatch):
    calls = []

    def fake_run(command, **kwargs):
        calls.append((command, kwargs))
        out = json.dumps({"key": "k", "accuracy": {}, "train_seconds": 0}) if "env" in kwargs else ""
        return type("Done", (), {"returncode": 0, "stdout": out, "stderr": ""})()

    monkeypatch.setattr(replay_run.subprocess, "run", fake_run)
    monkeypatch.setattr(replay_run.tempfile, "tempdir", str(tmp_path))
    monkeypatch.setenv("ANSEG_CACHE", str(tmp_path / "shared-cache"))
    record = {**_record(torch_threads=1), "segment": {}, "train": {}}
    replay_run.replay(record)
    (environment,) = [kwargs["env"] for _, kwargs in calls if "env" in kwargs]
    cache = environment["ANSEG_CACHE"]
    assert cache != str(tmp_path / "shared-cache") and cache.startswith(str(tmp_path)) and not list(tmp_path.iterdir())


def test_the_csv_names_the_machine_that_trained_and_the_one_that_replayed(tmp_path, monkeypatch, capsys):
    record = {**_record(cpus=2, cpu_model="Another CPU", torch="0.0.1"), "accuracy": {"unit_area": 0.5},
              "train_seconds": 1.0}
    path = tmp_path / "run.json"
    path.write_text(json.dumps(record))
    monkeypatch.setattr(replay_run, "replay", lambda run, root, keep: {"key": "k", "accuracy": {"unit_area": 0.25},
                                                                        "train_seconds": 1.0})
    table = tmp_path / "replays.csv"
    assert replay_run.main([str(path), "--csv", str(table)]) == 1
    assert "cpu_model Another CPU recorded" in capsys.readouterr().err  # said before training
    (row,) = list(csv.DictReader(table.open()))
    assert row["trained_on"] == "Another CPU, 2 cores" and row["replayed_on"] == replay_run.here()
    assert cpu_model() in row["replayed_on"] and row["holds"] == "False" and row["replayed"] == "0.25"


def test_a_retraining_stored_elsewhere_is_compared_without_training(tmp_path, monkeypatch):
    monkeypatch.setattr(replay_run, "replay", lambda *args: pytest.fail("--retrained must not train"))
    stored, retrained = tmp_path / "stored", tmp_path / "retrained"
    stored.mkdir(), retrained.mkdir()
    record = {**_record(cpus=2, cpu_model="One CPU"), "accuracy": {"unit_area": 0.5}, "train_seconds": 1.0}
    (stored / "k.json").write_text(json.dumps(record))
    table = tmp_path / "replays.csv"
    arguments = [str(stored / "k.json"), "--retrained", str(retrained), "--csv", str(table)]
    assert replay_run.main(arguments) == 2  # no retraining stored under the key
    again = {**_record(cpus=2, cpu_model="Another CPU"), "accuracy": {"unit_area": 0.25}, "train_seconds": 2.0}
    (retrained / "k.json").write_text(json.dumps(again))
    assert replay_run.main(arguments) == 1
    (row,) = list(csv.DictReader(table.open()))
    assert (row["trained_on"], row["replayed_on"], row["replayed"]) == ("One CPU, 2 cores", "Another CPU, 2 cores", "0.25")
    (retrained / "k.json").write_text(json.dumps({**again, **_record(code_revision="b" * 40)}))
    assert replay_run.main(arguments) == 2  # trained at another revision: not a replay
    (retrained / "k.json").write_text(json.dumps({**record, "environment": {**record["environment"], "cpu_model": "X"}}))
    assert replay_run.main(arguments) == 0


def test_at_trains_once_per_package_tree_and_sets_the_revisions_side_by_side(tmp_path, monkeypatch):
    trees = {"r1": "t1", "r2": "t1", "r3": "t2"}  # r1 and r2 hold the same package folder
    monkeypatch.setattr(replay_run, "code_tree", lambda revision: (revision * 20, trees[revision]))
    trained = []

    def fake_replay(run, root, keep, revision):
        trained.append(revision[:2])
        return {"key": "k", "accuracy": {"unit_area": 0.5 if revision.startswith("r1") else accuracy_r3},
                "train_seconds": 1.0}

    monkeypatch.setattr(replay_run, "replay", fake_replay)
    path = tmp_path / "run.json"
    path.write_text(json.dumps({**_record(cpus=2), "accuracy": {"unit_area": 0.4}, "train_seconds": 1.0}))
    table = tmp_path / "drift.csv"
    arguments = [str(path), "--at", "r1", "--at", "r2", "--at", "r3", "--csv", str(table)]
    accuracy_r3 = 0.5
    assert replay_run.main(arguments) == 0 and trained == ["r1", "r3"]
    rows = list(csv.DictReader(table.open()))
    assert [(row["at"][:2], row["code_tree"], row["replayed"], row["stored"]) for row in rows] == [
        ("r1", "t1", "0.5", "0.4"), ("r2", "t1", "0.5", "0.4"), ("r3", "t2", "0.5", "0.4")]
    accuracy_r3 = 0.25
    assert replay_run.main(arguments) == 1  # the revisions differ
    monkeypatch.setattr(replay_run, "code_tree", lambda revision: (_ for _ in ()).throw(LookupError("not here")))
    assert replay_run.main(arguments) == 2
    with pytest.raises(SystemExit):  # one of --at and --retrained
        replay_run.main([str(path), "--at", "r1", "--retrained", str(tmp_path)])
