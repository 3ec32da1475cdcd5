"""Run every notebook through papermill: ``python -m anseg.reproduce --data synthetic|real``.

``synthetic`` (the default of ``make reproduce``) runs on the embedded
generator with small settings and writes under ``runs/synthetic/``; ``real``
runs on the benchmark archives (``$ANSEG_DATA``) with the paper's settings
and writes the committed outputs: ``notebooks/executed/``, ``figures/`` and
``results/``. ``--smoke`` shrinks the synthetic settings further, for CI.
Each notebook takes its parameters from the table below; nothing else
differs between the runs.

``--train-only --jobs N`` trains the notebooks' configurations without
running the notebooks, N at a time, into the same result store
(``results/runs/<key>.json``, ``models/``). A notebook run afterwards reads
the stored results instead of training, so a long real run can be spread
over processes, machines (a GPU box) and sessions.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
NOTEBOOKS = REPO / "notebooks"

# Parameters shared by every notebook, per run kind. Notebook-specific ones follow.
COMMON = {
    "real": {"dataset": "psb", "epochs": 60, "seed": 0, "device": "auto", "smoke": False},
    "synthetic": {"dataset": "synthetic", "epochs": 12, "seed": 0, "device": "auto", "smoke": False},
    "smoke": {"dataset": "synthetic", "epochs": 2, "seed": 0, "device": "cpu", "smoke": True},
}

SYNTHETIC_CATEGORIES = ["figure", "vessel"]
PSB_ABLATION = ["Human", "Teddy", "Airplane"]
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
        "real": {"categories": PSB_ABLATION},
        "synthetic": {"categories": SYNTHETIC_CATEGORIES},
        "smoke": {"categories": ["figure"]},
    },
    "fig12_features.ipynb": {
        "real": {"categories": PSB_ABLATION},
        "synthetic": {"categories": ["figure"]},
        "smoke": {"categories": ["figure"]},
    },
    "fig11_cycles_ratio.ipynb": {
        "real": {"categories": ["Airplane"], "cycles_list": [1, 2, 3, 4, 5, 6], "ratios": [0.3, 0.4, 0.5, 0.6, 0.7]},
        "synthetic": {"categories": ["figure"], "cycles_list": [1, 2, 4], "ratios": [0.3, 0.5, 0.7]},
        "smoke": {"categories": ["figure"], "cycles_list": [1, 2], "ratios": [0.5]},
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
}


# Fig. 4's modes; also the cost order: attention-driven runs collapse every few epochs, "none" never does
ABLATION_MODES = ("nonuniform", "uniform", "none")
# Table IV's rows: (SegmentConfig overrides, TrainConfig overrides). "none" is the paper's row: the attention
# module and the downsampling removed, a per-face classifier on the same features (depth 0) plus the graph cut;
# "none, transformer" is our network on the input mesh alone, a stronger control the paper does not have.
TABLE_IV_ROWS = {
    "nonuniform": ({"mode": "nonuniform"}, {}),
    "uniform": ({"mode": "uniform"}, {}),
    "none": ({"mode": "none"}, {"depth": 0}),
    "none, transformer": ({"mode": "none"}, {}),
}


def notebook_settings(epochs: int, seed: int, device: str, smoke: bool) -> tuple[dict, dict, "TrainConfig"]:
    """Data set options, SegmentConfig overrides and TrainConfig of a notebook run (its setup cell does the same).

    A smoke run only checks that a notebook runs from end to end: 4 shapes, a tiny model, 2 cycles.
    """
    from anseg.train import TrainConfig

    shape_options = {"n_shapes": 4} if smoke else {}
    segment_options = {"cycles": 2, "clusters": 4} if smoke else {}
    train = TrainConfig(epochs=epochs, seed=seed, device=device, **({"width": 16, "depth": 1} if smoke else {}))
    return shape_options, segment_options, train


def _notebook_cells(name: str, p: dict) -> list[tuple]:
    """(data set, category, split, SegmentConfig options[, TrainConfig options]) of every result notebook ``name`` asks for."""
    from anseg import datasets
    from anseg.datasets import synthetic
    from anseg.features import ABLATION_SETS

    dataset = p["dataset"]
    categories = p.get("categories")
    if categories is None and "categories" in p:
        categories = list(synthetic.CATEGORIES if dataset == "synthetic" else datasets.PSB_CATEGORIES)
    if name == "table1_psb.ipynb":
        return [(dataset, c, s, {}) for s in p["splits"] for c in categories]  # split by split: each finishes whole
    if name == "table2_coseg.ipynb":
        return [(c, None, 0, {}) if c in datasets.DATASETS else (dataset, c, 0, {}) for c in categories]
    if name == "table3_human.ipynb":
        return [(dataset, p["category"], 0, {})]
    if name == "table4_ablation.ipynb":
        return [(dataset, c, 0, *TABLE_IV_ROWS[row]) for c in categories for row in TABLE_IV_ROWS]
    if name == "fig11_cycles_ratio.ipynb":
        return [(dataset, c, 0, {"cycles": n, "ratio": r}) for c in categories for r in p["ratios"] for n in p["cycles_list"]]
    if name == "fig12_features.ipynb":
        return [(dataset, c, 0, {"groups": g}) for c in categories for g in ABLATION_SETS.values()]
    if name == "fig4_attention.ipynb":
        return [(dataset, p["category"], 0, {"mode": m}) for m in ABLATION_MODES]
    if name == "explore.ipynb":
        return [] if p.get("model_path") else [(dataset, p["category"], 0, {})]
    raise ValueError(f"no plan for notebook {name}")


def planned_experiments(kind: str, only: list[str] | None = None) -> list[tuple["Experiment", dict]]:
    """Every (Experiment, data set options) the notebooks of ``kind`` train, without repeats.

    In notebook order, and inside a notebook the costliest runs first.
    """
    from dataclasses import replace

    from anseg.pipeline import SegmentConfig
    from anseg.train import Experiment

    plan = {}
    for name in _selected(only):
        p = {**COMMON[kind], **PER_NOTEBOOK[name][kind]}
        shape_options, segment_options, train = notebook_settings(p["epochs"], p["seed"], p["device"], p["smoke"])
        cells = sorted(_notebook_cells(name, p), key=lambda cell: ABLATION_MODES.index(cell[3].get("mode", "nonuniform")))
        for data, category, split, options, *train_options in cells:
            settings = replace(train, **(train_options[0] if train_options else {}))
            experiment = Experiment(data, category, split, SegmentConfig(**{**segment_options, **options}), settings)
            extra = shape_options if data == "synthetic" else {}
            plan.setdefault(experiment.key(extra), (experiment, extra))
    return list(plan.values())


def _selected(only: list[str] | None) -> list[str]:
    return [n for n in PER_NOTEBOOK if not only or any(o in n for o in only)]


def _describe(experiment) -> str:
    where = "/".join(str(x) for x in (experiment.dataset, experiment.category) if x is not None)
    s = experiment.segment
    return f"{where} split {experiment.split_index} {s.mode} N={s.cycles} r={s.ratio} groups={'+'.join(s.groups)}"


def _precompute_features(plan, jobs: int) -> None:
    """Fill the feature cache for every mesh of the plan, one process pool per feature set, before training starts."""
    from anseg import datasets, features

    sources = {}
    for experiment, extra in plan:
        split = experiment.split_index if experiment.dataset == "synthetic" else 0  # "all" is every split's meshes
        source = (experiment.dataset, experiment.category, split, tuple(sorted(extra.items())))
        sources.setdefault(experiment.segment.groups, set()).add(source)
    for groups, wanted in sources.items():
        meshes = [m.mesh for data, category, split, extra in sorted(wanted, key=str)
                  for m in datasets.load(data, category, "all", split, progress=False, **dict(extra))]
        features.compute_many(meshes, groups, workers=jobs, progress=False)


def _train_one(experiment, extra: dict, out_dir: str) -> dict:
    """One experiment, quietly (many run side by side)."""
    from anseg.train import run_experiment

    return run_experiment(experiment, out_dir=out_dir, progress=False, **extra)


def train_only(kind: str, only: list[str] | None, out: Path | None, jobs: int, stop_after: float | None = None) -> int:
    """Train (or find stored) every planned experiment, ``jobs`` at a time; returns the number that failed.

    With ``stop_after`` (seconds), no run starts after that time; the runs under way finish.
    """
    from anseg.parallel import run_parallel
    from anseg.train import stored_result_path

    _, results_root = output_dirs(kind, out)
    plan = planned_experiments(kind, only)
    todo = [(e, x) for e, x in plan if not stored_result_path(results_root, e.key(x)).is_file()]
    print(f"[anseg] {len(plan)} planned runs, {len(plan) - len(todo)} already stored, {len(todo)} to train "
          f"with {jobs} job(s) -> {results_root}", flush=True)
    if not todo:
        return 0
    started = time.time()
    _precompute_features(todo, jobs)
    print(f"[anseg] features ready after {time.time() - started:.0f} s", flush=True)
    calls = [(_train_one, (experiment, extra, str(results_root))) for experiment, extra in todo]
    remaining = stop_after and max(0.0, stop_after - (time.time() - started))
    failed = finished = 0
    for index, result in run_parallel(calls, jobs, stop_after=remaining):
        experiment = todo[index][0]
        finished += 1
        if isinstance(result, Exception):  # report and go on: the other runs are still worth having
            failed += 1
            print(f"[anseg] {finished}/{len(todo)} FAILED {_describe(experiment)}: {result}", file=sys.stderr, flush=True)
            continue
        print(f"[anseg] {finished}/{len(todo)} {_describe(experiment)}: {100 * result['accuracy']['unit_area']:.2f} % "
              f"(train {result['train_seconds']:.0f} s; {time.time() - started:.0f} s so far)", flush=True)
    if finished < len(todo):
        print(f"[anseg] stopped after {stop_after:.0f} s: {len(todo) - finished} run(s) not started", flush=True)
    return failed


HEADLINE_START = "<!-- headline: written by `python -m anseg.reproduce --data real` from results/*.csv; do not edit -->"
HEADLINE_END = "<!-- /headline -->"


def _markdown_row(label, values) -> str:
    """A table row: numbers with two decimals, missing ones (NaN) left empty."""
    import pandas as pd

    return f"| {label} | " + " | ".join("" if pd.isna(v) else f"{v:.2f}" for v in values) + " |"


def headline(results_dir: Path) -> str:
    """README's headline tables, built from the real run's result files (nothing typed by hand)."""
    import pandas as pd

    table1 = pd.read_csv(results_dir / "table1_psb.csv", index_col=0)
    split = next(c for c in table1.columns if c.startswith("ours, unit area (split"))
    over_splits = next(c for c in table1.columns if c.startswith("ours, unit area, mean of"))
    n_splits = int(over_splits.split("mean of ")[1].split()[0])
    more = [over_splits, "ours, std over splits"] if n_splits > 1 else []
    paper = "Ours (paper), Table I"
    peers = [c for c in table1.columns if c.endswith("our data, split 0") and table1[c].notna().any()]
    lines = [f"PSB, Table I ([notebook](notebooks/executed/table1_psb.ipynb)): Eq. 5 with unit area, "
             f"{split.split('(')[1].rstrip(')')}, graph cut on; beside ours the paper's column and the reference "
             "points DESIGN.md measured on exactly our data (split 0)."
             + (f" Then our mean over {n_splits} splits and its standard deviation (in the mean row: the spread of "
                "the 16-category mean from split to split)." if more else ""),
             "", "| category | ours | paper | ours − paper | " + " | ".join(c.split(",")[0] for c in peers)
             + (f" | ours, {n_splits} splits | std" if more else "") + " |",
             "|---|---|---|---|" + "---|" * (len(peers) + len(more))]
    for category, row in table1.iterrows():
        cells = [row[split], row[paper], row[split] - row[paper], *(row[c] for c in peers + more)]
        lines.append(_markdown_row(f"**{category}**" if category == "mean" else category, cells))
    table4 = pd.read_csv(results_dir / "table4_ablation.csv", index_col=0)
    rows = [m for m in TABLE_IV_ROWS if f"ours, {m}" in table4.columns]
    lines += ["", "Table IV, downsampling ablation on PSB split 0 ([notebook](notebooks/executed/table4_ablation.ipynb)), "
              "ours (paper); \"none\" is the paper's row, a per-face classifier without attention or downsampling, "
              "and \"none, transformer\" our network on the input mesh alone (no paper number):", "",
              "| category | " + " | ".join(rows) + " |", "|---|" + "---|" * len(rows)]
    for category, row in table4.iterrows():
        cells = [f"{row[f'ours, {m}']:.2f}" + (f" ({row[f'paper, {m}']:.2f})" if pd.notna(row.get(f"paper, {m}")) else "")
                 for m in rows]
        lines.append(f"| {category} | " + " | ".join(cells) + " |")
    coseg = results_dir / "table2_coseg.csv"
    if coseg.is_file():
        table2 = pd.read_csv(coseg, index_col=0)
        peer_columns = [c for c in table2.select_dtypes("number").columns if not c.startswith(("ours", "n_"))]
        lines += ["", "COSEG large sets as MeshCNN distributes them ([notebook](notebooks/executed/table2_coseg.ipynb)); "
                  "not the paper's data (its Table II uses the small sets), so compared with peers that report on these:",
                  "", "| set | ours, faces | " + " | ".join(peer_columns) + " |", "|---|---|" + "---|" * len(peer_columns)]
        for entry, row in table2.iterrows():
            lines.append(_markdown_row(entry, [row["ours, faces"], *(row[c] for c in peer_columns)]))
    human = results_dir / "table3_human.csv"
    if human.is_file():
        table3 = pd.read_csv(human)
        lines += ["", "Human body set as MeshCNN distributes it ([notebook](notebooks/executed/table3_human.ipynb)); "
                  "not the paper's full-resolution set, so compared with peers that report on this one:", "",
                  "| method | accuracy | metric |", "|---|---|---|"]
        lines += [f"| {row.method} | {row.accuracy:.2f} | {row.metric} |" for row in table3.itertuples()]
    return "\n".join(lines)


def update_readme(readme: Path, results_dir: Path) -> None:
    """Replace the block between the headline markers of ``readme`` with :func:`headline`."""
    text = readme.read_text()
    start, end = text.index(HEADLINE_START) + len(HEADLINE_START), text.index(HEADLINE_END)
    readme.write_text(text[:start] + "\n" + headline(results_dir) + "\n" + text[end:])


def output_dirs(kind: str, out: Path | None) -> tuple[Path, Path]:
    """Where executed notebooks and their figures/results go for a run kind."""
    if kind == "real" and out is None:
        return NOTEBOOKS / "executed", REPO
    base = out or REPO / "runs" / kind
    return base / "notebooks", base


def run(kind: str, only: list[str] | None = None, out: Path | None = None, kernel: str | None = None) -> int:
    """Execute the notebooks of one run kind; returns the number that failed."""
    import papermill

    executed_dir, results_root = output_dirs(kind, out)
    executed_dir.mkdir(parents=True, exist_ok=True)
    names = _selected(only)
    failed = 0
    for name in names:
        params = {**COMMON[kind], **PER_NOTEBOOK[name][kind], "output_dir": str(results_root)}
        started = time.time()
        print(f"[anseg] {name} ({kind}) ...", flush=True)
        try:
            papermill.execute_notebook(
                str(NOTEBOOKS / name),
                str(executed_dir / name),
                parameters=params,
                kernel_name=kernel,
                cwd=str(NOTEBOOKS),
                progress_bar=False,
            )
        except Exception as exc:  # papermill re-raises the cell's error; report and go on to the next notebook
            failed += 1
            print(f"[anseg] {name} FAILED after {time.time() - started:.0f} s: {exc}", file=sys.stderr)
            continue
        print(f"[anseg] {name} done in {time.time() - started:.0f} s -> {executed_dir / name}", flush=True)
    if kind == "real" and out is None and not failed and (results_root / "results" / "table4_ablation.csv").is_file():
        update_readme(REPO / "README.md", results_root / "results")
    return failed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m anseg.reproduce", description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", choices=["synthetic", "real"], default="synthetic", help="which data the notebooks run on (default: synthetic)")
    parser.add_argument("--smoke", action="store_true", help="tiny settings on synthetic data (what CI runs)")
    parser.add_argument("--only", nargs="*", help="run only the notebooks whose file name contains one of these strings")
    parser.add_argument("--out", type=Path, help="write here instead of the default folder of the run kind")
    parser.add_argument("--kernel", default=None, help="Jupyter kernel name (default: the notebook's own)")
    parser.add_argument("--train-only", action="store_true",
                        help="train the notebooks' configurations into the result store; run no notebook")
    parser.add_argument("--jobs", type=int, default=1, help="with --train-only: runs side by side (default: 1)")
    parser.add_argument("--stop-after", type=float, metavar="MINUTES",
                        help="with --train-only: start no run after this many minutes (the runs under way finish)")
    args = parser.parse_args(argv)
    if args.smoke and args.data == "real":
        parser.error("--smoke runs on synthetic data only")
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    kind = "smoke" if args.smoke else args.data
    if args.train_only:
        failed = train_only(kind, args.only, args.out, args.jobs, args.stop_after and 60 * args.stop_after)
        what = "run(s)"
    else:
        failed = run(kind, args.only, args.out, args.kernel)
        what = "notebook(s)"
    if failed:
        print(f"[anseg] {failed} {what} failed", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
