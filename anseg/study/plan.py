"""The notebooks' plan: each notebook's parameters per run kind and the runs it asks for, declared once, by name.

A notebook is registered with :func:`notebook` beside the function that
lists its runs (:class:`PlannedRun`: the table row it fills and what to
train), in the order :mod:`anseg.study.reproduce` runs them. The notebooks
loop over the same runs, and :func:`planned_experiments` trains them, so
adding a notebook is one registration here and nothing else.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from anseg.pipeline import DOWNSAMPLING_MODES, SegmentConfig
from anseg.study.store import REPO, Experiment
from anseg.train import TrainConfig

# Parameters shared by every notebook, per run kind. Notebook-specific ones follow.
# ``config`` names the configuration of anseg.configs that every run of the notebooks starts from: the validated
# default.
COMMON = {
    "real": {"dataset": "psb", "config": "default", "epochs": 60, "seed": 0, "device": "auto", "smoke": False},
    "synthetic": {"dataset": "synthetic", "config": "default", "epochs": 12, "seed": 0, "device": "auto", "smoke": False},
    "smoke": {"dataset": "synthetic", "config": "default", "epochs": 2, "seed": 0, "device": "cpu", "smoke": True},
}

SYNTHETIC_CATEGORIES = ["figure", "vessel"]
PSB_ABLATION = ["Human", "Teddy", "Airplane"]
OWN_FEATURES = "configuration's own"  # Fig. 12's fifth set: the groups of the configuration the runs start from
PLAIN_READING = "paper"  # Table I's column of the paper's method as written (anseg.configs)
# the configurations kept for the record (Tables I-III), each a column beside ours read from the store, never retrained:
# the one the first study ran; a default that is replaced joins them under a name of its own, its runs keeping their keys
RECORD_CONFIGURATIONS = ("v1",)
# explore.ipynb: segment the category's first test mesh with a model trained here, statically rendered;
# a user points mesh_path / model_path at their own files and sets interactive for a trame view.
EXPLORE_DEFAULTS = {"mesh_path": None, "model_path": None, "interactive": False}

# Table IV's rows: (SegmentConfig overrides, TrainConfig overrides). "none" is the paper's row: the attention
# module and the downsampling removed, a per-face classifier on the same features (depth 0) plus the graph cut;
# "none, transformer" is our network on the input mesh alone, a stronger control the paper does not have.
TABLE_IV_ROWS = {
    "nonuniform": ({"mode": "nonuniform"}, {}),
    "uniform": ({"mode": "uniform"}, {}),
    "none": ({"mode": "none"}, {"depth": 0}),
    "none, transformer": ({"mode": "none"}, {}),
}


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


@dataclass(frozen=True)
class Notebook:
    """A registered notebook: its parameters per run kind (beside :data:`COMMON`) and the runs they ask for."""

    parameters: dict[str, dict]
    runs: Callable[[dict], list[PlannedRun]]


PLANS: dict[str, Notebook] = {}  # by notebook name, in the order they run


def notebook(name: str, real: dict, synthetic: dict, smoke: dict):
    """Register notebook ``name`` with its parameters per run kind; decorates the function that lists its runs."""
    def register(runs: Callable[[dict], list[PlannedRun]]):
        PLANS[name] = Notebook({"real": real, "synthetic": synthetic, "smoke": smoke}, runs)
        return runs

    return register


@notebook("table1_psb.ipynb", real={"categories": None, "splits": [0, 1, 2, 3, 4]},
          synthetic={"categories": SYNTHETIC_CATEGORIES, "splits": [0, 1]},
          smoke={"categories": ["figure"], "splits": [0]})
def _table1(p: dict) -> list[PlannedRun]:
    """Split by split (each finishes whole), then the paper's method as written on the first split."""
    from anseg.configs import overrides

    plain, first = overrides(PLAIN_READING), p["splits"][0]
    return ([PlannedRun({"category": c, "split": s}, p["dataset"], c, s) for s in p["splits"] for c in p["categories"]]
            + [PlannedRun({"category": c, "split": first, "configuration": PLAIN_READING}, p["dataset"], c, first,
                          *plain) for c in p["categories"]])


@notebook("table2_coseg.ipynb",
          real={"dataset": "coseg", "categories": ["coseg_aliens", "coseg_chairs", "coseg_vases"]},
          synthetic={"categories": SYNTHETIC_CATEGORIES}, smoke={"categories": ["vessel"]})
def _table2(p: dict) -> list[PlannedRun]:
    """A MeshCNN distribution (coseg_aliens, ...) is a data set of its own."""
    from anseg import datasets

    return [PlannedRun({"set": c}, *((c, None) if c in datasets.DATASETS else (p["dataset"], c)))
            for c in p["categories"]]


@notebook("table3_human.ipynb", real={"dataset": "human_seg", "category": None},
          synthetic={"dataset": "synthetic", "category": "figure"}, smoke={"dataset": "synthetic", "category": "figure"})
def _table3(p: dict) -> list[PlannedRun]:
    return [PlannedRun({}, p["dataset"], p["category"])]


def papers_method_file(name: str) -> str:
    """Where a notebook writes the runs of the paper's configuration it read beside its own (``<name>_paper.csv``),
    for the claims ledger to judge the paper's claims on."""
    return f"{name.removesuffix('.csv')}_{PLAIN_READING}.csv"


def table4_rows(config: str) -> list[str]:
    """Table IV's rows a configuration runs: the paper's method as written, only the three the paper has."""
    return [row for row in TABLE_IV_ROWS if config != PLAIN_READING or row != "none, transformer"]


@notebook("table4_ablation.ipynb", real={"categories": PSB_ABLATION, "splits": [0, 1, 2, 3, 4], "every_category": False},
          synthetic={"categories": SYNTHETIC_CATEGORIES, "splits": [0, 1], "every_category": False},
          smoke={"categories": ["figure"], "splits": [0], "every_category": True})
def _table4(p: dict) -> list[PlannedRun]:
    """Split by split, as Table I; with ``every_category``, also split 0 (the clean test) of every other category
    of the data set, for the claim read over every category."""
    others = [c for c in dataset_categories(p["dataset"]) if c not in p["categories"]] if p["every_category"] else []
    units = [(c, s) for s in p["splits"] for c in p["categories"]] + [(c, 0) for c in others]
    return [PlannedRun({"category": c, "split": s, "mode": row}, p["dataset"], c, s, *TABLE_IV_ROWS[row])
            for c, s in units for row in table4_rows(p["config"])]


@notebook("fig12_features.ipynb", real={"categories": PSB_ABLATION, "splits": [0, 1, 2, 3, 4]},
          synthetic={"categories": ["figure"], "splits": [0]}, smoke={"categories": ["figure"], "splits": [0]})
def _fig12(p: dict) -> list[PlannedRun]:
    """The paper's four sets, then the configuration's own (Table I's run); the paper's method as written, the four."""
    from anseg.features import ABLATION_SETS

    own = {} if p["config"] == PLAIN_READING else {OWN_FEATURES: tuple(SegmentConfig(**notebook_settings(p)[1]).groups)}
    sets = {**ABLATION_SETS, **own}
    return [PlannedRun({"category": c, "split": s, "features": f}, p["dataset"], c, s, {"groups": g})
            for s in p["splits"] for c in p["categories"] for f, g in sets.items()]


# ``removed``: per category, the paper's downsampling ratios (the share of faces a cycle removes)
@notebook("fig11_cycles_ratio.ipynb",
          real={"categories": ["Airplane", "Human"], "cycles_list": [1, 2, 3, 4, 5, 6],
                "removed": {"Airplane": [0.3, 0.4, 0.5, 0.6, 0.7], "Human": [0.5]}, "splits": [0, 1, 2]},
          synthetic={"categories": ["figure"], "cycles_list": [1, 2, 4], "removed": {"figure": [0.3, 0.5, 0.7]},
                     "splits": [0]},
          smoke={"categories": ["figure"], "cycles_list": [1, 2], "removed": {"figure": [0.5]}, "splits": [0]})
def _fig11(p: dict) -> list[PlannedRun]:
    """SegmentConfig.ratio is the share kept: 1 - the paper's ratio.

    The paper's method as written runs the cross through the paper's choice
    (every N at its share removed, every share at its N), not the whole grid.
    """
    from anseg.study.reference import FIG11_CHOICE

    def wanted(r, n):
        return p["config"] != PLAIN_READING or r == FIG11_CHOICE["removed"] or n == FIG11_CHOICE["cycles"]

    return [PlannedRun({"category": c, "split": s, "removed": r, "cycles": n}, p["dataset"], c, s,
                       {"cycles": n, "ratio": round(1 - r, 6)})
            for s in p["splits"] for c in p["categories"] for r in p["removed"][c] for n in p["cycles_list"] if wanted(r, n)]


@notebook("fig4_attention.ipynb", real={"category": "Human", "model_splits": [0]},
          synthetic={"category": "figure", "model_splits": [0]}, smoke={"category": "figure", "model_splits": [0]})
def _fig4(p: dict) -> list[PlannedRun]:
    """Split 0's three modes (Figs. 4 and 10), and per split of ``model_splits`` the two nonuniform models the
    claims read: the configuration's and the paper's unsupervised attention (Table I's runs)."""
    from anseg.configs import overrides

    plain_segment, plain_train = overrides(PLAIN_READING)
    return ([PlannedRun({"mode": m, "split": 0}, p["dataset"], p["category"], 0, {"mode": m}) for m in DOWNSAMPLING_MODES]
            + [PlannedRun({"mode": "nonuniform", "split": s}, p["dataset"], p["category"], s, {"mode": "nonuniform"})
               for s in p["model_splits"] if s != 0]
            + [PlannedRun({"mode": "nonuniform", "split": s, "configuration": PLAIN_READING}, p["dataset"], p["category"],
                          s, plain_segment, plain_train) for s in p["model_splits"]])


@notebook("explore.ipynb", real={"category": "Teddy", **EXPLORE_DEFAULTS},
          synthetic={"category": "figure", **EXPLORE_DEFAULTS}, smoke={"category": "figure", **EXPLORE_DEFAULTS})
def _explore(p: dict) -> list[PlannedRun]:
    """A model of the user's, or a shipped one, needs no training."""
    return [] if p.get("model_path") or explore_model_name(p) else [PlannedRun({}, p["dataset"], p["category"])]


@notebook("claims_ledger.ipynb", real={}, synthetic={}, smoke={})
def _ledger(p: dict) -> list[PlannedRun]:
    """Trains nothing: it reads what the others wrote, so it is registered last."""
    return []


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


def notebook_parameters(name: str, kind: str) -> dict:
    """The parameters a notebook runs with for a run kind (``output_dir`` aside), ``categories=None`` resolved."""
    return resolve_categories({**COMMON[kind], **PLANS[name].parameters[kind]})


def with_choices(p: dict, config: str | None = None, splits: list[int] | None = None) -> dict:
    """A notebook's parameters with a named configuration and, where it takes ``splits``,
    the splits chosen instead of the plan's."""
    return {**p, **({"config": config} if config else {}), **({"splits": list(splits)} if splits and "splits" in p else {})}


def dataset_categories(dataset: str) -> list[str]:
    """Every category of a data set with categories (PSB, synthetic)."""
    from anseg import datasets
    from anseg.datasets import synthetic

    return list(synthetic.CATEGORIES if dataset == "synthetic" else datasets.PSB_CATEGORIES)


def resolve_categories(p: dict) -> dict:
    """``categories=None`` means every category of the data set."""
    if "categories" in p and p["categories"] is None:
        p = {**p, "categories": dataset_categories(p["dataset"])}
    return p


def notebook_runs(name: str, p: dict) -> list[PlannedRun]:
    """Every run notebook ``name`` asks for with parameters ``p``, in the order its tables list them."""
    if name not in PLANS:
        raise ValueError(f"no plan for notebook {name}")
    return PLANS[name].runs(resolve_categories(p))


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
    return [n for n in PLANS if not only or any(o in n for o in only)]


def output_dirs(kind: str, out: Path | None) -> tuple[Path, Path]:
    """Where executed notebooks and the result store (figures, results, models) go for a run kind."""
    if kind == "real" and out is None:
        return REPO / "notebooks" / "executed", REPO
    base = out or REPO / "runs" / kind
    return base / "notebooks", base
