"""Per-level health of a trained model's hierarchy: input scale, giant faces, attention at boundaries.

    python benchmarks/levels.py results/validation/runs/<key>.json [...] [--with priority=weighted] [--out levels.csv]
                                [--render hierarchy.png]

Each argument is a stored validation cell (:mod:`anseg.study.validate`): its model
(``results/validation/models/<training_key>.pt``) is run on the cell's
held-out TRAINING meshes, once in the model's own mode, once with the
uniform collapse and once per ``--with`` (SegmentConfig overrides of the
model's settings, e.g. another collapse priority), and for every level this prints the means over meshes of:

* ``z99`` / ``zmax``: the 99th percentile and the maximum over faces of each
  face's largest standardised input (|x - mean| / std with the model's
  level-0 statistics): how far a level sits outside what the network was
  fitted on;
* ``giant``: the largest number of input faces that one face of the level
  stands for, and ``giant_share``: the share of input faces that sit in a
  face standing for more than 8x the level's mean (weighted by input faces,
  so a few giant faces cannot hide among many small ones); ``vs uniform``:
  the largest over meshes of the level's largest face over the largest face
  of the uniform hierarchy of the same mesh and level (the issue's giant-face
  criterion: at most 8);
* ``own``: the share of the level's area that the network's prediction on
  that level alone labels as the level's pooled ground truth (each face the
  area majority of the input faces it stands for): how well the classifier
  reads the level, before anything is carried back to the input faces
  (a model with coarse context is read without it here);
* ``auc``: the ROC AUC of the attention for faces within 2 rings of another
  label (the pooled ground truth) against the rest, on the levels that are
  collapsed (0.5: attention says nothing about boundaries).
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from sklearn.metrics import roc_auc_score

from anseg import datasets
from anseg.collapse import CollapseWarning, rings_to_other_label
from anseg.configs import parse_overrides
from anseg.metrics import accuracy
from anseg.pipeline import Segmenter, build_levels, level_features, level_output
from anseg.study.comparison import csv_text

GIANT_FACTOR = 8
BAND_RINGS = 2


def hierarchy(item, model: Segmenter, config) -> tuple[list, list[np.ndarray]]:
    """The levels of one mesh's hierarchy, and for each the number of input faces every face stands for."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CollapseWarning)
        levels = build_levels(item.mesh, model, config)
    stands_for = [np.bincount(levels.input_to_level(i), minlength=level.mesh.n_faces) if i
                  else np.ones(level.mesh.n_faces, int) for i, level in enumerate(levels)]
    return levels, stands_for


def level_statistics(item, model: Segmenter, config) -> list[dict]:
    """The statistics of every level of one mesh's hierarchy (module docstring)."""
    levels, counts = hierarchy(item, model, config)
    model.network.eval()
    rows = []
    for index, (level, stands_for, target) in enumerate(zip(levels, counts,
                                                            levels.labels_on_every_level(item.labels, model.n_classes))):
        raw = level_features(level, index, len(levels), config.local_scale)
        largest = np.abs(model.standardize(raw)).max(axis=1)
        with torch.no_grad():
            logits = level_output(model, levels, index).logits
        predicted = logits.argmax(dim=1).numpy()
        mean = stands_for.sum() / level.mesh.n_faces
        row = {"level": index, "faces": level.mesh.n_faces, "z99": float(np.percentile(largest, 99)),
               "zmax": float(largest.max()), "giant": int(stands_for.max()),
               "giant_share": float(stands_for[stands_for > GIANT_FACTOR * mean].sum() / stands_for.sum()),
               "own": accuracy(predicted, target, level.mesh.face_areas), "auc": np.nan}
        if level.attention is not None:
            band = rings_to_other_label(level.mesh, target) <= BAND_RINGS
            if 0 < band.sum() < len(band):
                row["auc"] = float(roc_auc_score(band, level.attention))
        rows.append(row)
    return rows


def render_hierarchies(item, model: Segmenter, variants: dict, path: Path) -> None:
    """Fig. 4-style panel: each hierarchy's levels, faces coloured by log2 of the input faces they stand for."""
    from anseg import viz

    images, titles = [], []
    for name, overrides in variants.items():
        levels, counts = hierarchy(item, model, replace(model.config, **overrides))
        for index, (level, stands_for) in enumerate(zip(levels, counts)):
            images.append(viz.render(level.mesh, face_scalars=np.log2(stands_for), cmap="viridis", clim=(0, 10),
                                     window_size=(360, 360)))
            titles.append(f"{name}\nlevel {index}: {level.mesh.n_faces} faces, largest {stands_for.max()}")
    viz.render_panel(images, titles, path, ncols=len(levels), title=f"{item.name} (held-out training mesh)",
                     colorbar={"cmap": "viridis", "vmin": 0, "vmax": 10, "label": "log2(input faces per face)"})


def _mean(values) -> float:
    """The mean of the values that are not NaN (NaN when none is)."""
    values = np.asarray(values, dtype=float)
    return float(values[~np.isnan(values)].mean()) if (~np.isnan(values)).any() else float("nan")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cells", nargs="+", type=Path, help="stored validation cells (results/validation/runs/<key>.json)")
    parser.add_argument("--with", dest="variants", action="append", default=[],
                        help="field=value[,...]: also run the hierarchy with these SegmentConfig overrides")
    parser.add_argument("--out", type=Path, help="also write the rows as CSV")
    parser.add_argument("--render", type=Path, help="also render the first cell's first held-out mesh's hierarchies (PNG)")
    args = parser.parse_args(argv)

    torch.set_num_threads(1)
    table = []
    for path in args.cells:
        cell = json.loads(path.read_text())
        model = Segmenter.load(path.parent.parent / "models" / f"{cell['training_key']}.pt")
        meshes = datasets.load(cell["dataset"], cell["category"], "train", cell["split_index"], progress=False)
        held_out = [m for m in meshes if m.name in set(cell["held_out"])]
        variants = {model.config.mode: {}, "uniform": {"mode": "uniform"}}
        variants.update({text: parse_overrides(text)[0] for text in args.variants})
        per_mesh = {name: [level_statistics(item, model, replace(model.config, **overrides)) for item in held_out]
                    for name, overrides in variants.items()}
        for name, meshes_rows in per_mesh.items():
            for index in range(len(meshes_rows[0])):
                values = {k: _mean([rows[index][k] for rows in meshes_rows]) for k in meshes_rows[0][index] if k != "level"}
                # the criterion is per mesh: this hierarchy's largest face over the uniform one's, same mesh and level
                values["giant_vs_uniform"] = max(rows[index]["giant"] / uniform[index]["giant"]
                                                 for rows, uniform in zip(meshes_rows, per_mesh["uniform"]))
                table.append({"arm": cell["arm"], "category": cell["category"], "hierarchy": name, "level": index, **values})
        if args.render and path == args.cells[0]:
            render_hierarchies(held_out[0], model, variants, args.render)
    print(f"{'arm':<16} {'category':<10} {'hierarchy':<18} lvl  faces    z99     zmax   giant  share  own   auc  vs uniform")
    for r in table:
        print(f"{r['arm']:<16} {r['category']:<10} {r['hierarchy']:<18} {r['level']:>3} {r['faces']:6.0f} {r['z99']:7.1f} "
              f"{r['zmax']:8.1f} {r['giant']:6.0f} {r['giant_share']:6.3f} {r['own']:5.3f} "
              f"{r['auc']:5.2f} {r['giant_vs_uniform']:6.2f}")
    if args.out:
        args.out.write_text(csv_text(table))


if __name__ == "__main__":
    main()
