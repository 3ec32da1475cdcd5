"""How well a stored model fits the meshes it was trained on: bias read, not guessed.

    python benchmarks/training_fit.py psb/Hand [psb/FourLeg ...]
    python benchmarks/training_fit.py --cell results/validation/fit/runs/KEY.json [--models DIR] [--csv PATH]

A shipped model (by name) is scored on its run's training meshes; a validation
cell (its stored record) with its model under ``--models`` (default: the
``models`` folder beside the record's ``runs``) on the training meshes it
lists. Printed per mesh and pooled (Eq. 5, unit area), beside the held-out
accuracy the run stored, then the label pairs that lose the most area
(true -> predicted, % of the training meshes' surface). A network far from
fitting its own meshes is stopped before it has learned: more steps or
capacity, or information its inputs lack, not regularisation.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from anseg import datasets, metrics, pretrained
from anseg.pipeline import Segmenter
from anseg.train import evaluate

REPO = Path(__file__).resolve().parents[1]
WORST_PAIRS = 5


def shipped(name: str) -> tuple[Segmenter, list, dict]:
    """A shipped model, the training meshes of its run, and that run's record."""
    record = json.loads((REPO / "results" / "runs" / f"{pretrained.card(name)['run']}.json").read_text())
    meshes = datasets.load(record["dataset"], record.get("category"), "train", record["split_index"], progress=False,
                           **record.get("dataset_options", {}))
    return Segmenter.pretrained(name), meshes, record


def cell(path: Path, models: Path | None) -> tuple[Segmenter, list, dict]:
    """A validation cell's model and the training meshes its record lists (the held-out ones are left out)."""
    record = json.loads(path.read_text())
    model_file = (models or path.parent.parent / "models") / f"{record['training_key']}.pt"
    if not model_file.is_file():
        raise ValueError(f"{model_file}: no such model file (cells keep their models only where they trained)")
    names = set(record["train_meshes"])
    meshes = [m for m in datasets.load(record["dataset"], record["category"], "train", record["split_index"],
                                       progress=False) if m.name in names]
    return Segmenter.load(model_file), meshes, record


def report(title: str, model: Segmenter, meshes: list, record: dict) -> dict:
    """Print the fit of one model on its training meshes; returns its row (training and held-out accuracy, %)."""
    scores = evaluate(model, meshes, progress=False)
    held_out = 100 * record["accuracy"]["unit_area"]
    print(f"\n{title}: {len(meshes)} training meshes, {100 * scores['smoothed']['unit_area']:.2f} % on them "
          f"(held out: {held_out:.2f} %)")
    for row in scores["per_mesh"]:
        print(f"  {row['name']:<20} {100 * row['accuracy']:6.2f}")
    n = len(model.label_names)
    confusion = sum(metrics.confusion_matrix(p, m.labels, n, m.mesh.face_areas / m.mesh.face_areas.sum())
                    for p, m in zip(scores["predictions"], meshes)) / len(meshes)
    np.fill_diagonal(confusion, 0.0)
    order = np.argsort(confusion, axis=None)[::-1][:WORST_PAIRS]
    pairs = [np.unravel_index(i, confusion.shape) for i in order if confusion.flat[i] > 0]
    print("  most area lost (true -> predicted): " + ", ".join(
        f"{model.label_names[t]} -> {model.label_names[p]} {100 * confusion[t, p]:.1f}" for t, p in pairs))
    return {"model": title, "category": record.get("category"), "training_meshes": len(meshes),
            "on_training_meshes": 100 * scores["smoothed"]["unit_area"], "held_out": held_out}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="shipped models (`anseg models` lists them)")
    parser.add_argument("--cell", type=Path, action="append", default=[], help="a validation cell's record (repeatable)")
    parser.add_argument("--models", type=Path, help="the folder of the cells' models (default: beside their runs)")
    parser.add_argument("--csv", type=Path, help="also write the rows (model, category, both accuracies) here")
    args = parser.parse_args(argv)
    if not args.names and not args.cell:
        parser.error("name a shipped model or a --cell")
    rows = []
    try:
        for name in args.names:
            rows.append(report(name, *shipped(name)))
        for path in args.cell:
            model, meshes, record = cell(path, args.models)
            rows.append(report(f"{record['arm']} {record['category']} fold {record['fold']} seed {record['seed']}",
                               model, meshes, record))
        if args.csv:
            from anseg.study.comparison import csv_text

            args.csv.write_text(csv_text(rows))
    except (ValueError, OSError) as exc:
        print(f"training_fit: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
