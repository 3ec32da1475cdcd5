"""Round-trip study: how much of the ground truth survives downsampling and upsampling.

For every test mesh: downsample N cycles at a ratio, pool the ground-truth
labels to the coarsest mesh (area-weighted majority through the stacked
fine-to-coarse map), carry them back with ``upsample_through`` (vertex-split
vote, no graph-cut smoothing) and score against the ground truth with
``anseg.metrics.pooled_accuracy`` (the unit-area figure: each mesh scaled to
unit area, i.e. the mean of per-mesh area-weighted accuracies).

Modes compared:

* ``nonuniform`` with an ORACLE score: high near label boundaries, score =
  -(face rings to the nearest face of another label) plus a random jitter
  below one ring to break ties, recomputed on each level from the pooled labels;
* ``uniform`` (shortest edge first) and ``random`` (static random scores).

With ``--model MODEL.pt`` (a nonuniform model trained on one PSB category)
the study runs instead on that category's split-0 TRAINING meshes with the
model's own attention, recomputed on every level as ``segment`` does, with
the model's settings and then with each ``--set`` variant of them (e.g.
``once_per_pass=true``, or another density range); it also reports how many
input faces the largest coarse face stands for (how far a region was wiped
out).

Usage::

    ANSEG_DATA=/work/shared/datasets ANSEG_CACHE=/tmp/anseg-cache \\
        python benchmarks/roundtrip.py [--categories Teddy Human] [--all-meshes] [--out roundtrip.csv]
    python benchmarks/roundtrip.py --model models/<key>.pt --categories Human --set once_per_pass=true
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import csv
import time
import warnings

import numpy as np

from anseg import datasets
from anseg.collapse import COLLAPSE_MODES, CollapseWarning, downsample, rings_to_other_label
from anseg.hierarchy import pool_labels, round_trip_labels
from anseg.metrics import pooled_accuracy


def oracle_scores(mesh, labels, rng) -> np.ndarray:
    """High near label boundaries: minus the rings to another label, jittered below one ring to break ties."""
    return -rings_to_other_label(mesh, labels) + 0.5 * rng.random(mesh.n_faces)


def round_trip(item, mode: str, cycles: int, ratio: float, seed: int) -> tuple[np.ndarray, int]:
    """Predicted fine labels after the down-and-up trip, and how many cycles missed their face target."""
    n_classes = len(item.label_names)
    areas = item.mesh.face_areas
    rng = np.random.default_rng(seed)
    records, current, missed = [], item.mesh, 0
    for cycle in range(cycles):
        scores = None
        if mode == "nonuniform":  # the oracle reads the labels of the level it collapses
            labels = pool_labels(records, item.labels, areas, n_classes) if records else item.labels
            scores = oracle_scores(current, labels, rng)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CollapseWarning)
            current, record = downsample(current, scores, ratio=ratio, mode=mode, seed=seed + cycle)
        missed += not record.reached_target
        records.append(record)
    return round_trip_labels(records, item.labels, areas, n_classes), missed


def learned_round_trip(item, model, config) -> tuple[np.ndarray, int]:
    """Fine labels after the trip through the levels the model's attention builds under ``config``,
    and the largest coarse face."""
    from anseg.pipeline import build_levels

    n_classes = len(item.label_names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CollapseWarning)
        levels = build_levels(item.mesh, model, config)
    coarsest = len(levels) - 1
    return (levels.round_trip(coarsest, item.labels, n_classes),
            int(np.bincount(levels.input_to_level(coarsest)).max()) if coarsest else 1)


def learned_study(model_path: str, categories, variants: list[str]) -> None:
    """The round trip through the model's own hierarchy, then through each variant of its collapse settings."""
    from dataclasses import replace

    from anseg.configs import parse_overrides
    from anseg.pipeline import Segmenter

    model = Segmenter.load(model_path)
    for category in categories:
        items = datasets.load("psb", category=category, split="train", split_index=0, progress=False)
        print(f"{category}: {len(items)} training meshes (split 0), the model's attention, {model.config.cycles} cycles "
              f"at ratio {model.config.ratio}, no smoothing")
        for variant in ["", *variants]:
            segment_overrides, _ = parse_overrides(variant)
            trips = [learned_round_trip(item, model, replace(model.config, **segment_overrides)) for item in items]
            scores = pooled_accuracy([t[0] for t in trips], [i.labels for i in items], [i.mesh.face_areas for i in items])
            largest = [t[1] for t in trips]
            print(f"  {variant or 'as trained':<40} round trip {100 * scores['unit_area']:6.2f} %   input faces behind the "
                  f"largest coarse face: median {np.median(largest):.0f}, max {max(largest)}", flush=True)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--categories", nargs="*", default=None, help="PSB categories (default: all 16)")
    parser.add_argument("--no-human", action="store_true", help="skip the human_seg test meshes")
    parser.add_argument("--all-meshes", action="store_true", help="all 20 meshes per PSB category, not the split-0 test set")
    parser.add_argument("--cycles", type=int, default=4)
    parser.add_argument("--ratio", type=float, default=0.5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="write the per-category table as CSV here")
    parser.add_argument("--model", help="study a trained nonuniform model's attention on its training meshes instead")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE,...",
                        help="with --model: also collapse with these segmentation settings (repeatable), e.g. "
                             "once_per_pass=true or density_range=8,priority=weighted")
    args = parser.parse_args(argv)
    if args.model:
        learned_study(args.model, args.categories or ["Human"], args.set)
        return

    sets = [("psb", c) for c in (args.categories if args.categories is not None else datasets.PSB_CATEGORIES)]
    if not args.no_human:
        sets.append(("human_seg", None))
    split = "all" if args.all_meshes else "test"
    print(f"{args.cycles} cycles at ratio {args.ratio}, no smoothing; unit-area accuracy (%) of the round trip")
    print(f"{'set':<12}{'meshes':>7}" + "".join(f"{m:>12}" for m in COLLAPSE_MODES) + f"{'missed':>8}{'seconds':>9}")
    rows = []
    for name, category in sets:
        items = datasets.load(name, category=category, split=split, progress=False)
        row = {"set": category or name, "meshes": len(items)}
        started, missed = time.perf_counter(), 0
        for mode in COLLAPSE_MODES:
            predicted = []
            for item in items:
                labels, misses = round_trip(item, mode, args.cycles, args.ratio, args.seed)
                predicted.append(labels)
                missed += misses
            scores = pooled_accuracy(predicted, [i.labels for i in items], [i.mesh.face_areas for i in items])
            row[mode] = 100 * scores["unit_area"]
        row["missed_targets"] = missed
        row["seconds"] = time.perf_counter() - started
        rows.append(row)
        print(f"{row['set']:<12}{row['meshes']:>7}" + "".join(f"{row[m]:>12.2f}" for m in COLLAPSE_MODES)
              + f"{missed:>8}{row['seconds']:>9.1f}", flush=True)
    psb_rows = [r for r in rows if r["set"] != "human_seg"]
    if psb_rows:
        print(f"{'PSB mean':<19}" + "".join(f"{np.mean([r[m] for r in psb_rows]):>12.2f}" for m in COLLAPSE_MODES))
    print("missed: downsampling cycles that stopped above their face target (all modes)")
    if args.out:
        with open(args.out, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)


if __name__ == "__main__":
    main()
