"""Data sets as MeshCNN distributes them, with per-edge labels: the large COSEG sets and human_seg.

Layout (``coseg.tar.gz`` holds the three ``coseg_*`` sets, ``human_seg.tar.gz``
the human one; or their extracted folders)::

    <set>/train/*.obj   <set>/test/*.obj
    <set>/seg/<stem>.eseg     one 1-based label per undirected edge
    <set>/sseg/<stem>.seseg   one row of per-class weights per edge (optional)
    <set>/classes.txt         one class name per line (optional)

Edges are numbered as :attr:`anseg.mesh.Mesh.edges` numbers them (faces in file
order, local edges (v0,v1), (v1,v2), (v2,v0), a new number at an edge's first
appearance); ``load_mesh`` keeps the OBJ's order, so the numbering matches the
files, and the label count must equal the edge count.

Per-face labels: the majority of the face's three edge labels; when all three
differ, the label of its longest edge, along which it borders that part most
(counted in ``LabeledMesh.label_ties``). Soft labels: the mean of the three
edges' rows. Names: ``classes.txt``, else ``part_<label as in the files>``; the class
count is the larger of the names listed and the largest label in the set, so
every mesh of a set shares it (soft columns beyond it must be zero and are
dropped). Label files without a mesh are ignored.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from anseg.datasets.archive import dataset_folder
from anseg.datasets.common import (
    DatasetError,
    LabeledMesh,
    labeled_mesh,
    natural_key,
    progress_bar,
    read_integer_column,
    read_mesh,
    read_table,
)
from anseg.mesh import Mesh

ARCHIVES = {"coseg_aliens": "coseg.tar.gz", "coseg_chairs": "coseg.tar.gz", "coseg_vases": "coseg.tar.gz",
            "human_seg": "human_seg.tar.gz"}


def majority_of_three(votes: np.ndarray, priority: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``votes`` (N, 3): the value held by at least two entries, else the entry of largest ``priority``.

    Returns the chosen values (N,) and a boolean mask (N,) of the rows that
    needed the tie rule (three different values). Equal priorities pick the
    first entry.
    """
    a, b, c = votes.T
    chosen = np.where((a == b) | (a == c), a, np.where(b == c, b, -1))
    ties = chosen == -1
    rows = np.flatnonzero(ties)
    chosen[rows] = votes[rows, np.argmax(priority[rows], axis=1)]
    return chosen, ties


def edge_labels_to_faces(mesh: Mesh, edge_labels: np.ndarray) -> tuple[np.ndarray, int]:
    """Per-face labels from per-edge labels (in :attr:`Mesh.edges` order), and the number of three-way ties."""
    votes = edge_labels[mesh.face_edges]
    labels, ties = majority_of_three(votes, mesh.edge_lengths[mesh.face_edges])
    return labels, int(ties.sum())


def _class_names(folder: Path, edge_labels: dict[str, np.ndarray]) -> list[str]:
    listed = folder / "classes.txt"
    names = [line.strip() for line in listed.read_text().splitlines() if line.strip()] if listed.is_file() else []
    n_used = max(int(labels.max()) for labels in edge_labels.values()) + 1  # labels are 0-based here
    if names and n_used > len(names):
        raise DatasetError(f"{listed} lists {len(names)} classes but the .eseg files use label {n_used}")
    return names or [f"part_{i + 1}" for i in range(n_used)]


def _read_edge_labels(folder: Path) -> dict[str, np.ndarray]:
    """Every ``seg/*.eseg`` of the set, 0-based, by stem."""
    files = sorted((folder / "seg").glob("*.eseg"))
    if not files:
        raise DatasetError(f"{folder / 'seg'}: no .eseg label files")
    out = {}
    for path in files:
        labels = read_integer_column(path)
        if labels.min() < 1:
            raise DatasetError(f"{path}: label {labels.min()} found; .eseg labels are 1-based")
        out[path.stem] = labels - 1
    return out


def _read_soft_labels(path: Path, n_edges: int, n_classes: int) -> np.ndarray:
    soft = read_table(path)
    if soft.shape[0] != n_edges:
        raise DatasetError(f"{path}: {soft.shape[0]} rows but the mesh has {n_edges} edges")
    if soft.shape[1] < n_classes or (soft[:, n_classes:] != 0).any():
        raise DatasetError(f"{path}: {soft.shape[1]} columns of class weights for {n_classes} classes")
    return soft[:, :n_classes]


def load(root: Path, name: str, split: str, progress: bool = True) -> list[LabeledMesh]:
    """Read the MeshCNN-layout set ``name`` ("train", "test" or "all" = train then test)."""
    folder = dataset_folder(root, name, ARCHIVES[name])
    edge_labels = _read_edge_labels(folder)
    names = _class_names(folder, edge_labels)
    soft_folder = folder / "sseg"
    parts = ("train", "test") if split == "all" else (split,)
    paths = [p for part in parts for p in sorted((folder / part).glob("*.obj"), key=lambda p: natural_key(p.name))]
    if not paths:
        raise DatasetError(f"{folder}: no .obj meshes in {' or '.join(f'{part}/' for part in parts)}")
    meshes = []
    for path in progress_bar(paths, f"{name} {split}", progress):
        if path.stem not in edge_labels:
            raise DatasetError(f"{path}: no label file {folder / 'seg' / (path.stem + '.eseg')}")
        mesh = read_mesh(path)
        per_edge = edge_labels[path.stem]
        if len(per_edge) != len(mesh.edges):
            raise DatasetError(
                f"{folder / 'seg' / (path.stem + '.eseg')}: {len(per_edge)} labels but {path.name} has {len(mesh.edges)} edges "
                "(labels follow the first-appearance edge order of the faces)"
            )
        labels, ties = edge_labels_to_faces(mesh, per_edge)
        soft = None
        if soft_folder.is_dir():
            soft_edges = _read_soft_labels(soft_folder / f"{path.stem}.seseg", len(mesh.edges), len(names))
            soft = soft_edges[mesh.face_edges].mean(axis=1)
        meshes.append(labeled_mesh(mesh, labels, names, f"{name}/{path.parent.name}/{path.stem}", path, soft, ties))
    return meshes
