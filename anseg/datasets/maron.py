"""The original human body set of Maron et al. 2017 (full resolution), per-face or per-vertex labels.

Layout under the data root (the authors' extracted benchmark folder, renamed
or linked to ``maron``)::

    maron/meshes/{train,test}/**/<stem>.{off,obj,ply}
    maron/segs/{train,test}/**/<stem>.txt     one integer label per line

A mesh's label file mirrors its path (``meshes/train/faust/a.off`` ->
``segs/train/faust/a.txt``); where that file is absent and the mirrored
folder holds exactly one ``.txt``, that file labels every mesh of the folder
(meshes sharing one connectivity, as FAUST's do). A file with one line per
face gives per-face labels; one with a line per vertex gives per-vertex
labels, turned per-face by the majority of the three vertices, or, when all
three differ, the label of the vertex with the largest inner angle (the
corner that covers most of the face); such faces are counted in
``LabeledMesh.label_ties``. When a mesh has as many faces as vertices, the
file is read as per-face. Labels are 0- or 1-based, decided over the whole set
as for COSEG; names are ``part_<label as in the files>``. The split is the
set's own train/test folders.
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
)
from anseg.datasets.coseg import zero_based
from anseg.datasets.meshcnn import majority_of_three
from anseg.mesh import Mesh
from anseg.mesh_files import SUPPORTED_SUFFIXES

FOLDER = "maron"


def inner_angles(mesh: Mesh) -> np.ndarray:
    """(F, 3) the angle of each face at each of its corners (0 for degenerate corners)."""
    corners = mesh.vertices[mesh.faces]
    to_next = np.roll(corners, -1, axis=1) - corners
    to_previous = np.roll(corners, 1, axis=1) - corners
    cosine = (to_next * to_previous).sum(axis=2)
    sine = np.linalg.norm(np.cross(to_next, to_previous), axis=2)
    return np.arctan2(sine, cosine)


def vertex_labels_to_faces(mesh: Mesh, vertex_labels: np.ndarray) -> tuple[np.ndarray, int]:
    """Per-face labels from per-vertex labels, and the number of three-way ties."""
    labels, ties = majority_of_three(vertex_labels[mesh.faces], inner_angles(mesh))
    return labels, int(ties.sum())


def label_file(segs: Path, relative: Path) -> Path:
    """The label file of the mesh at ``meshes/<relative>``: mirrored path, else the folder's only .txt."""
    mirrored = (segs / relative).with_suffix(".txt")
    if mirrored.is_file():
        return mirrored
    shared = sorted(mirrored.parent.glob("*.txt"))
    if len(shared) == 1:
        return shared[0]
    raise DatasetError(f"no label file for meshes/{relative}: expected {mirrored}"
                       + (f" (its folder holds {len(shared)} others)" if shared else ""))


def load(root: Path, split: str, progress: bool = True) -> list[LabeledMesh]:
    """Read the Maron et al. set in ``split`` ("train", "test" or "all" = train then test)."""
    folder = dataset_folder(root, FOLDER)
    meshes_dir, segs_dir = folder / "meshes", folder / "segs"
    relative = {
        part: sorted(
            (p.relative_to(meshes_dir) for p in (meshes_dir / part).rglob("*") if p.suffix.lower() in SUPPORTED_SUFFIXES),
            key=lambda p: natural_key(p.as_posix()),
        )
        for part in ("train", "test")
    }
    sources = {path: label_file(segs_dir, path) for paths in relative.values() for path in paths}
    if not sources:
        raise DatasetError(f"{meshes_dir}: no meshes under train/ or test/")
    # labels of the whole set, so that train and test agree on the base and the class count
    raw = {source: read_integer_column(source) for source in set(sources.values())}
    file_labels, names = zero_based(raw, segs_dir)
    chosen = [path for part in (("train", "test") if split == "all" else (split,)) for path in relative[part]]
    if not chosen:
        raise DatasetError(f"{meshes_dir / split}: no meshes")
    meshes = []
    for path in progress_bar(chosen, f"Maron {split}", progress):
        mesh = read_mesh(meshes_dir / path)
        labels, source, ties = file_labels[sources[path]], sources[path], 0
        if len(labels) == mesh.n_vertices and len(labels) != mesh.n_faces:
            labels, ties = vertex_labels_to_faces(mesh, labels)
        elif len(labels) != mesh.n_faces:
            raise DatasetError(f"{source}: {len(labels)} labels, but meshes/{path} has "
                               f"{mesh.n_faces} faces and {mesh.n_vertices} vertices")
        meshes.append(labeled_mesh(mesh, labels, names, path.with_suffix("").as_posix(), meshes_dir / path, label_ties=ties))
    return meshes
