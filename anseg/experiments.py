"""The experiment layer: what an experiment is, where its result is kept, the plan of the notebooks, and running many.

* :class:`Experiment` and its key: one trained-and-evaluated configuration,
  keyed by everything that decides its result.
* :class:`ResultStore`: ``<root>/results/runs/<key>.json`` and
  ``<root>/models/<key>.pt``, written atomically by the process that asked
  for the run (never by a worker, so workers need no file system shared
  with it), with a resumable checkpoint beside the model while training.
* :func:`train_and_evaluate`: the work of one experiment; it returns the
  result and the model file's bytes and writes nothing but its checkpoint.
* The plan: the notebooks' parameters (:data:`COMMON`, :data:`PER_NOTEBOOK`)
  and every experiment they ask for (:func:`planned_experiments`).
* :func:`run_plan`: many experiments at once through
  :func:`anseg.parallel.run_parallel`, on a process pool of this machine, a
  Dask ``LocalCluster`` or an existing Dask cluster; validation studies
  (:mod:`anseg.validate`) run through the same runner.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from anseg import features
from anseg.cache import atomic_write
from anseg.pipeline import DOWNSAMPLING_MODES, SegmentConfig
from anseg.train import TrainConfig, evaluate, fit_and_time

REPO = Path(__file__).resolve().parent.parent

# Fields of SegmentConfig ("segment") and TrainConfig ("train") introduced after results were stored, with
# the value the older results ran with: at that value a field stays out of the key.
SETTINGS_ADDED_LATER = {
    "segment": {"once_per_pass": False, "local_scale": "unit_area", "priority": "score", "density_range": float("inf"),
                "concave_discount": 3.0, "passes": 1},
    "train": {"embed_norm": False, "schedule": "constant", "coarse_context": False, "detach_share": False,
              "average_last": 0, "position_pairs": 0, "diffusion_blocks": 0,
              "heat_bias_pairs": 0},
}
# The feature code every stored result ran with: its version and FeatureSettings' defaults. A result computed
# from other features has other keys, so no stored result or model is reused across a change of features.
FEATURES_OF_STORED_RESULTS = {"version": 1, "sdf_rays": 16, "sdf_cone_degrees": 120.0, "agd_sources": 64,
                              "smooth_radii": (0.03, 0.1, 0.3)}


@dataclass
class Experiment:
    """One trained-and-evaluated configuration: what a table cell is made of."""

    dataset: str
    category: str | None
    split_index: int = 0
    segment: SegmentConfig = field(default_factory=SegmentConfig)
    train: TrainConfig = field(default_factory=TrainConfig)

    def key(self, dataset_options: dict | None = None) -> str:
        """A short hash of everything that decides the result, data set options (e.g. ``n_shapes``) included.

        Settings added after results were stored leave the key alone at their
        default (:data:`SETTINGS_ADDED_LATER`), so those results keep their keys;
        so does the feature code they ran with (:data:`FEATURES_OF_STORED_RESULTS`).
        """
        keyed = {part: {k: v for k, v in asdict(config).items() if SETTINGS_ADDED_LATER[part].get(k, object()) != v}
                 for part, config in (("segment", self.segment), ("train", self.train))}
        if (code := features.code()) != FEATURES_OF_STORED_RESULTS:
            keyed["features"] = code
        text = json.dumps({"dataset": self.dataset, "category": self.category, "split": self.split_index, **keyed,
                           **({"options": dataset_options} if dataset_options else {})}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def environment() -> dict:
    """Versions, hardware (and the torch threads a replay needs), the code revision, the features' fingerprint and the
    date (UTC), kept with every result."""
    from datetime import datetime, timezone

    import sklearn
    import trimesh

    return {
        "python": platform.python_version(), "torch": torch.__version__, "numpy": np.__version__,
        "trimesh": trimesh.__version__, "scikit-learn": sklearn.__version__,
        "machine": platform.machine(), "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(), "torch_threads": torch.get_num_threads(),
        "torch_kernels": torch.backends.cpu.get_cpu_capability(),  # another instruction set rounds otherwise
        "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        **code_revision(), "features": features.fingerprint(),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def code_revision(root: Path = REPO) -> dict:
    """The git commit the package runs from and whether its code differs from it (None for both outside a checkout).

    ``code_clean`` looks at the tracked files of the package and its build
    file only: a study writes its results into the same checkout, and those
    writes change no code.
    """
    import subprocess

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    revision = git("rev-parse", "HEAD")
    changes = git("status", "--porcelain", "--untracked-files=no", "--", "anseg", "pyproject.toml") if revision else None
    return {"code_revision": revision, "code_clean": None if changes is None else not changes}


def trained_on(result: dict) -> str:
    """The machine a stored result was trained on: its GPU, else its CPU count (a notebook may read results made elsewhere)."""
    env = result["environment"]
    return env["cuda"] or f"CPU, {env['cpus']} cores"


class ResultStore:
    """Results (under ``results``, relative to the root) and models (under ``models``); every write is atomic."""

    def __init__(self, root: str | os.PathLike, results: str = "results/runs"):
        self.root = Path(root)
        self.results = self.root / results

    def result_path(self, key: str) -> Path:
        return self.results / f"{key}.json"

    def model_path(self, key: str) -> Path:
        return self.root / "models" / f"{key}.pt"

    def checkpoint_path(self, key: str) -> Path:
        return self.model_path(key).with_suffix(".ckpt")

    def get(self, key: str) -> dict | None:
        """The stored result of ``key``, or None."""
        path = self.result_path(key)
        return json.loads(path.read_text()) if path.is_file() else None

    def put(self, result: dict, model: bytes | None = None, model_key: str | None = None) -> dict:
        """Store a result and its model file's bytes (under ``model_key``, default the result's key).

        The model goes first, so a stored result always has its model.
        """
        model_key = model_key or result["key"]
        if model is not None:
            atomic_write(self.model_path(model_key), lambda tmp: tmp.write_bytes(model))
            self.checkpoint_path(model_key).unlink(missing_ok=True)
        text = json.dumps(result, indent=1)
        atomic_write(self.result_path(result["key"]), lambda tmp: tmp.write_text(text))
        return json.loads(text)  # the form a stored result is read back in


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


# Parameters shared by every notebook, per run kind. Notebook-specific ones follow.
# ``config`` names the configuration of anseg.configs that every run of the notebooks starts from: the validated
# default. Until a notebook's runs under it are all stored, its committed executed copy still shows the runs it
# last read (`v1`, the defaults before cross-validation; its record names them), and `--status` says what is left.
COMMON = {
    "real": {"dataset": "psb", "config": "default", "epochs": 60, "seed": 0, "device": "auto", "smoke": False},
    "synthetic": {"dataset": "synthetic", "config": "default", "epochs": 12, "seed": 0, "device": "auto", "smoke": False},
    "smoke": {"dataset": "synthetic", "config": "default", "epochs": 2, "seed": 0, "device": "cpu", "smoke": True},
}

SYNTHETIC_CATEGORIES = ["figure", "vessel"]
PSB_ABLATION = ["Human", "Teddy", "Airplane"]
OWN_FEATURES = "configuration's own"  # Fig. 12's fifth set: the groups of the configuration the runs start from
PLAIN_READING = "paper"  # Table I's column of the paper's method as written (anseg.configs)
RECORD_CONFIGURATION = "v1"  # the column kept for the record (Tables I-III): the configuration the first study ran
# explore.ipynb: segment the category's first test mesh with a model trained here, statically rendered;
# a user points mesh_path / model_path at their own files and sets interactive for a trame view.
EXPLORE_DEFAULTS = {"mesh_path": None, "model_path": None, "interactive": False}

PER_NOTEBOOK = {
    "table1_psb.ipynb": {
        "real": {"categories": None, "splits": [0, 1, 2, 3, 4]},
        "synthetic": {"categories": SYNTHETIC_CATEGORIES, "splits": [0, 1]},
        "smoke": {"categories": ["figure"], "splits": [0]},
    },
    "table2_coseg.ipynb": {
        "real": {"dataset": "coseg", "categories": ["coseg_aliens", "coseg_chairs", "coseg_vases"]},
        "synthetic": {"categories": SYNTHETIC_CATEGORIES},
        "smoke": {"categories": ["vessel"]},
    },
    "table3_human.ipynb": {
        "real": {"dataset": "human_seg", "category": None},
        "synthetic": {"dataset": "synthetic", "category": "figure"},
        "smoke": {"dataset": "synthetic", "category": "figure"},
    },
    "table4_ablation.ipynb": {
        "real": {"categories": PSB_ABLATION, "splits": [0, 1, 2, 3, 4]},
        "synthetic": {"categories": SYNTHETIC_CATEGORIES, "splits": [0, 1]},
        "smoke": {"categories": ["figure"], "splits": [0]},
    },
    "fig12_features.ipynb": {
        "real": {"categories": PSB_ABLATION, "splits": [0, 1, 2, 3, 4]},
        "synthetic": {"categories": ["figure"], "splits": [0]},
        "smoke": {"categories": ["figure"], "splits": [0]},
    },
    # ``removed``: per category, the paper's downsampling ratios (the share of faces a cycle removes)
    "fig11_cycles_ratio.ipynb": {
        "real": {"categories": ["Airplane", "Human"], "cycles_list": [1, 2, 3, 4, 5, 6],
                 "removed": {"Airplane": [0.3, 0.4, 0.5, 0.6, 0.7], "Human": [0.5]}, "splits": [0, 1, 2]},
        "synthetic": {"categories": ["figure"], "cycles_list": [1, 2, 4], "removed": {"figure": [0.3, 0.5, 0.7]},
                      "splits": [0]},
        "smoke": {"categories": ["figure"], "cycles_list": [1, 2], "removed": {"figure": [0.5]}, "splits": [0]},
    },
    "fig4_attention.ipynb": {
        "real": {"category": "Human"},
        "synthetic": {"category": "figure"},
        "smoke": {"category": "figure"},
    },
    "explore.ipynb": {
        "real": {"category": "Teddy", **EXPLORE_DEFAULTS},
        "synthetic": {"category": "figure", **EXPLORE_DEFAULTS},
        "smoke": {"category": "figure", **EXPLORE_DEFAULTS},
    },
    # last: it reads what the others wrote
    "claims_ledger.ipynb": {"real": {}, "synthetic": {}, "smoke": {}},
}


# Table IV's rows: (SegmentConfig overrides, TrainConfig overrides). "none" is the paper's row: the attention
# module and the downsampling removed, a per-face classifier on the same features (depth 0) plus the graph cut;
# "none, transformer" is our network on the input mesh alone, a stronger control the paper does not have.
TABLE_IV_ROWS = {
    "nonuniform": ({"mode": "nonuniform"}, {}),
    "uniform": ({"mode": "uniform"}, {}),
    "none": ({"mode": "none"}, {"depth": 0}),
    "none, transformer": ({"mode": "none"}, {}),
}


def notebook_settings(p: dict) -> tuple[dict, dict, TrainConfig]:
    """Data set options, SegmentConfig overrides and TrainConfig of a notebook run with parameters ``p``.

    The settings start from the named configuration ``p["config"]``
    (:mod:`anseg.configs`). A smoke run only checks that a notebook runs from
    end to end: 4 shapes, a tiny model, 2 cycles.
    """
    from anseg.configs import overrides

    segment_options, train_options = overrides(p["config"])
    shape_options = {"n_shapes": 4} if p["smoke"] else {}
    segment_options = {**segment_options, **({"cycles": 2, "clusters": 4} if p["smoke"] else {})}
    train = TrainConfig(**{**train_options, "epochs": p["epochs"], "seed": p["seed"], "device": p["device"],
                           **({"width": 16, "depth": 1} if p["smoke"] else {})})
    return shape_options, segment_options, train


@dataclass(frozen=True)
class PlannedRun:
    """One run a notebook asks for: the table row it fills (``row``) and what to train.

    ``segment`` and ``train`` override the notebook's SegmentConfig and
    TrainConfig (:func:`notebook_settings`).
    """

    row: dict
    dataset: str
    category: str | None
    split: int = 0
    segment: dict = field(default_factory=dict)
    train: dict = field(default_factory=dict)


def notebook_parameters(name: str, kind: str) -> dict:
    """The parameters a notebook runs with for a run kind (``output_dir`` aside), ``categories=None`` resolved."""
    return resolve_categories({**COMMON[kind], **PER_NOTEBOOK[name][kind]})


def with_choices(p: dict, config: str | None = None, splits: list[int] | None = None) -> dict:
    """A notebook's parameters with a named configuration and, where it takes ``splits``, the splits chosen instead of the plan's."""
    return {**p, **({"config": config} if config else {}), **({"splits": list(splits)} if splits and "splits" in p else {})}


def resolve_categories(p: dict) -> dict:
    """``categories=None`` means every category of the data set."""
    from anseg import datasets
    from anseg.datasets import synthetic

    if "categories" in p and p["categories"] is None:
        p = {**p, "categories": list(synthetic.CATEGORIES if p["dataset"] == "synthetic" else datasets.PSB_CATEGORIES)}
    return p


def notebook_runs(name: str, p: dict) -> list[PlannedRun]:
    """Every run notebook ``name`` asks for with parameters ``p``, in the order its tables list them.

    The one declaration of the plan: the notebooks loop over it and
    :func:`planned_experiments` trains it.
    """
    from anseg import datasets
    from anseg.features import ABLATION_SETS

    dataset, categories = p["dataset"], resolve_categories(p).get("categories")
    if name == "table1_psb.ipynb":  # split by split: each finishes whole; then the plain reading on the first split
        from anseg.configs import overrides

        plain = overrides(PLAIN_READING)
        return ([PlannedRun({"category": c, "split": s}, dataset, c, s) for s in p["splits"] for c in categories]
                + [PlannedRun({"category": c, "split": p["splits"][0], "configuration": PLAIN_READING}, dataset, c,
                              p["splits"][0], *plain) for c in categories])
    if name == "table2_coseg.ipynb":  # a MeshCNN distribution (coseg_aliens, ...) is a data set of its own
        return [PlannedRun({"set": c}, *((c, None) if c in datasets.DATASETS else (dataset, c))) for c in categories]
    if name == "table3_human.ipynb":
        return [PlannedRun({}, dataset, p["category"])]
    if name == "table4_ablation.ipynb":  # split by split, as Table I
        return [PlannedRun({"category": c, "split": s, "mode": row}, dataset, c, s, *TABLE_IV_ROWS[row])
                for s in p["splits"] for c in categories for row in TABLE_IV_ROWS]
    if name == "fig11_cycles_ratio.ipynb":  # SegmentConfig.ratio is the share kept: 1 - the paper's ratio
        return [PlannedRun({"category": c, "split": s, "removed": r, "cycles": n}, dataset, c, s,
                           {"cycles": n, "ratio": round(1 - r, 6)})
                for s in p["splits"] for c in categories for r in p["removed"][c] for n in p["cycles_list"]]
    if name == "fig12_features.ipynb":  # the paper's four sets, then the configuration's own (Table I's run)
        sets = {**ABLATION_SETS, OWN_FEATURES: tuple(SegmentConfig(**notebook_settings(p)[1]).groups)}
        return [PlannedRun({"category": c, "split": s, "features": f}, dataset, c, s, {"groups": g})
                for s in p["splits"] for c in categories for f, g in sets.items()]
    if name == "fig4_attention.ipynb":  # the three modes, and the paper's unsupervised attention (Table I's run)
        from anseg.configs import overrides

        plain_segment, plain_train = overrides(PLAIN_READING)
        return ([PlannedRun({"mode": m}, dataset, p["category"], 0, {"mode": m}) for m in DOWNSAMPLING_MODES]
                + [PlannedRun({"mode": "nonuniform", "configuration": PLAIN_READING}, dataset, p["category"], 0,
                              plain_segment, plain_train)])
    if name == "explore.ipynb":  # a model of the user's, or a shipped one, needs no training
        return [] if p.get("model_path") or explore_model_name(p) else [PlannedRun({}, dataset, p["category"])]
    if name == "claims_ledger.ipynb":  # trains nothing: reads the other notebooks' results
        return []
    raise ValueError(f"no plan for notebook {name}")


def explore_model_name(p: dict) -> str | None:
    """The shipped model explore.ipynb uses for its data set and category (:mod:`anseg.pretrained`), or None.

    Only one trained with the notebook's configuration: a shipped model is
    never shown under another configuration's name.
    """
    from anseg import pretrained

    name = f"{p['dataset']}/{p['category']}" if p["dataset"] == "psb" else p["category"]
    shipped = pretrained.cards().get(name)
    return name if shipped and shipped["configuration"]["name"] == p["config"] else None


def planned_experiment(run: PlannedRun, p: dict) -> tuple[Experiment, dict]:
    """The Experiment of a planned run under a notebook's parameters ``p``, and its data set options."""
    from dataclasses import replace

    shape_options, segment_options, train = notebook_settings(p)
    experiment = Experiment(run.dataset, run.category, run.split, SegmentConfig(**{**segment_options, **run.segment}),
                            replace(train, **run.train))
    return experiment, (shape_options if run.dataset == "synthetic" else {})


def planned_experiments(kind: str, only: list[str] | None = None, config: str | None = None,
                        splits: list[int] | None = None) -> list[tuple[Experiment, dict]]:
    """Every (Experiment, data set options) the notebooks of ``kind`` train, without repeats.

    In notebook order, and inside a notebook the costliest runs first; with
    ``config``, from that named configuration instead of the run kind's; with
    ``splits``, on those splits in the notebooks that take several.
    """
    plan = {}
    for name in selected_notebooks(only):
        p = with_choices(notebook_parameters(name, kind), config, splits)
        # costliest first: attention-driven runs collapse every few epochs, "none" never does
        runs = sorted(notebook_runs(name, p), key=lambda run: DOWNSAMPLING_MODES.index(run.segment.get("mode", "nonuniform")))
        for run in runs:
            experiment, extra = planned_experiment(run, p)
            plan.setdefault(experiment.key(extra), (experiment, extra))
    return list(plan.values())


def selected_notebooks(only: list[str] | None) -> list[str]:
    return [n for n in PER_NOTEBOOK if not only or any(o in n for o in only)]


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


def output_dirs(kind: str, out: Path | None) -> tuple[Path, Path]:
    """Where executed notebooks and the result store (figures, results, models) go for a run kind."""
    if kind == "real" and out is None:
        return REPO / "notebooks" / "executed", REPO
    base = out or REPO / "runs" / kind
    return base / "notebooks", base


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
