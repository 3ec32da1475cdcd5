"""The benchmark data sets as lists of meshes with per-face labels.

``load(name, category=None, split="train", split_index=0, root=None)`` returns
a list of :class:`LabeledMesh`. The data sits under the data root (``root=``,
else ``$ANSEG_DATA``), as the archives are distributed or as their extracted
folders (see :mod:`anseg.datasets.archive`). One reader per layout:

* ``psb``: Princeton Segmentation Benchmark, Kalogerakis labels (:mod:`.psb`);
  a ``category`` and one of the five fixed splits;
* ``coseg_aliens``, ``coseg_chairs``, ``coseg_vases``, ``human_seg``: the
  MeshCNN distributions with per-edge labels (:mod:`.meshcnn`); one fixed split;
* ``coseg``: the original COSEG layout, ``category`` = the set (:mod:`.coseg`);
* ``maron``: the original Maron et al. 2017 layout (:mod:`.maron`);
* ``synthetic``: procedurally generated shapes, no data needed (:mod:`.synthetic`).

Labels are 0-based and index ``label_names``, which every mesh of a data set
(or PSB category) shares, so train and test agree. A mesh that fails
:meth:`Mesh.validate` is repaired and keeps ``face_map``, the input index of
each face (its labels are carried over).
"""

from __future__ import annotations

import os

from anseg.datasets import coseg, maron, meshcnn, psb
from anseg.datasets.archive import DatasetError, data_root
from anseg.datasets.common import SPLITS, LabeledMesh
from anseg.datasets.psb import PSB_CATEGORIES, PSB_SPLIT_COUNT, psb_split

DATASETS = ("psb", "coseg_aliens", "coseg_chairs", "coseg_vases", "human_seg", "coseg", "maron", "synthetic")


def load(name: str, category: str | None = None, split: str = "train", split_index: int = 0,
         root: str | os.PathLike | None = None, **options) -> list[LabeledMesh]:
    """Read a data set (or a PSB / COSEG category) as a list of :class:`LabeledMesh`.

    ``split`` is "train", "test" or "all"; ``split_index`` picks one of the
    fixed splits where a data set has several (PSB: 0-4). ``options`` go to
    the reader: ``progress=False`` hides the progress bar; ``synthetic``
    takes its generator's settings (``n_shapes``, ``seed``, ...).
    """
    if split not in SPLITS:
        raise DatasetError(f"unknown split {split!r}; valid splits: {', '.join(SPLITS)}")
    if name == "synthetic":  # imported on use: it needs no data root
        from anseg.datasets.synthetic import load as load_synthetic

        return load_synthetic(category=category, split=split, split_index=split_index, root=root, **options)
    if name not in DATASETS:
        raise DatasetError(f"unknown data set {name!r}; valid names: {', '.join(DATASETS)}")
    root = data_root(root)
    if name == "psb":
        return psb.load(root, category, split, split_index, **options)
    if name == "coseg":
        return coseg.load(root, category, split, split_index, **options)
    if category is not None:
        raise DatasetError(f"{name} has no categories (got category={category!r})")
    if split_index != 0:
        raise DatasetError(f"{name} has one fixed train/test split; split_index must be 0 (got {split_index})")
    if name == "maron":
        return maron.load(root, split, **options)
    return meshcnn.load(root, name, split, **options)


__all__ = [
    "DATASETS",
    "PSB_CATEGORIES",
    "PSB_SPLIT_COUNT",
    "SPLITS",
    "DatasetError",
    "LabeledMesh",
    "data_root",
    "load",
    "psb_split",
]
