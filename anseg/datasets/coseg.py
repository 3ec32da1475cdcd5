"""The original COSEG layout (Wang et al. 2012, Sidi et al. 2011): one folder per set, per-face labels.

Layout under the data root (``category`` names the set, e.g. "Vases")::

    coseg/<Set>/shapes/<stem>.off
    coseg/<Set>/gt/<stem>.seg      one integer label per face, in face order

Labels may be 0- or 1-based: the smallest label over all ``.seg`` files of
the set decides (0 or 1; anything else is an error), so one mesh lacking
part 0 cannot shift its labels. Label names are ``part_<label as in the
files>``, as many as the largest label of the set asks for.

The published sets have no fixed train/test split. Split ``k`` follows the
rule behind ``psb_splits.json``: the shapes in natural order of their stems,
shuffled with ``random.Random(k)``; the first ``round(train_fraction * n)``
are the training set (default 0.6, PSB's 12 of 20).
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from pathlib import Path

from anseg.datasets.archive import dataset_folder
from anseg.datasets.common import (
    DatasetError,
    LabeledMesh,
    labeled_mesh,
    natural_key,
    progress_bar,
    read_integer_column,
    read_mesh,
)

FOLDER = "coseg"


def shuffled_split(ids: Sequence, split_index: int, n_train: int) -> dict[str, list]:
    """Split ``ids`` with ``random.Random(split_index)``: ``n_train`` for training, the rest for testing.

    Both parts keep the order of ``ids``.
    """
    if not 0 < n_train < len(ids):
        raise DatasetError(f"cannot split {len(ids)} shapes into {n_train} for training and at least one for testing")
    order = list(range(len(ids)))
    random.Random(split_index).shuffle(order)
    train = sorted(order[:n_train])
    test = sorted(order[n_train:])
    return {"train": [ids[i] for i in train], "test": [ids[i] for i in test]}


def zero_based(labels_by_file: dict, where: Path) -> tuple[dict, list[str]]:
    """Shift a set's integer labels to 0-based and name the classes.

    The base is the smallest label over the whole set (0 or 1). Returns the
    shifted labels (same keys) and the names ``part_<label as in the files>``.
    """
    if not labels_by_file:
        raise DatasetError(f"{where}: no label files")
    lowest = min(int(labels.min()) for labels in labels_by_file.values())
    highest = max(int(labels.max()) for labels in labels_by_file.values())
    if lowest not in (0, 1):
        raise DatasetError(f"{where}: smallest label is {lowest}; labels must be 0- or 1-based")
    names = [f"part_{value}" for value in range(lowest, highest + 1)]
    return {key: labels - lowest for key, labels in labels_by_file.items()}, names


def load(root: Path, category: str | None, split: str, split_index: int = 0,
         progress: bool = True, train_fraction: float = 0.6) -> list[LabeledMesh]:
    """Read COSEG set ``category`` in ``split`` ("train", "test" or "all") of shuffled split ``split_index``."""
    base = dataset_folder(root, FOLDER)
    present = sorted(p.name for p in base.iterdir() if (p / "shapes").is_dir())
    if category not in present:
        raise DatasetError(f"COSEG needs a set name as category; got {category!r}, "
                           f"sets under {base}: {', '.join(present) or 'none'}")
    folder = base / category
    mesh_paths = sorted((folder / "shapes").glob("*.off"), key=lambda p: natural_key(p.stem))
    if not mesh_paths:
        raise DatasetError(f"{folder / 'shapes'}: no .off meshes")
    face_labels, names = zero_based({p.stem: read_integer_column(folder / "gt" / f"{p.stem}.seg") for p in mesh_paths},
                                    folder / "gt")
    if split != "all":
        if not 0 < train_fraction < 1:
            raise DatasetError(f"train_fraction must be between 0 and 1, got {train_fraction}")
        mesh_paths = shuffled_split(mesh_paths, split_index, round(train_fraction * len(mesh_paths)))[split]
    meshes = []
    for path in progress_bar(mesh_paths, f"COSEG {category} {split}", progress):
        mesh = read_mesh(path)
        labels = face_labels[path.stem]
        if len(labels) != mesh.n_faces:
            raise DatasetError(f"{folder / 'gt' / (path.stem + '.seg')}: {len(labels)} labels "
                               f"but {path.name} has {mesh.n_faces} faces")
        meshes.append(labeled_mesh(mesh, labels, names, f"{category}/{path.stem}", path))
    return meshes
