"""The experiment layer: the store, and a plan run serially, on a Dask LocalCluster, and through a killed worker."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest
import torch

from anseg.pipeline import SegmentConfig
from anseg.study.runner import run_plan
from anseg.study.store import Experiment, ResultStore
from anseg.train import TrainConfig

OPTIONS = {"n_shapes": 4}


def tiny_plan(n: int = 4, epochs: int = 2) -> list[tuple[Experiment, dict]]:
    segment = SegmentConfig(cycles=1, clusters=4)
    return [(Experiment("synthetic", "figure", 0, segment, TrainConfig(epochs=epochs, width=16, depth=1, seed=seed,
                                                                       device="cpu")), OPTIONS) for seed in range(n)]


def stored(store: ResultStore, plan) -> list[dict]:
    return [store.get(e.key(x)) for e, x in plan]


def same_numbers(a: dict, b: dict) -> bool:
    return a["accuracy"] == b["accuracy"] and a["per_mesh"] == b["per_mesh"] and a["key"] == b["key"]


def test_the_store_writes_the_model_before_the_result(tmp_path):
    store = ResultStore(tmp_path)
    store.checkpoint_path("k").parent.mkdir(parents=True)
    store.checkpoint_path("k").write_bytes(b"partial")
    back = store.put({"key": "k", "accuracy": 1.0}, b"model bytes")
    assert back == store.get("k") and store.model_path("k").read_bytes() == b"model bytes"
    assert not store.checkpoint_path("k").exists()  # the finished run's checkpoint is gone
    assert store.get("absent") is None


@pytest.mark.slow
def test_a_plan_on_a_local_cluster_matches_the_serial_run(tmp_path):
    torch.set_num_threads(1)
    plan = tiny_plan()
    serial, dask = ResultStore(tmp_path / "serial"), ResultStore(tmp_path / "dask")
    assert run_plan(plan, serial) == 0
    assert run_plan(plan, dask, workers=2) == 0
    for a, b in zip(stored(serial, plan), stored(dask, plan)):
        assert same_numbers(a, b)
    assert all(dask.model_path(e.key(x)).is_file() for e, x in plan)
    assert run_plan(plan, dask, workers=2) == 0  # everything stored: nothing runs again


@pytest.mark.slow
def test_a_worker_killed_mid_run_costs_only_that_run(tmp_path):
    from distributed import Client, LocalCluster

    torch.set_num_threads(1)
    plan = tiny_plan(epochs=6)
    serial, dask = ResultStore(tmp_path / "serial"), ResultStore(tmp_path / "dask")
    assert run_plan(plan, serial) == 0
    env = {"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, env=env, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        killed = []

        def kill_one_worker_once_it_trains():
            deadline = time.time() + 120
            while time.time() < deadline and not any(p.is_file() for p in (tmp_path / "dask" / "models").glob("*.ckpt")):
                time.sleep(0.05)
            pid = next(iter(client.run(os.getpid).values()))
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

        killer = threading.Thread(target=kill_one_worker_once_it_trains)
        killer.start()
        assert run_plan(plan, dask, scheduler=cluster.scheduler_address) == 0
        killer.join()
    assert killed, "no worker was killed"
    results = stored(dask, plan)
    assert all(r is not None for r in results)
    assert len(list((tmp_path / "dask" / "results" / "runs").glob("*.json"))) == len(plan)  # each stored once
    for a, b in zip(stored(serial, plan), results):
        assert same_numbers(a, b)


def test_the_slurm_job_script_starts_one_thread_workers_with_the_gpu_resource():
    import subprocess
    import sys

    pytest.importorskip("dask_jobqueue", reason="dask-jobqueue is the dev extra's; pip install dask-jobqueue")
    from anseg.study.store import REPO

    run = subprocess.run([sys.executable, str(REPO / "scripts" / "slurm_cluster.py"), "--print-job-script", "--gpu"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    script = run.stdout
    assert "#SBATCH --gres=gpu:1" in script and "--resources GPU=1" in script and "--nthreads 1" in script
    assert "export OMP_NUM_THREADS=1" in script and "distributed.cli.dask_worker" in script


def test_every_record_names_the_code_revision_and_whether_its_code_was_clean(tmp_path):
    import subprocess

    from anseg.study.store import REPO, code_revision, environment

    record = environment()
    assert {"code_revision", "code_clean"} <= record.keys()
    if (REPO / ".git").exists():
        head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
        assert record["code_revision"] == head
    # outside a checkout both are unknown, not guessed
    assert code_revision(tmp_path) == {"code_revision": None, "code_clean": None}
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    (tmp_path / "anseg").mkdir()
    (tmp_path / "anseg" / "m.py").write_text("x = 1\n")
    git = ["git", "-C", str(tmp_path), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "c"], check=True)
    assert code_revision(tmp_path)["code_clean"] is True
    (tmp_path / "anseg" / "m.py").write_text("x = 2\n")
    assert code_revision(tmp_path)["code_clean"] is False
