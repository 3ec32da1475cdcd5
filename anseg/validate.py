"""Cross-validation on TRAINING meshes: how a default is chosen (never on a test split).

    python -m anseg.validate --study scale --arm default --arm "relative:local_scale=relative" \\
        [--categories Hand Vase ...] [--folds 3] [--use-folds 0 1 2] [--seeds 0 1] [--workers N | --scheduler ADDRESS]
        [--ensemble]

The training meshes of one fixed PSB split (split 0 by default) are cut into
``folds`` folds (mesh ``i`` of the split's training list goes to fold
``i % folds``: 12 meshes give 3 folds of 8 train / 4 held out). Every *arm*
(a named set of overrides of :class:`SegmentConfig` and, with a ``train.``
prefix, :class:`TrainConfig`) is trained on each fold's other meshes and
scored on its held-out ones, once per seed, on a development suite of
categories (:data:`DEV_SUITE`: the weakest categories and one easy control).
The test meshes of the split are never read: only ``split="train"`` is
loaded (a test checks that).

Each cell (arm x category x fold x seed) is keyed like an experiment
(:meth:`Experiment.key`, the fold in the data options) and stored under
``<out>/runs/<key>.json`` as it finishes, so a study resumes where it stopped.
Settings that act only when a trained model segments (:data:`INFERENCE_ONLY`:
the graph cut's weight, how levels are combined, test-time passes) do not
retrain: the cell reuses the model of the same training settings, kept under ``<out>/models``
(not committed).

The report (printed, and written as CSV under ``<out>``) gives per arm and
category the mean held-out accuracy (Eq. 5, unit area, graph cut as the arm
sets it), the suite mean (the mean over categories) with the spread of that
mean over the fold x seed replicates, and for each arm against the baseline
the paired difference: per (category, fold) the mean over seeds of arm minus
baseline, averaged, with a 95 % percentile interval from a two-stage
bootstrap (categories resampled with replacement, then the folds inside each
drawn category), and what the arm's training costs: its CPU seconds over the
baseline's on the cells both trained (a cell records both its wall and its
CPU time). The decision rule: adopt when the interval excludes 0 and the
mean is positive.

``--ensemble`` also scores each arm's seeds together, their class
probabilities averaged (:func:`~anseg.pipeline.segment`'s ``ensemble``), once
every seed's model of a (category, fold) is stored: how much of a difference
is seed variance, at k trainings and k segmentations per mesh. Those scores
go under ``<out>/ensembles`` and ``<out>/<study>_ensemble.csv``.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from anseg.cache import atomic_write
from anseg.configs import NAMED, overrides
from anseg.experiments import Experiment, ResultStore, environment
from anseg.pipeline import SegmentConfig, Segmenter
from anseg.train import TrainConfig, evaluate, fit

DEV_SUITE = ("Hand", "Vase", "FourLeg", "Human", "Armadillo", "Chair", "Airplane", "Bird", "Teddy")
# SegmentConfig fields that change only how a trained model segments, not the training, each with the value
# a model's key takes for it: fixed values, not the defaults, so that a new default leaves the stored models found.
INFERENCE_ONLY = {"smooth_weight": 1.0, "concave_discount": 3.0, "combine": "all", "passes": 1}
DEFAULT_OUT = Path("results", "validation")
BOOTSTRAP_SAMPLES = 10_000
MIN_CATEGORIES = 3  # fewer give a bootstrap interval that is no interval at all


@dataclass(frozen=True)
class Arm:
    """A named configuration: overrides of SegmentConfig and TrainConfig fields."""

    name: str
    segment: dict = field(default_factory=dict)
    train: dict = field(default_factory=dict)

    @classmethod
    def parse(cls, text: str) -> "Arm":
        """``"name:field=value,train.field=value"``, overrides of the defaults.

        An arm named after a configuration of :mod:`anseg.configs` (``paper``)
        starts from that configuration: ``"paper:combine=all"``.
        """
        name, _, spec = text.partition(":")
        if not name:
            raise ValueError(f"arm {text!r} has no name; write name:field=value,...")
        segment, train = overrides(name if name in NAMED else "default", spec)
        return cls(name, segment, train)

    def configs(self, epochs: int | None = None) -> tuple[SegmentConfig, TrainConfig]:
        train = {**({"epochs": epochs} if epochs else {}), **self.train}
        return SegmentConfig(**self.segment), TrainConfig(**train)


def fold_of(n_meshes: int, n_folds: int) -> np.ndarray:
    """The fold of each of a split's training meshes: mesh i goes to fold i % n_folds."""
    if not 2 <= n_folds <= n_meshes:
        raise ValueError(f"folds must lie in 2..{n_meshes}, got {n_folds}")
    return np.arange(n_meshes) % n_folds


@dataclass(frozen=True)
class Cell:
    """One training and scoring: an arm on one fold of one category, with one seed."""

    arm: Arm
    category: str
    fold: int
    seed: int
    folds: int = 3
    epochs: int | None = None
    dataset: str = "psb"
    split_index: int = 0
    options: tuple = ()  # data set options (the synthetic generator's), as sorted (name, value) pairs

    def configs(self) -> tuple[SegmentConfig, TrainConfig]:
        segment, train = self.arm.configs(self.epochs)
        return segment, replace(train, seed=self.seed)

    def _experiment(self, segment: SegmentConfig) -> Experiment:
        return Experiment(self.dataset, self.category, self.split_index, segment, self.configs()[1])

    def _options(self) -> dict:
        return {**dict(self.options), "validation": {"folds": self.folds, "fold": self.fold}}

    def key(self) -> str:
        return self._experiment(self.configs()[0]).key(self._options())

    def training_key(self) -> str:
        """The key of the trained model: the cell's key with the inference-only settings at fixed values."""
        segment = replace(self.configs()[0], **INFERENCE_ONLY)
        return self._experiment(segment).key(self._options())

    def describe(self) -> str:
        return f"{self.arm.name} {self.category} fold {self.fold} seed {self.seed}"


def load_training_meshes(cell: Cell, root=None) -> list:
    """The training meshes of the cell's split, and only those: the test split is never read."""
    from anseg import datasets

    return datasets.load(cell.dataset, cell.category, split="train", split_index=cell.split_index, root=root,
                         progress=False, **dict(cell.options))


def compute_cell(cell: Cell, root=None, model: bytes | None = None, checkpoint: str | None = None) -> tuple[dict, bytes | None]:
    """Train one cell (or take the trained ``model`` file's bytes) and score its held-out meshes.

    Returns the result and, when it trained, the model file's bytes; writes
    nothing but ``checkpoint``, so it runs in any worker.
    """
    import io

    meshes = load_training_meshes(cell, root)
    fold = fold_of(len(meshes), cell.folds)
    train_set = [m for m, f in zip(meshes, fold) if f != cell.fold]
    held_out = [m for m, f in zip(meshes, fold) if f == cell.fold]
    segment, train = cell.configs()
    started, cpu_started = time.time(), time.process_time()
    trained = model is None
    network = (fit(train_set, meshes[0].label_names, segment, train, checkpoint, progress=False) if trained
               else Segmenter.load(io.BytesIO(model)))
    train_seconds, train_cpu_seconds = time.time() - started, time.process_time() - cpu_started
    scores = evaluate(network, held_out, segment, progress=False)
    result = {
        "key": cell.key(), "training_key": cell.training_key(), "arm": cell.arm.name, "category": cell.category,
        "fold": cell.fold, "folds": cell.folds, "seed": cell.seed, "dataset": cell.dataset,
        "split_index": cell.split_index, "segment": asdict(segment), "train": asdict(train),
        "train_meshes": [m.name for m in train_set], "held_out": [m.name for m in held_out],
        "accuracy": scores["smoothed"], "accuracy_unsmoothed": scores["unsmoothed"], "per_mesh": scores["per_mesh"],
        "trained": trained, "train_seconds": train_seconds, "train_cpu_seconds": train_cpu_seconds,
        "environment": environment(),
    }
    return result, (network.to_bytes() if trained else None)


def validation_store(out: str | Path) -> ResultStore:
    """A study's store: ``<out>/runs/<key>.json``, and the models under ``<out>/models/<training_key>.pt``."""
    return ResultStore(out, results="runs")


def study_cells(arms, categories, folds: int, use_folds, seeds, epochs=None, dataset="psb", split_index=0, options=()) -> list[Cell]:
    """Every cell of a study, arm by arm inside each category (run_study trains each model once, whatever the order)."""
    return [Cell(arm, category, fold, seed, folds, epochs, dataset, split_index, tuple(sorted(dict(options).items())))
            for seed in seeds for fold in use_folds for category in categories for arm in arms]


def run_study(cells: list[Cell], out: str | Path = DEFAULT_OUT, root=None, workers: int = 1,
              scheduler: str | None = None, progress: bool = True, backend: str = "dask", train: bool = True) -> list[dict]:
    """Run (or read back) every cell, ``workers`` at a time (or on the Dask cluster at ``scheduler``).

    ``backend="loky"``: a plain process pool, where Dask is not installed (the GPU machine).
    ``train=False``: score only the cells whose trained model is stored (a stopped study's inference-only arms).

    Results come back to this process and are stored as they arrive. Cells
    that train go first; the cells that only change how a trained model
    segments follow, with that model's bytes.
    """
    from anseg.parallel import run_parallel

    store = validation_store(out)
    results = {cell.key(): store.get(cell.key()) for cell in cells}
    for phase in ("train", "reuse") if train else ("reuse",):
        todo = [c for c in cells if results[c.key()] is None
                and (store.model_path(c.training_key()).is_file()) == (phase == "reuse")]
        if phase == "reuse":
            calls = [(compute_cell, (c, root, store.model_path(c.training_key()).read_bytes())) for c in todo]
        else:
            first = {}
            for c in todo:  # one training per model, by the first cell that needs it; its twins reuse it
                first.setdefault(c.training_key(), c)
            todo = list(first.values())
            calls = [(compute_cell, (c, root, None, str(store.checkpoint_path(c.training_key())))) for c in todo]
        for index, outcome in run_parallel(calls, workers, progress=progress, desc=f"validate ({phase})",
                                           backend=backend, scheduler=scheduler):
            if isinstance(outcome, Exception):
                print(f"[anseg] FAILED {todo[index].describe()}: {outcome}", file=sys.stderr, flush=True)
                continue
            result, model = outcome
            results[result["key"]] = store.put(result, model, model_key=result["training_key"])
    return [_named(results[c.key()], c) for c in cells if results[c.key()] is not None]


def ensemble_key(cells: list[Cell]) -> str:
    """The key of an ensemble: a hash of its member cells' keys."""
    import hashlib

    return hashlib.sha256(" ".join(sorted(c.key() for c in cells)).encode()).hexdigest()[:16]


def compute_ensemble(cells: list[Cell], models: list[bytes], root=None) -> dict:
    """Score one arm's held-out meshes of one category and fold with its seeds' models together.

    The class probabilities of the models (one per cell, same arm, category
    and fold, other seeds) are averaged before the graph cut: the control
    that says how much of a difference between arms is seed variance.
    """
    import io

    first = cells[0]
    meshes = load_training_meshes(first, root)
    held_out = [m for m, f in zip(meshes, fold_of(len(meshes), first.folds)) if f == first.fold]
    networks = [Segmenter.load(io.BytesIO(model)) for model in models]
    started = time.time()
    scores = evaluate(networks[0], held_out, first.configs()[0], progress=False, ensemble=tuple(networks[1:]))
    return {"key": ensemble_key(cells), "arm": first.arm.name, "category": first.category, "fold": first.fold,
            "seeds": [c.seed for c in cells], "members": [c.key() for c in cells],
            "held_out": [m.name for m in held_out], "accuracy": scores["smoothed"],
            "accuracy_unsmoothed": scores["unsmoothed"], "per_mesh": scores["per_mesh"],
            "segment_seconds": time.time() - started, "environment": environment()}


def run_ensembles(cells: list[Cell], out: str | Path = DEFAULT_OUT, root=None, workers: int = 1,
                  scheduler: str | None = None, progress: bool = True, backend: str = "dask") -> list[dict]:
    """Score every (arm, category, fold) of the study with all its seeds' models together; stored under ``<out>/ensembles``.

    A group lacks a score while any of its seeds' models is not stored (said once, on stderr).
    """
    from anseg.parallel import run_parallel

    models, store = validation_store(out), ResultStore(out, results="ensembles")
    groups: dict[tuple[str, str, int], list[Cell]] = {}
    for cell in cells:
        groups.setdefault((cell.arm.name, cell.category, cell.fold), []).append(cell)
    groups = {name: members for name, members in groups.items() if len(members) > 1}
    ready = {name: members for name, members in groups.items()
             if all(models.model_path(c.training_key()).is_file() for c in members)}
    if len(ready) < len(groups):
        print(f"[anseg] {len(groups) - len(ready)} of {len(groups)} ensembles lack a stored model; not scored",
              file=sys.stderr)
    results = {name: store.get(ensemble_key(members)) for name, members in ready.items()}
    todo = [name for name, result in results.items() if result is None]
    calls = [(compute_ensemble, (ready[name], [models.model_path(c.training_key()).read_bytes() for c in ready[name]], root))
             for name in todo]
    for index, outcome in run_parallel(calls, workers, progress=progress, desc="validate (ensembles)",
                                       backend=backend, scheduler=scheduler):
        if isinstance(outcome, Exception):
            print(f"[anseg] FAILED ensemble {' '.join(map(str, todo[index]))}: {outcome}", file=sys.stderr, flush=True)
            continue
        results[todo[index]] = store.put(outcome)
    return [{**r, "arm": name[0]} for name, r in results.items() if r is not None]


def ensemble_comparisons(ensembles: list[dict], results: list[dict], baseline: str) -> list[dict]:
    """Per arm, its ensemble against the mean of its single models, and against the baseline's single models.

    Paired over the (category, fold) cells, with the same two-stage bootstrap
    as :func:`paired_difference`.
    """
    singles: dict[tuple[str, str, int], list[float]] = {}
    for (arm, category, fold, _), value in accuracy_table(results).items():
        singles.setdefault((arm, category, fold), []).append(value)
    rows = []
    for arm in sorted({e["arm"] for e in ensembles}):
        seeds = max(len(e["seeds"]) for e in ensembles if e["arm"] == arm)
        name = f"{arm} x{seeds}"
        table = {(name, e["category"], e["fold"], 0): 100 * e["accuracy"]["unit_area"] for e in ensembles if e["arm"] == arm}
        for against in dict.fromkeys((arm, baseline)):
            table.update({(against, c, f, 0): float(np.mean(v)) for (a, c, f), v in singles.items() if a == against})
            rows.append({**paired_difference(table, name, against), "against": f"{against}, one model (seeds averaged)"})
    return rows


def _named(result: dict, cell: Cell) -> dict:
    """A stored result under the arm name of this study: a cell's key holds its settings, not the name it ran under."""
    return {**result, "arm": cell.arm.name}


def accuracy_table(results: list[dict]) -> dict[tuple[str, str, int, int], float]:
    """(arm, category, fold, seed) -> held-out accuracy in % (Eq. 5, unit area, as the arm segments)."""
    return {(r["arm"], r["category"], r["fold"], r["seed"]): 100 * r["accuracy"]["unit_area"] for r in results}


def paired_difference(table: dict, arm: str, baseline: str, samples: int = BOOTSTRAP_SAMPLES, seed: int = 0) -> dict:
    """Arm minus baseline over the (category, fold) cells both have, seeds averaged inside a cell.

    Returns the mean difference, its 95 % two-stage bootstrap interval
    (categories, then folds inside each category, resampled with
    replacement) and the number of categories and paired cells.
    """
    pairs: dict[str, dict[int, list[float]]] = {}
    for (name, category, fold, seed_), value in table.items():
        other = table.get((baseline, category, fold, seed_))
        if name == arm and other is not None:
            pairs.setdefault(category, {}).setdefault(fold, []).append(value - other)
    if not pairs:
        return {"arm": arm, "baseline": baseline, "mean": float("nan"), "low": float("nan"), "high": float("nan"),
                "categories": 0, "cells": 0}
    per_category = [np.array([np.mean(v) for v in folds.values()]) for folds in pairs.values()]
    mean = float(np.mean([d.mean() for d in per_category]))
    rng = np.random.default_rng(seed)
    draws = np.empty(samples)
    for b in range(samples):
        chosen = rng.integers(0, len(per_category), len(per_category))
        draws[b] = np.mean([rng.choice(per_category[c], len(per_category[c])).mean() for c in chosen])
    low, high = np.percentile(draws, [2.5, 97.5])
    return {"arm": arm, "baseline": baseline, "mean": mean, "low": float(low), "high": float(high),
            "categories": len(per_category), "cells": int(sum(len(d) for d in per_category))}


def training_cost(results: list[dict], arm: str, baseline: str) -> float:
    """The arm's training CPU seconds over the baseline's, summed over the cells both trained (NaN without any).

    CPU time of the training process, not wall time: a cell that waited
    beside other jobs, or was paused, costs what it computed.
    """
    def seconds(name):
        return {(r["category"], r["fold"], r["seed"]): r["train_cpu_seconds"] for r in results
                if r["arm"] == name and r.get("trained") and "train_cpu_seconds" in r}

    ours, theirs = seconds(arm), seconds(baseline)
    shared = ours.keys() & theirs.keys()
    if not shared:
        return float("nan")
    return sum(ours[c] for c in shared) / sum(theirs[c] for c in shared)


def seed_spread(table: dict) -> list[dict]:
    """How far each arm moves from seed to seed, over the (category, fold) cells run with two seeds or more.

    Per arm: the median and the largest range (max - min over seeds) of a
    cell's accuracy, and the range of the suite mean (categories averaged,
    each over its folds) from seed to seed, on the cells every seed has.
    """
    rows = []
    for arm in sorted({k[0] for k in table}):
        by_cell: dict[tuple[str, int], dict[int, float]] = {}
        for (name, category, fold, seed), value in table.items():
            if name == arm:
                by_cell.setdefault((category, fold), {})[seed] = value
        seeds = sorted({s for values in by_cell.values() for s in values})
        shared = {cell: values for cell, values in by_cell.items() if len(values) == len(seeds)}
        if len(seeds) < 2 or not shared:
            continue
        ranges = [max(v.values()) - min(v.values()) for v in shared.values()]
        categories = sorted({category for category, _ in shared})
        suite = [np.mean([np.mean([v[s] for (c, _), v in shared.items() if c == category]) for category in categories])
                 for s in seeds]
        rows.append({"arm": arm, "seeds": len(seeds), "cells": len(shared), "median_range": float(np.median(ranges)),
                     "max_range": float(np.max(ranges)), "suite_mean_range": float(np.ptp(suite))})
    return rows


def summarize(results: list[dict], baseline: str) -> tuple[list[dict], list[dict]]:
    """Per arm and category (and the suite mean) rows, and each arm's paired comparison with the baseline."""
    table = accuracy_table(results)
    arms = sorted({k[0] for k in table}, key=lambda a: (a != baseline, a))
    categories = sorted({k[1] for k in table})
    rows = []
    for arm in arms:
        cells = {k: v for k, v in table.items() if k[0] == arm}
        for category in categories:
            values = [v for k, v in cells.items() if k[1] == category]
            if values:
                rows.append({"arm": arm, "category": category, "mean": float(np.mean(values)),
                             "std": float(np.std(values, ddof=1)) if len(values) > 1 else float("nan"), "runs": len(values)})
        replicates = {}
        for (_, category, fold, seed), value in cells.items():
            replicates.setdefault((fold, seed), {})[category] = value
        complete = [np.mean(list(r.values())) for r in replicates.values() if len(r) == len(categories)]
        means = [row["mean"] for row in rows if row["arm"] == arm]
        rows.append({"arm": arm, "category": "suite mean", "mean": float(np.mean(means)),
                     "std": float(np.std(complete, ddof=1)) if len(complete) > 1 else float("nan"), "runs": len(cells)})
    comparisons = [{**paired_difference(table, arm, baseline), "cost": training_cost(results, arm, baseline)}
                   for arm in arms if arm != baseline]
    return rows, comparisons


def write_report(results: list[dict], baseline: str, out: str | Path, study: str) -> str:
    """Write ``<out>/<study>_accuracy.csv``, ``_paired.csv`` (and ``_seeds.csv`` with several seeds); return the report as text."""
    rows, comparisons = summarize(results, baseline)
    spread = seed_spread(accuracy_table(results))
    out = Path(out)
    for name, table in (("accuracy", rows), ("paired", comparisons), ("seeds", spread)):
        if table:
            text = csv_text(table)
            atomic_write(out / f"{study}_{name}.csv", lambda tmp, text=text: tmp.write_text(text))
    lines = [f"{'arm':<24} {'category':<12} {'mean':>7} {'std':>6} {'runs':>4}"]
    lines += [f"{r['arm']:<24} {r['category']:<12} {r['mean']:7.2f} {r['std']:6.2f} {r['runs']:4d}" for r in rows]
    if comparisons:
        lines.append(f"\npaired difference against {baseline!r} (95 % bootstrap over categories, then folds):")
        if len({r["seed"] for r in results}) == 1:
            lines.append("  (one seed: the interval leaves out the spread from seed to seed; a screen, not a verdict)")
        for c in comparisons:
            if c["categories"] < MIN_CATEGORIES:
                verdict = f"no verdict on fewer than {MIN_CATEGORIES} categories"
            else:
                verdict = "adopt" if c["low"] > 0 else ("worse" if c["high"] < 0 else "no evidence")
            cost = f"; training costs {c['cost']:.2f}x the baseline's CPU time" if np.isfinite(c["cost"]) else ""
            lines.append(f"  {c['arm']:<24} {c['mean']:+6.2f} [{c['low']:+6.2f}, {c['high']:+6.2f}] "
                         f"({c['categories']} categories, {c['cells']} cells): {verdict}{cost}")
    if spread:
        lines.append("\nfrom seed to seed (range over seeds: of one cell's accuracy, median and largest; of the suite mean):")
        lines += [f"  {r['arm']:<24} {r['median_range']:5.2f} median, {r['max_range']:5.2f} largest over {r['cells']} cells; "
                  f"suite mean {r['suite_mean_range']:5.2f} ({r['seeds']} seeds)" for r in spread]
    return "\n".join(lines)


def write_ensemble_report(ensembles: list[dict], results: list[dict], baseline: str, out: str | Path, study: str) -> str:
    """Write ``<out>/<study>_ensemble.csv`` (:func:`ensemble_comparisons`); return it as text."""
    rows = ensemble_comparisons(ensembles, results, baseline)
    text = csv_text(rows)
    atomic_write(Path(out) / f"{study}_ensemble.csv", lambda tmp: tmp.write_text(text))
    lines = ["\nseeds together (class probabilities averaged), paired over categories x folds:"]
    lines += [f"  {r['arm']:<16} against {r['against']:<36} {r['mean']:+6.2f} [{r['low']:+6.2f}, {r['high']:+6.2f}] "
              f"({r['categories']} categories, {r['cells']} cells)" for r in rows]
    return "\n".join(lines)


def csv_text(rows: list[dict]) -> str:
    """Rows of dicts as CSV text (floats with 4 decimals), the header from the first row."""
    import io

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows([{k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in row.items()} for row in rows])
    return buffer.getvalue()


def read_results(out: str | Path, cells: list[Cell]) -> list[dict]:
    """The stored results of those cells that have one."""
    store = validation_store(out)
    return [_named(r, cell) for r, cell in ((store.get(cell.key()), cell) for cell in cells) if r is not None]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="anseg validate", description=__doc__.splitlines()[0])
    parser.add_argument("--study", required=True, help="name of the study: the report goes to OUT/STUDY_*.csv")
    parser.add_argument("--arm", action="append", required=True,
                        help="NAME[:field=value,train.field=value,...]; repeat for each arm (the first is the baseline "
                             "unless --baseline says otherwise)")
    parser.add_argument("--baseline", help="the arm the others are compared with (default: the first --arm)")
    parser.add_argument("--categories", nargs="+", default=list(DEV_SUITE), help="default: the development suite")
    parser.add_argument("--folds", type=int, default=3, help="folds of the split's training meshes (default: 3)")
    parser.add_argument("--use-folds", type=int, nargs="+", help="which folds to run (default: all)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--epochs", type=int, help="training epochs (default: TrainConfig's)")
    parser.add_argument("--split", type=int, default=0, help="the fixed PSB split whose TRAINING meshes are used (default: 0)")
    parser.add_argument("--dataset", default="psb")
    parser.add_argument("--workers", type=int, default=1,
                        help="cells trained side by side, one Dask worker process of one thread each (default: 1)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler (tcp://HOST:8786) to send the cells to")
    parser.add_argument("--backend", choices=["dask", "loky"], default="dask",
                        help="Dask (default), or a plain process pool where Dask is not installed")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"result store and report folder (default: {DEFAULT_OUT})")
    parser.add_argument("--data", help="data root (default: $ANSEG_DATA)")
    parser.add_argument("--report-only", action="store_true", help="write the report from the stored cells, train nothing")
    parser.add_argument("--no-train", action="store_true",
                        help="train nothing; score the cells whose model is stored (e.g. graph-cut arms of a stopped study)")
    parser.add_argument("--ensemble", action="store_true",
                        help="also score each arm's seeds together (class probabilities averaged; needs their models "
                             "stored): how much of a difference is seed variance")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    try:
        arms = [Arm.parse(text) for text in args.arm]
        for arm in arms:
            arm.configs(args.epochs)  # a bad value fails here, before any training
        if len({a.name for a in arms}) != len(arms):
            raise ValueError("arm names must differ")
        baseline = args.baseline or arms[0].name
        if baseline not in {a.name for a in arms}:
            raise ValueError(f"baseline {baseline!r} is not among the arms")
        if args.workers < 1:
            raise ValueError("--workers must be at least 1")
        if args.ensemble and len(args.seeds) < 2:
            raise ValueError("--ensemble needs two seeds or more")
        if args.scheduler and args.backend != "dask":
            raise ValueError("--scheduler needs the dask backend")
        use_folds = args.use_folds if args.use_folds is not None else list(range(args.folds))
        if any(not 0 <= f < args.folds for f in use_folds):
            raise ValueError(f"--use-folds must lie in 0..{args.folds - 1}")
        fold_of(12 if args.dataset == "psb" else args.folds, args.folds)
    except ValueError as exc:
        parser.error(str(exc))
    cells = study_cells(arms, args.categories, args.folds, use_folds, args.seeds, args.epochs, args.dataset, args.split)
    if args.report_only:
        results = read_results(args.out, cells)
    else:
        results = run_study(cells, args.out, args.data, args.workers, args.scheduler, progress=not args.quiet,
                            backend=args.backend, train=not args.no_train)
    if not results:
        print("no results stored for this study yet", file=sys.stderr)
        return 1
    print(write_report(results, baseline, args.out, args.study))
    if args.ensemble:
        ensembles = run_ensembles(cells, args.out, args.data, args.workers, args.scheduler, not args.quiet, args.backend)
        if ensembles:
            print(write_ensemble_report(ensembles, results, baseline, args.out, args.study))
    return 0 if len(results) == len(cells) else 1


if __name__ == "__main__":
    sys.exit(main())
