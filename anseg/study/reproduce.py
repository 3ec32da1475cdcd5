"""Run every notebook through papermill: ``python -m anseg.study.reproduce --data synthetic|real``.

``synthetic`` (the default of ``make reproduce``) runs on the embedded
generator with small settings and writes under ``runs/synthetic/``; ``real``
runs on the benchmark archives (``$ANSEG_DATA``) with the paper's settings
and writes the committed outputs: ``notebooks/executed/``, ``figures/`` and
``results/``. ``--smoke`` shrinks the synthetic settings further, for CI.
Each notebook takes its parameters from the plan (:mod:`anseg.study`);
nothing else differs between the runs.

``--train-only --workers N`` trains the notebooks' configurations without
running the notebooks, N at a time on a Dask ``LocalCluster`` of this
machine, into the same result store (``results/runs/<key>.json``,
``models/``); ``--scheduler tcp://HOST:8786`` sends them to a running Dask
cluster instead. A notebook run afterwards reads the stored results instead
of training, so a long real run can be spread over processes, machines (a
GPU box) and sessions. ``--status`` says, per notebook, how many of its
planned runs the store holds and about how much training is left.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from anseg.configs import NAMED
from anseg.study.headline import update_readme
from anseg.study.plan import (
    COMMON,
    PLANS,
    notebook_parameters,
    output_dirs,
    planned_experiments,
    selected_notebooks,
    with_choices,
)
from anseg.study.runner import run_plan
from anseg.study.store import REPO, ResultStore

NOTEBOOKS = REPO / "notebooks"


def run(kind: str, only: list[str] | None = None, out: Path | None = None, kernel: str | None = None,
        config: str | None = None, splits: list[int] | None = None) -> int:
    """Execute the notebooks of one run kind; returns the number that failed.

    With ``config``, every run starts from that named configuration; with
    ``splits``, the notebooks that take several splits run on those alone.
    """
    import papermill

    executed_dir, results_root = output_dirs(kind, out)
    executed_dir.mkdir(parents=True, exist_ok=True)
    names = selected_notebooks(only)
    if kind == "real" and "OMP_NUM_THREADS" not in os.environ:
        # the runs trained on one thread; with more, the clustering and the matrix products can round otherwise and
        # a mesh's hierarchy change (seen on one Fig. 4 mesh), so the kernels segment as the runs did
        os.environ["OMP_NUM_THREADS"] = "1"
        print("[anseg] OMP_NUM_THREADS=1 for the notebooks' kernels (the stored runs' setting); set it to choose",
              flush=True)
    # an executed notebook is read, not watched: no progress bars in its outputs (tqdm reads this)
    os.environ.setdefault("TQDM_DISABLE", "1")
    narrowed = [n for n in names if splits and "splits" in PLANS[n].parameters[kind]]
    if kind == "real" and out is None and narrowed:
        print(f"[anseg] --splits {' '.join(map(str, splits))}: the committed outputs of {', '.join(narrowed)} "
              "will cover these splits alone", flush=True)
    failed = 0
    for name in names:
        # relative to the notebooks' folder (their working directory): executed notebooks name no machine's paths
        params = {**with_choices({**COMMON[kind], **PLANS[name].parameters[kind]}, config, splits),
                  "output_dir": os.path.relpath(results_root, NOTEBOOKS)}
        started = time.time()
        print(f"[anseg] {name} ({kind}) ...", flush=True)
        # executed aside and moved into place only on success: a failed run never replaces the executed copy
        attempt = executed_dir / failed_name(name)
        try:
            papermill.execute_notebook(  # paths as relative as they can be: papermill records them
                os.path.relpath(NOTEBOOKS / name),
                os.path.relpath(attempt),
                parameters=params,
                kernel_name=kernel,
                cwd=str(NOTEBOOKS),
                progress_bar=False,
            )
        except Exception as exc:  # papermill re-raises the cell's error; report and go on to the next notebook
            failed += 1
            print(f"[anseg] {name} FAILED after {time.time() - started:.0f} s: {exc}\n"
                  f"[anseg] {executed_dir / name} is left as it was; the failed run is in {attempt}", file=sys.stderr)
            continue
        os.replace(attempt, executed_dir / name)
        print(f"[anseg] {name} done in {time.time() - started:.0f} s -> {executed_dir / name}", flush=True)
    if kind == "real" and out is None and not failed and (results_root / "results" / "table4_ablation.csv").is_file():
        update_readme(REPO / "README.md", results_root / "results")
    return failed


def status(kind: str, only: list[str] | None = None, out: Path | None = None, config: str | None = None,
           splits: list[int] | None = None) -> list[dict]:
    """Per notebook: its configuration, its planned runs, how many the store holds, and the training time left.

    The time left is the stored runs' median training time (one process)
    times the runs missing; None before any is stored.
    """
    from statistics import median

    store = ResultStore(output_dirs(kind, out)[1])
    rows = []
    for name in selected_notebooks(only):
        plan = planned_experiments(kind, [name], config, splits)
        stored = [r for r in (store.get(e.key(x)) for e, x in plan) if r is not None]
        seconds = [r["train_seconds"] for r in stored if "train_seconds" in r]
        rows.append({"notebook": name, "config": config or notebook_parameters(name, kind)["config"],
                     "planned": len(plan), "stored": len(stored),
                     "hours_left": median(seconds) * (len(plan) - len(stored)) / 3600 if seconds else None})
    return rows


def failed_name(name: str) -> str:
    """Where a notebook is executed before it is known to succeed (and stays when it fails); git ignores it."""
    return f"{Path(name).stem}.failed.ipynb"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m anseg.study.reproduce", description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", choices=["synthetic", "real"], default="synthetic",
                        help="which data the notebooks run on (default: synthetic)")
    parser.add_argument("--smoke", action="store_true", help="tiny settings on synthetic data (what CI runs)")
    parser.add_argument("--only", nargs="*", help="run only the notebooks whose file name contains one of these strings")
    parser.add_argument("--out", type=Path, help="write here instead of the default folder of the run kind")
    parser.add_argument("--kernel", default=None, help="Jupyter kernel name (default: the notebook's own)")
    parser.add_argument("--config", choices=list(NAMED),
                        help="the named configuration every run starts from (default: the plan's for the run kind)")
    parser.add_argument("--splits", type=int, nargs="+", metavar="K",
                        help="the notebooks that take several splits run on these alone (default: the plan's; "
                             "their records name the splits)")
    parser.add_argument("--train-only", action="store_true",
                        help="train the notebooks' configurations into the result store; run no notebook")
    parser.add_argument("--workers", type=int, default=1,
                        help="with --train-only: runs side by side, one Dask worker process each (default: 1)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="with --train-only: a running Dask scheduler (tcp://HOST:8786) to send the runs to")
    parser.add_argument("--backend", choices=["dask", "loky"], default="dask",
                        help="with --train-only: Dask (default), or a plain process pool where Dask is not installed")
    parser.add_argument("--status", action="store_true",
                        help="say how many of each notebook's planned runs are stored, and the training left; run nothing")
    parser.add_argument("--stop-after", type=float, metavar="MINUTES",
                        help="with --train-only: start no run after this many minutes (the runs under way finish)")
    args = parser.parse_args(argv)
    if args.smoke and args.data == "real":
        parser.error("--smoke runs on synthetic data only")
    if args.workers < 1:
        parser.error("--workers must be at least 1")
    if args.scheduler and args.backend != "dask":
        parser.error("--scheduler needs the dask backend")
    kind = "smoke" if args.smoke else args.data
    if args.splits:
        from anseg.datasets import PSB_SPLIT_COUNT
        from anseg.datasets.synthetic import N_SPLITS

        count = PSB_SPLIT_COUNT if kind == "real" else N_SPLITS
        if not all(0 <= s < count for s in args.splits):
            parser.error(f"--splits: the {args.data} data has splits 0 to {count - 1}")
    if args.status:
        for row in status(kind, args.only, args.out, args.config, args.splits):
            left = ("trains nothing" if not row["planned"] else "no run stored yet" if row["hours_left"] is None
                    else f"about {row['hours_left']:.1f} h of one-process training left")
            print(f"{row['notebook']:<26} {row['config']:<8} {row['stored']:>4} of {row['planned']:>4} runs stored; {left}")
        return 0
    if args.train_only:
        store = ResultStore(output_dirs(kind, args.out)[1])
        failed = run_plan(planned_experiments(kind, args.only, args.config, args.splits), store, args.workers, args.scheduler,
                          args.backend, stop_after=args.stop_after and 60 * args.stop_after)
        what = "run(s)"
    else:
        failed = run(kind, args.only, args.out, args.kernel, args.config, args.splits)
        what = "notebook(s)"
    if failed:
        print(f"[anseg] {failed} {what} failed", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
