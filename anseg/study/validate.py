"""Cross-validation on TRAINING meshes: how a default is chosen (never on a test split).

    python -m anseg.study.validate --study scale --arm default --arm "relative:local_scale=relative" \\
        [--categories Hand Vase ...] [--folds 3] [--use-folds 0 1 2] [--seeds 0 1] [--workers N | --scheduler ADDRESS]
        [--ensemble]

The training meshes of one fixed PSB split (split 0 by default) are cut into ``folds`` folds
(mesh ``i`` of the training list goes to fold ``i % folds``). Every *arm* (named overrides of
:class:`SegmentConfig` and, with a ``train.`` prefix, :class:`TrainConfig`) is trained on each
fold's other meshes and scored on its held-out ones, once per seed, on :data:`DEV_SUITE` (the
weakest categories and one easy control). Only ``split="train"`` is loaded, so the test meshes
are never read (a test checks that).

Each cell (arm x category x fold x seed) is keyed like an experiment (:meth:`Experiment.key`) and
stored under ``<out>/runs/<key>.json`` as it finishes, so a study resumes where it stopped.
:data:`INFERENCE_ONLY` settings do not retrain: the cell reuses the model of the same training
settings, kept under ``<out>/models`` (not committed). The report (:mod:`anseg.study.comparison`)
gives each arm's held-out accuracy and its paired difference from the baseline with a 95 %
two-stage bootstrap interval; the rule: adopt an arm for accuracy when the interval lies above
0, and an arm that removes a defect (``--fix ARM``: labels that depend on pose, order, threads or
the machine) when it is non-inferior, the interval's lower end above -0.5 points
(:func:`anseg.study.comparison.verdict`). ``--ensemble`` also scores each arm's seeds together, their probabilities averaged
(:func:`~anseg.pipeline.segment`'s ``ensemble``), to show how much of a difference is seed
variance (``<out>/ensembles``, ``<out>/<study>_ensemble.csv``).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from anseg.configs import NAMED, overrides
from anseg.pipeline import SegmentConfig, Segmenter
from anseg.study.comparison import write_ensemble_report, write_report
from anseg.study.store import Experiment, ResultStore, environment
from anseg.train import TrainConfig, evaluate, fit_and_time

DEV_SUITE = ("Hand", "Vase", "FourLeg", "Human", "Armadillo", "Chair", "Airplane", "Bird", "Teddy")
# SegmentConfig fields that change only how a trained model segments, not the training, each with the value
# a model's key takes for it: fixed values, not the defaults, so that a new default leaves the stored models found.
INFERENCE_ONLY = {"smooth_weight": 1.0, "concave_discount": 3.0, "combine": "all", "passes": 1}
DEFAULT_OUT = Path("results", "validation")


@dataclass(frozen=True)
class Arm:
    """A named configuration: overrides of SegmentConfig and TrainConfig fields."""

    name: str
    segment: dict = field(default_factory=dict)
    train: dict = field(default_factory=dict)

    @classmethod
    def parse(cls, text: str) -> "Arm":
        """``"name:field=value,train.field=value"``, overrides of the defaults.

        An arm named after a configuration of :mod:`anseg.configs` (``paper``),
        or after one and a variant (``paper/relative``), starts from that
        configuration: ``"paper:combine=all"``, ``"paper/relative:local_scale=relative"``.
        """
        name, _, spec = text.partition(":")
        if not name:
            raise ValueError(f"arm {text!r} has no name; write name:field=value,...")
        base = name.split("/")[0]
        segment, train = overrides(base if base in NAMED else "default", spec)
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
    trained = model is None
    if trained:
        network, train_seconds, train_cpu_seconds = fit_and_time(train_set, meshes[0].label_names, segment, train,
                                                                 checkpoint, progress=False)
    else:
        network, train_seconds, train_cpu_seconds = Segmenter.load(io.BytesIO(model)), 0.0, 0.0
    scores = evaluate(network, held_out, segment, progress=False)
    fit = evaluate(network, train_set, segment, progress=False)  # its own training meshes: bias against variance
    result = {
        "key": cell.key(), "training_key": cell.training_key(), "arm": cell.arm.name, "category": cell.category,
        "fold": cell.fold, "folds": cell.folds, "seed": cell.seed, "dataset": cell.dataset,
        "split_index": cell.split_index, "segment": asdict(segment), "train": asdict(train),
        "train_meshes": [m.name for m in train_set], "held_out": [m.name for m in held_out],
        "accuracy": scores["smoothed"], "accuracy_unsmoothed": scores["unsmoothed"], "per_mesh": scores["per_mesh"],
        "train_accuracy": fit["smoothed"], "train_per_mesh": fit["per_mesh"], "trained": trained,
        "train_seconds": train_seconds, "train_cpu_seconds": train_cpu_seconds,
        "environment": environment(),
    }
    return result, (network.to_bytes() if trained else None)


def validation_store(out: str | Path) -> ResultStore:
    """A study's store: ``<out>/runs/<key>.json``, and the models under ``<out>/models/<training_key>.pt``."""
    return ResultStore(out, results="runs")


def study_cells(arms, categories, folds: int, use_folds, seeds,
                epochs=None, dataset="psb", split_index=0, options=()) -> list[Cell]:
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


def _named(result: dict, cell: Cell) -> dict:
    """A stored result under the arm name of this study: a cell's key holds its settings, not the name it ran under."""
    return {**result, "arm": cell.arm.name}


def read_results(out: str | Path, cells: list[Cell]) -> list[dict]:
    """The stored results of those cells that have one."""
    store = validation_store(out)
    return [_named(r, cell) for r, cell in ((store.get(cell.key()), cell) for cell in cells) if r is not None]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m anseg.study.validate", description=__doc__.splitlines()[0])
    parser.add_argument("--study", required=True, help="name of the study: the report goes to OUT/STUDY_*.csv")
    parser.add_argument("--arm", action="append", required=True,
                        help="NAME[:field=value,train.field=value,...]; repeat for each arm (the first is the baseline "
                             "unless --baseline says otherwise)")
    parser.add_argument("--baseline", help="the arm the others are compared with (default: the first --arm)")
    parser.add_argument("--fix", action="append", default=[], metavar="ARM",
                        help="an arm that removes a defect (pose, order, threads, machine): adopted when non-inferior, "
                             "its interval's lower end above -0.5 points, instead of above 0 (repeatable)")
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
        not_compared = sorted(set(args.fix) - ({a.name for a in arms} - {baseline}))
        if not_compared:
            raise ValueError(f"--fix names an arm that is not compared with the baseline: {', '.join(not_compared)}")
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
    print(write_report(results, baseline, args.out, args.study, tuple(args.fix)))
    if args.ensemble:
        ensembles = run_ensembles(cells, args.out, args.data, args.workers, args.scheduler, not args.quiet, args.backend)
        if ensembles:
            print(write_ensemble_report(ensembles, results, baseline, args.out, args.study))
    return 0 if len(results) == len(cells) else 1


if __name__ == "__main__":
    sys.exit(main())
