"""Training time of one category, by stage, beside a reference revision of the code.

    python benchmarks/train.py [--dataset psb] [--category Teddy] [--split 0] [--mode nonuniform]
                               [--epochs 60] [--device auto] [--threads 1] [--set OVERRIDES]
                               [--reference REV] [--reference-set OVERRIDES] [--pairs N]

Trains on the split's training meshes and evaluates on its test meshes, as
``anseg.study.runner.train_and_evaluate`` does (nothing is stored; the test
accuracy is printed only to show whether two codes give the same result).
Stages: level-0 features (read from the cache when there), rebuilding the
hierarchy from the current attention (every ``recollapse_every`` epochs),
the gradient steps (the rest of training) and evaluation. ``--threads 1``
is the setting of the parallel runs. With ``--reference`` the same run is
made in a fresh process with the code of that git revision (a temporary
worktree), and every stage is printed beside it with the reference's time
over ours. ``--set`` overrides the default settings (``patch_size=32``, the
syntax of ``anseg.configs``); ``--reference-set`` gives the reference run
settings of its own (``""``: the defaults), with our code where there is no
``--reference``: what a setting saves, as a ratio. ``--pairs N`` runs each
code N times, in alternating order, and prints medians: on a shared machine
one pair can be off by 20 % either way.
"""

from __future__ import annotations

# first: importing stages pins the float kernels (anseg/kernels.py) before NumPy and torch load
from stages import import_from, kernels_of_children, print_stages, reference_checkout, stage_timers

# isort: split
import argparse
import multiprocessing
import time
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def measure(args, code: str | None, overrides: str) -> tuple[dict, float, str]:
    """Runs in a fresh process: seconds by stage, the test accuracy, and what ran."""
    import_from(code)
    import torch

    import anseg.train as train
    from anseg import datasets
    from anseg.configs import configuration
    from anseg.pipeline import SegmentConfig

    torch.set_num_threads(args.threads)
    # warm-up: numba compiles the collapse and the ray caster on first use (a reference checkout compiles afresh)
    shapes = datasets.load("synthetic", category="figure", split="train", n_shapes=4, progress=False)[:2]
    train.fit(shapes, shapes[0].label_names, SegmentConfig(mode=args.mode, cycles=2, clusters=4),
              train.TrainConfig(epochs=1, width=16, depth=1), progress=False)
    category = None if args.category in ("", "none") else args.category
    load = dict(category=category, split_index=args.split, progress=False)
    train_set, test_set = datasets.load(args.dataset, split="train", **load), datasets.load(args.dataset, split="test", **load)
    config, settings = configuration("default",
                                     f"mode={args.mode},train.epochs={args.epochs},train.device={args.device},{overrides}")
    totals = defaultdict(float)
    wrapped = {"features (level 0)": (train, "level_zero_features"), "rebuild hierarchy": (train, "_examples")}
    start = time.perf_counter()
    with stage_timers(totals, wrapped):
        model = train.fit(train_set, train_set[0].label_names, config, settings, progress=False)
    totals["gradient steps"] = time.perf_counter() - start - totals["features (level 0)"] - totals["rebuild hierarchy"]
    evaluated = time.perf_counter()
    scores = train.evaluate(model, test_set, progress=False)
    totals["evaluate"] = time.perf_counter() - evaluated
    totals["total"] = time.perf_counter() - start
    faces = np.mean([m.mesh.n_faces for m in train_set])
    what = (f"{args.dataset} {category} split {args.split}: {len(train_set)} training meshes ({faces:.0f} faces on average), "
            f"{len(test_set)} test meshes; mode {args.mode}, {args.epochs} epochs{', ' + overrides if overrides else ''}; device "
            f"{train.resolve_device(args.device)}, torch threads {torch.get_num_threads()}")
    return dict(totals), 100 * scores["smoothed"]["unit_area"], what


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="psb")
    parser.add_argument("--category", default="Teddy")
    parser.add_argument("--split", type=int, default=0)
    parser.add_argument("--mode", default="nonuniform", choices=["nonuniform", "uniform", "none"])
    parser.add_argument("--epochs", type=int, default=60)
    parser.add_argument("--device", default="auto")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: 1)")
    parser.add_argument("--reference", help="git revision whose code trains the same run beside this one")
    parser.add_argument("--set", default="", help="overrides of the default settings, field=value,... (default: none)")
    parser.add_argument("--reference-set", help="the reference run's overrides instead of --set (\"\": the defaults)")
    parser.add_argument("--reference-kernels", choices=["native"],
                        help="the reference runs each library's own kernels (ANSEG_KERNELS=native): the pin's cost")
    parser.add_argument("--pairs", type=int, default=1,
                        help="runs of each code, in alternating order; the figures are medians (default: 1)")
    args = parser.parse_args(argv)

    context = multiprocessing.get_context("spawn")  # fresh processes: each imports its own anseg
    reference_set = args.set if args.reference_set is None else args.reference_set
    label = " ".join(filter(None, [args.reference, f"[{reference_set or 'defaults'}]" if args.reference_set is not None else "",
                                   f"{args.reference_kernels} kernels" if args.reference_kernels else ""]))
    with reference_checkout(args.reference) as code:
        compared = code is not None or args.reference_set is not None or args.reference_kernels is not None
        runs = {"ours": [], "reference": []}
        for pair in range(args.pairs):
            # alternate which code goes first, so that a load that drifts over the run weighs on both alike
            order = [("ours", None, args.set)] + ([("reference", code, reference_set)] if compared else [])
            for name, checkout, overrides in order[:: 1 if pair % 2 == 0 else -1]:
                with kernels_of_children(args.reference_kernels if name == "reference" else None), \
                        ProcessPoolExecutor(1, mp_context=context) as pool:
                    runs[name].append(pool.submit(measure, args, checkout, overrides).result())
    ours, accuracy, what = _median_run(runs["ours"])
    reference = _median_run(runs["reference"]) if compared else None
    print(what + (f"; median of {args.pairs} runs of each code, in alternating order" if args.pairs > 1 else ""))
    print(f"test accuracy (Eq. 5, unit area): {accuracy:.2f} %"
          + (f"; {label}: {reference[1]:.2f} %" if reference else ""))
    print_stages(ours, reference[0] if reference else None, name=label or "reference")
    if compared and args.pairs > 1:
        ratios = sorted(r[0]["total"] / o[0]["total"] for o, r in zip(runs["ours"], runs["reference"]))
        print(f"total, reference over ours, pair by pair: {', '.join(f'{x:.2f}x' for x in ratios)}")


def _median_run(runs: list[tuple[dict, float, str]]) -> tuple[dict, float, str]:
    """Each stage's median seconds over the runs; the accuracy and description of the first (every run trains the same)."""
    medians = {stage: float(np.median([r[0][stage] for r in runs])) for stage in runs[0][0]}
    return medians, runs[0][1], runs[0][2]


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
