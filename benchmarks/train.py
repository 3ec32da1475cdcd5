"""Training time of one category, by stage, with the notebooks' settings.

    python benchmarks/train.py [--dataset psb] [--category Teddy] [--split 0] [--mode nonuniform]
                               [--epochs 60] [--device auto] [--threads 1]

Trains on the split's training meshes and evaluates on its test meshes, as
``anseg.train.run_experiment`` does (nothing is stored). Stages: level-0
features (read from the cache when there), rebuilding the hierarchy from the
current attention (every ``recollapse_every`` epochs), the gradient steps
(the rest of training) and evaluation. ``--threads 1`` is the setting of the
parallel runs (``python -m anseg.reproduce --train-only --workers N``).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import numpy as np
from stages import print_stages, stage_timers


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="psb")
    parser.add_argument("--category", default="Teddy")
    parser.add_argument("--split", type=int, default=0)
    parser.add_argument("--mode", default="nonuniform", choices=["nonuniform", "uniform", "none"])
    parser.add_argument("--epochs", type=int, default=60)
    parser.add_argument("--device", default="auto")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: 1)")
    args = parser.parse_args(argv)

    import torch

    import anseg.train as train
    from anseg import datasets
    from anseg.pipeline import SegmentConfig

    torch.set_num_threads(args.threads)
    category = None if args.category in ("", "none") else args.category
    load = dict(category=category, split_index=args.split, progress=False)
    train_set, test_set = datasets.load(args.dataset, split="train", **load), datasets.load(args.dataset, split="test", **load)
    config = SegmentConfig(mode=args.mode)
    settings = train.TrainConfig(epochs=args.epochs, device=args.device)
    totals = defaultdict(float)
    stages = {"features (level 0)": (train, "level_zero_features"), "rebuild hierarchy": (train, "_examples")}
    start = time.perf_counter()
    with stage_timers(totals, stages):
        model = train.fit(train_set, train_set[0].label_names, config, settings, progress=True)
    totals["gradient steps"] = time.perf_counter() - start - totals["features (level 0)"] - totals["rebuild hierarchy"]
    evaluated = time.perf_counter()
    scores = train.evaluate(model, test_set, progress=False)
    totals["evaluate"] = time.perf_counter() - evaluated
    totals["total"] = time.perf_counter() - start
    faces = [m.mesh.n_faces for m in train_set]
    print(f"{args.dataset} {category} split {args.split}: {len(train_set)} training meshes "
          f"({np.mean(faces):.0f} faces on average), {len(test_set)} test meshes; mode {args.mode}, {args.epochs} epochs")
    print(f"device {train.resolve_device(args.device)}, torch threads {torch.get_num_threads()}; "
          f"test accuracy (Eq. 5, unit area) {100 * scores['smoothed']['unit_area']:.2f} %")
    print_stages(totals)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
