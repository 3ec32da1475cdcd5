"""The Princeton Segmentation Benchmark with the semantic labels of Kalogerakis et al. 2010.

Layout (``psb_labeled.tar.gz`` or its extracted folder)::

    LabeledDB_new/<Category>/<id>.off
    LabeledDB_new/<Category>/<id>_labels.txt

A label file alternates lines: a part name, then the 1-based indices of the
faces in that part. Every face must be labelled exactly once. A category's
label names are the sorted union of the part names over all its meshes, so
that every mesh of the category (train and test alike) uses the same indices.

Splits come from ``psb_splits.json`` (package data): five fixed splits of 12
train / 8 test meshes for each of the paper's 16 categories (Bust, Bearing
and Mech have no consistent labels and no split; ``split="all"`` still reads
them).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import numpy as np

from anseg.datasets.archive import dataset_folder
from anseg.datasets.common import (
    DatasetError,
    LabeledMesh,
    labeled_mesh,
    progress_bar,
    read_mesh,
)

FOLDER = "LabeledDB_new"
ARCHIVE = "psb_labeled.tar.gz"
SPLITS_FILE = Path(__file__).with_name("psb_splits.json")


@cache
def _splits() -> list[dict]:
    return json.loads(SPLITS_FILE.read_text())["splits"]


PSB_CATEGORIES = tuple(sorted(_splits()[0]))
PSB_SPLIT_COUNT = len(_splits())


def psb_split(category: str, split_index: int = 0) -> dict[str, list[int]]:
    """The model ids of ``category`` in fixed split ``split_index``: ``{"train": [...], "test": [...]}``."""
    splits = _splits()
    if not 0 <= split_index < len(splits):
        raise DatasetError(f"PSB split_index must be in 0..{len(splits) - 1}, got {split_index}")
    if category not in splits[split_index]:
        raise DatasetError(f"PSB category {category!r} has no train/test split; "
                           f"categories with splits: {', '.join(PSB_CATEGORIES)}")
    chosen = splits[split_index][category]
    return {"train": list(chosen["train"]), "test": list(chosen["test"])}


def read_part_names(path: Path) -> list[str]:
    """The part names of a label file (its odd lines), in file order."""
    return _label_lines(path)[0::2]


def _label_lines(path: Path) -> list[str]:
    lines = [line.strip() for line in path.read_text().splitlines() if line.strip()]
    if len(lines) % 2:
        raise DatasetError(f"{path}: {len(lines)} non-empty lines; expected pairs of a part name line and a face index line")
    return lines


def category_label_names(category_folder: Path) -> list[str]:
    """Sorted union of the part names over every label file of a category folder."""
    files = sorted(category_folder.glob("*_labels.txt"))
    if not files:
        raise DatasetError(f"{category_folder}: no *_labels.txt files")
    return sorted({name for path in files for name in read_part_names(path)})


def read_face_labels(path: Path, n_faces: int, label_names: list[str]) -> np.ndarray:
    """Per-face 0-based label indices (into ``label_names``) from a PSB label file.

    Raises DatasetError naming the file when an index is not an integer or is
    out of range, or a face is labelled twice or not at all.
    """
    lines = _label_lines(path)
    index_of = {name: i for i, name in enumerate(label_names)}
    faces, labels = [], []
    for line_number, (part, indices) in enumerate(zip(lines[0::2], lines[1::2])):
        if part not in index_of:
            raise DatasetError(f"{path}: part {part!r} is not among the label names {label_names}")
        try:
            ids = np.array(indices.split(), dtype=np.int64) - 1
        except ValueError:
            raise DatasetError(f"{path}: the face index line of part {part!r} "
                               f"(pair {line_number + 1}) holds a non-integer") from None
        faces.append(ids)
        labels.append(np.full(len(ids), index_of[part], dtype=np.int64))
    faces = np.concatenate(faces) if faces else np.empty(0, dtype=np.int64)
    labels = np.concatenate(labels) if labels else np.empty(0, dtype=np.int64)
    outside = (faces < 0) | (faces >= n_faces)
    if outside.any():
        raise DatasetError(f"{path}: face index {faces[outside][0] + 1} out of range 1..{n_faces}")
    times = np.bincount(faces, minlength=n_faces)
    if (times > 1).any():
        raise DatasetError(f"{path}: {int((times > 1).sum())} faces labelled more than once "
                           f"(first: face {np.flatnonzero(times > 1)[0] + 1})")
    if (times == 0).any():
        raise DatasetError(f"{path}: {int((times == 0).sum())} of {n_faces} faces have no label "
                           f"(first: face {np.flatnonzero(times == 0)[0] + 1})")
    out = np.empty(n_faces, dtype=np.int64)
    out[faces] = labels
    return out


def load(root: Path, category: str | None, split: str, split_index: int = 0, progress: bool = True) -> list[LabeledMesh]:
    """Read the meshes of one PSB category in ``split`` ("train", "test" or "all") of split ``split_index``."""
    base = dataset_folder(root, FOLDER, ARCHIVE)
    present = sorted(p.name for p in base.iterdir() if p.is_dir())
    if category not in present:
        raise DatasetError(f"PSB needs a category; got {category!r}, valid categories: {', '.join(present)}")
    folder = base / category
    if split == "all":
        ids = sorted((int(p.stem) for p in folder.glob("*.off") if p.stem.isdigit()))
    else:
        ids = psb_split(category, split_index)[split]
    names = category_label_names(folder)
    meshes = []
    for model in progress_bar(ids, f"PSB {category} {split}", progress):
        mesh_path, label_path = folder / f"{model}.off", folder / f"{model}_labels.txt"
        if not label_path.is_file():
            raise DatasetError(f"{label_path}: missing (every PSB mesh needs its label file)")
        mesh = read_mesh(mesh_path)
        labels = read_face_labels(label_path, mesh.n_faces, names)
        meshes.append(labeled_mesh(mesh, labels, names, f"{category}/{model}", mesh_path))
    return meshes
