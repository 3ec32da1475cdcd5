"""Compare settings on held-out TRAINING meshes, never on the test split (how defaults get chosen).

    python benchmarks/holdout.py --category Human [--holdout 3] [--epochs 60] --variant once_per_pass=true ...

Trains on the first 12 - holdout training meshes of PSB split 0 and scores
the last ``holdout`` (Eq. 5, unit area, graph cut on and off), once with the
default settings and once per ``--variant``: ``name=value`` pairs separated
by commas, SegmentConfig fields as they are and TrainConfig fields with a
``train.`` prefix (``--variant train.attention_weight=0``).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import fields

from anseg import datasets
from anseg.pipeline import SegmentConfig
from anseg.train import TrainConfig, evaluate, fit


def parse_variant(text: str) -> tuple[dict, dict]:
    """``"once_per_pass=true,train.epochs=90"`` -> (SegmentConfig, TrainConfig) keyword arguments, typed like the defaults."""
    defaults = {"": SegmentConfig(), "train.": TrainConfig()}
    types = {prefix + f.name: type(getattr(config, f.name)) for prefix, config in defaults.items() for f in fields(config)}
    segment, train = {}, {}
    for item in filter(None, text.split(",")):
        name, _, value = item.partition("=")
        if name not in types:
            raise SystemExit(f"unknown setting {name!r}; settings: {', '.join(types)}")
        typed = value.lower() in ("1", "true", "yes") if types[name] is bool else types[name](value)
        if name.startswith("train."):
            train[name[len("train."):]] = typed
        else:
            segment[name] = typed
    return segment, train


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--category", default="Human")
    parser.add_argument("--holdout", type=int, default=3)
    parser.add_argument("--epochs", type=int, default=60)
    parser.add_argument("--variant", action="append", default=[], help="SegmentConfig overrides, name=value[,name=value]")
    parser.add_argument("--only-variants", action="store_true", help="skip the default configuration")
    args = parser.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    meshes = datasets.load("psb", category=args.category, split="train", split_index=0, progress=False)
    train_set, held_out = meshes[:-args.holdout], meshes[-args.holdout:]
    variants = ([] if args.only_variants else [({}, {})]) + [parse_variant(v) for v in args.variant]
    for segment_overrides, train_overrides in variants:
        started = time.time()
        settings = TrainConfig(**{"epochs": args.epochs, **train_overrides})
        model = fit(train_set, train_set[0].label_names, SegmentConfig(**segment_overrides), settings, progress=False)
        scores = evaluate(model, held_out, progress=False)
        print(json.dumps({"category": args.category, "train": len(train_set), "held_out": [m.name for m in held_out],
                          "overrides": {**segment_overrides, **{f"train.{k}": v for k, v in train_overrides.items()}},
                          "unit_area": round(100 * scores["smoothed"]["unit_area"], 2),
                          "unit_area_unsmoothed": round(100 * scores["unsmoothed"]["unit_area"], 2),
                          "seconds": round(time.time() - started)}), flush=True)


if __name__ == "__main__":
    main()
