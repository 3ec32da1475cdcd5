"""What the data set readers share: the labelled mesh they return, reading and repairing a mesh, small parsers."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anseg.datasets.archive import DatasetError
from anseg.mesh import Mesh, MeshError, degenerate_faces, repair
from anseg.mesh_files import load_mesh
from anseg.progress import progress

SPLITS = ("train", "test", "all")
PROGRESS_MIN_MESHES = 10  # show a progress bar when loading at least this many meshes


@dataclass
class LabeledMesh:
    """A mesh with one 0-based label per face.

    ``soft_labels`` (F, C) are per-face class weights where the source has
    them; ``face_map`` is the input face index of every face when the file's
    mesh had to be repaired; ``label_ties`` counts the input faces whose label
    came from a tie rule (per-edge or per-vertex labels with three different
    values around the face), see :mod:`.meshcnn`.
    """

    mesh: Mesh
    labels: np.ndarray
    label_names: list[str]
    name: str
    soft_labels: np.ndarray | None = None
    face_map: np.ndarray | None = None
    label_ties: int = 0

    def __post_init__(self):
        self.labels = np.asarray(self.labels, dtype=np.int64)
        n_faces, n_classes = self.mesh.n_faces, len(self.label_names)
        if self.labels.shape != (n_faces,):
            raise DatasetError(f"{self.name}: {self.labels.shape[0]} labels for {n_faces} faces")
        if n_faces and (self.labels.min() < 0 or self.labels.max() >= n_classes):
            raise DatasetError(f"{self.name}: labels span [{self.labels.min()}, {self.labels.max()}] "
                               f"but there are {n_classes} label names")
        if self.soft_labels is not None:
            self.soft_labels = np.asarray(self.soft_labels, dtype=np.float64)
            if self.soft_labels.shape != (n_faces, n_classes):
                raise DatasetError(f"{self.name}: soft labels of shape {self.soft_labels.shape}, expected {(n_faces, n_classes)}")
        if self.face_map is not None and len(self.face_map) != n_faces:
            raise DatasetError(f"{self.name}: face_map has {len(self.face_map)} entries for {n_faces} faces")


def labeled_mesh(mesh: Mesh, labels, label_names, name: str, source, soft_labels=None, label_ties: int = 0) -> LabeledMesh:
    """Wrap a mesh read from ``source`` and its per-face labels, repairing the mesh if it fails validation.

    Labels (and soft labels) are given for the faces as read; after a repair
    they follow the kept faces through ``face_map``.
    """
    face_map = None
    try:
        mesh.validate()
        if (thin := int(degenerate_faces(mesh).sum())) > 0:
            # slivers pass validate, yet the readers drop them as they did when it refused them: the stored runs and
            # the shipped models read the benchmark meshes so
            raise MeshError(f"{thin} slivers")
    except MeshError as problem:
        try:
            mesh, face_map = repair(mesh, drop_slivers=True)
            mesh.validate()
        except MeshError as left:
            raise DatasetError(f"{source}: {problem}; repair did not fix it: {left}") from None
        labels = np.asarray(labels)[face_map]
        soft_labels = None if soft_labels is None else np.asarray(soft_labels)[face_map]
    return LabeledMesh(mesh, labels, list(label_names), name, soft_labels, face_map, label_ties)


def read_mesh(path: Path) -> Mesh:
    """The mesh in ``path`` as written (not validated: :func:`labeled_mesh` does that); DatasetError if unreadable."""
    try:
        return load_mesh(path, validate=False)
    except MeshError as exc:
        raise DatasetError(str(exc)) from None


def natural_key(text: str) -> tuple:
    """Sort key that orders embedded numbers by value ("2" before "10")."""
    return tuple(int(part) if part.isdigit() else part for part in re.split(r"(\d+)", text))


def read_table(path: os.PathLike, columns: int | None = None) -> np.ndarray:
    """A whitespace-separated table of numbers, one row per non-empty line, as (rows, columns) float64.

    Raises DatasetError naming the file if a value is not a number or rows differ in length.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: no such file")
    text = path.read_text()
    widths = [len(line.split()) for line in text.splitlines() if line.strip()]
    if not widths:
        raise DatasetError(f"{path}: empty file")
    if set(widths) != ({columns} if columns is not None else {widths[0]}):
        wanted = f"{columns} value(s) per line" if columns is not None else "lines of equal length"
        raise DatasetError(f"{path}: lines hold {'/'.join(map(str, sorted(set(widths))))} values; expected {wanted}")
    try:
        values = np.array(text.split(), dtype=np.float64)
    except ValueError as exc:
        raise DatasetError(f"{path}: not a table of numbers ({exc})") from None
    return values.reshape(len(widths), -1)


def read_integer_column(path: os.PathLike) -> np.ndarray:
    """One integer per non-empty line (written as "3" or "3.0"), as int64; DatasetError otherwise."""
    values = read_table(path, columns=1)[:, 0]
    if not (values == np.round(values)).all():
        raise DatasetError(f"{path}: expected one integer label per line, found {values[values != np.round(values)][0]}")
    return values.astype(np.int64)


def progress_bar(items, description: str, enabled: bool = True):
    """``items`` wrapped in a tqdm bar when there are many of them and ``enabled``."""
    return progress(items, show=enabled and len(items) >= PROGRESS_MIN_MESHES, desc=description, unit="mesh", leave=False)
