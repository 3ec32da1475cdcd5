"""Run every notebook through papermill: ``python -m anseg.reproduce --data synthetic|real``.

``synthetic`` (the default of ``make reproduce``) runs on the embedded
generator with small settings and writes under ``runs/synthetic/``; ``real``
runs on the benchmark archives (``$ANSEG_DATA``) with the paper's settings
and writes the committed outputs: ``notebooks/executed/``, ``figures/`` and
``results/``. ``--smoke`` shrinks the synthetic settings further, for CI.
Each notebook takes its parameters from the table below; nothing else
differs between the runs.
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
    "fig11_cycles_ratio.ipynb": {
        "real": {"categories": ["Teddy"], "cycles_list": [1, 2, 3, 4, 5, 6], "ratios": [0.3, 0.4, 0.5, 0.6, 0.7]},
        "synthetic": {"categories": ["figure"], "cycles_list": [1, 2, 4], "ratios": [0.3, 0.5, 0.7]},
        "smoke": {"categories": ["figure"], "cycles_list": [1, 2], "ratios": [0.5]},
    },
    "fig12_features.ipynb": {
        "real": {"categories": PSB_ABLATION},
        "synthetic": {"categories": ["figure"]},
        "smoke": {"categories": ["figure"]},
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
    names = [n for n in PER_NOTEBOOK if not only or any(o in n for o in only)]
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
    return failed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m anseg.reproduce", description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", choices=["synthetic", "real"], default="synthetic", help="which data the notebooks run on (default: synthetic)")
    parser.add_argument("--smoke", action="store_true", help="tiny settings on synthetic data (what CI runs)")
    parser.add_argument("--only", nargs="*", help="run only the notebooks whose file name contains one of these strings")
    parser.add_argument("--out", type=Path, help="write here instead of the default folder of the run kind")
    parser.add_argument("--kernel", default=None, help="Jupyter kernel name (default: the notebook's own)")
    args = parser.parse_args(argv)
    if args.smoke and args.data == "real":
        parser.error("--smoke runs on synthetic data only")
    kind = "smoke" if args.smoke else args.data
    failed = run(kind, args.only, args.out, args.kernel)
    if failed:
        print(f"[anseg] {failed} notebook(s) failed", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
