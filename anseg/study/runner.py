"""Running experiments: one here (:func:`run_experiment`), or a whole plan at once (:func:`run_plan`).

:func:`train_and_evaluate` is the work of one experiment; it returns the
result and the model file's bytes and writes nothing but its checkpoint, so
it runs in this process, a pool worker or a Dask worker.
:func:`run_plan` sends many through :func:`anseg.parallel.run_parallel`, on a
process pool of this machine, a Dask ``LocalCluster`` or an existing Dask
cluster; validation studies (:mod:`anseg.study.validate`) run through the same runner.
"""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import asdict

from anseg import features
from anseg.study.store import Experiment, ResultStore, environment
from anseg.train import evaluate, fit_and_time


def train_and_evaluate(experiment: Experiment, dataset_options: dict | None = None, root=None,
                       checkpoint: str | os.PathLike | None = None, progress: bool = False) -> tuple[dict, bytes]:
    """Train on the split's training meshes and evaluate on its test meshes: the result and the model file's bytes.

    Writes nothing but ``checkpoint`` (resumed from when it holds the same
    settings), so it can run anywhere: in this process, a pool worker or a
    Dask worker.
    """
    from anseg import datasets

    dataset_options = dict(dataset_options or {})
    load = dict(category=experiment.category, split_index=experiment.split_index, root=root, progress=progress,
                **dataset_options)
    train_set = datasets.load(experiment.dataset, split="train", **load)
    test_set = datasets.load(experiment.dataset, split="test", **load)
    label_names = train_set[0].label_names
    model, train_seconds, train_cpu_seconds = fit_and_time(train_set, label_names, experiment.segment, experiment.train,
                                                           checkpoint, progress)
    started = time.time()
    scores = evaluate(model, test_set, progress=progress)
    evaluate_seconds = time.time() - started
    fit = evaluate(model, train_set, progress=False)  # bias or variance: read, not guessed
    result = {
        "key": experiment.key(dataset_options), "dataset": experiment.dataset, "category": experiment.category,
        "split_index": experiment.split_index, "dataset_options": dataset_options,
        "segment": asdict(experiment.segment), "train": asdict(experiment.train),
        "n_train": len(train_set), "n_test": len(test_set), "label_names": label_names,
        "accuracy": scores["smoothed"], "accuracy_unsmoothed": scores["unsmoothed"], "per_mesh": scores["per_mesh"],
        "train_accuracy": fit["smoothed"], "train_per_mesh": fit["per_mesh"],
        "train_seconds": train_seconds, "train_cpu_seconds": train_cpu_seconds, "evaluate_seconds": evaluate_seconds,
        "environment": environment(),
    }
    return result, model.to_bytes()


def run_experiment(experiment: Experiment, root=None, out_dir: str | os.PathLike | None = None,
                   progress: bool = True, **dataset_options) -> dict:
    """Train and evaluate one experiment here, or read its stored result; the result is returned (and stored).

    With ``out_dir`` the result and the model go to its :class:`ResultStore`
    (a checkpoint beside the model while training) and a stored result of the
    same key is returned without training again.
    """
    store = ResultStore(out_dir) if out_dir else None
    key = experiment.key(dataset_options)
    if store is not None and (stored := store.get(key)) is not None:
        return stored
    checkpoint = store.checkpoint_path(key) if store else None
    result, model = train_and_evaluate(experiment, dataset_options, root, checkpoint, progress)
    return store.put(result, model) if store else json.loads(json.dumps(result))



def _describe(experiment) -> str:
    where = "/".join(str(x) for x in (experiment.dataset, experiment.category) if x is not None)
    s = experiment.segment
    return f"{where} split {experiment.split_index} {s.mode} N={s.cycles} r={s.ratio} groups={'+'.join(s.groups)}"


def _precompute_features(plan, jobs: int) -> None:
    """Fill the feature cache for every mesh of the plan, one process pool per feature set, before training starts."""
    from anseg import datasets

    sources = {}
    for experiment, extra in plan:
        split = experiment.split_index if experiment.dataset == "synthetic" else 0  # "all" is every split's meshes
        source = (experiment.dataset, experiment.category, split, tuple(sorted(extra.items())))
        sources.setdefault(experiment.segment.groups, set()).add(source)
    for groups, wanted in sources.items():
        meshes = [m.mesh for data, category, split, extra in sorted(wanted, key=str)
                  for m in datasets.load(data, category, "all", split, progress=False, **dict(extra))]
        features.compute_many(meshes, groups, workers=jobs, progress=False)



def run_plan(plan: list[tuple[Experiment, dict]], store: ResultStore, workers: int = 1, scheduler: str | None = None,
             backend: str = "dask", stop_after: float | None = None, root=None) -> int:
    """Train (or find stored) every experiment of ``plan``; returns the number that failed.

    The runs go through :func:`anseg.parallel.run_parallel` (``backend``,
    ``workers``, ``scheduler``); each result comes back here and is stored as
    it arrives. With ``stop_after`` (seconds) no run starts after that time.
    Checkpoints are written beside the store's models, so a retried run
    continues from its checkpoint where the workers see this file system.
    """
    from anseg.parallel import GpuCall, run_parallel

    todo = [(e, x) for e, x in plan if store.get(e.key(x)) is None]
    print(f"[anseg] {len(plan)} planned runs, {len(plan) - len(todo)} already stored, {len(todo)} to train "
          f"-> {store.root}", flush=True)
    if not todo:
        return 0
    started = time.time()
    if backend != "dask" or scheduler is None:  # a local run fills the feature cache first, in parallel
        _precompute_features(todo, workers)
        print(f"[anseg] features ready after {time.time() - started:.0f} s", flush=True)
    calls = [(GpuCall(train_and_evaluate) if e.train.device.startswith("cuda") else train_and_evaluate,
              (e, x, root, str(store.checkpoint_path(e.key(x))))) for e, x in todo]
    remaining = stop_after and max(0.0, stop_after - (time.time() - started))
    failed = finished = 0
    for index, outcome in run_parallel(calls, workers, stop_after=remaining, backend=backend, scheduler=scheduler):
        experiment = todo[index][0]
        finished += 1
        if isinstance(outcome, Exception):  # report and go on: the other runs are still worth having
            failed += 1
            print(f"[anseg] {finished}/{len(todo)} FAILED {_describe(experiment)}: {outcome}", file=sys.stderr, flush=True)
            continue
        result = store.put(*outcome)
        print(f"[anseg] {finished}/{len(todo)} {_describe(experiment)}: {100 * result['accuracy']['unit_area']:.2f} % "
              f"(train {result['train_seconds']:.0f} s; {time.time() - started:.0f} s so far)", flush=True)
    if finished < len(todo):
        print(f"[anseg] stopped after {stop_after:.0f} s: {len(todo) - finished} run(s) not started", flush=True)
    return failed
