"""A mesh's levels, the input mesh first, and what carries values between them.

Level i's collapse record leads to level i + 1 (:mod:`anseg.collapse` keeps
the engine and the record). Values go down by pooling over the input faces
each coarse face stands for (area-weighted means; labels by area majority)
and come back up by replaying the collapses backwards, where a face that
reappears takes the vote of the faces across its outer edges
(:func:`anseg.collapse.upsample`). :class:`Hierarchy` holds the levels in
order and answers these questions by level index, so that no caller slices
the records itself. The functions below do the same for any chain of records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from anseg.collapse import CollapseRecord, upsample
from anseg.mesh import Mesh

if TYPE_CHECKING:
    import torch

    from anseg.cluster import PatchLayout
    from anseg.geometry.spectral import Spectrum


@dataclass
class Level:
    """One level: its mesh, feature groups and patch layout; ``record`` leads from it to the next level.

    A level the network never reads (the input level of a mesh segmented through a collapse,
    :data:`anseg.pipeline.NETWORK_FACES`) has no groups and no layout (None).
    """

    mesh: Mesh
    groups: dict[str, np.ndarray]
    layout: PatchLayout | None
    attention: np.ndarray | None = None
    record: CollapseRecord | None = None
    logits: torch.Tensor | None = field(default=None, repr=False)  # kept from the pass that computed the attention
    spectrum: Spectrum | None = field(default=None, repr=False)  # for a model that reads the eigenbasis


class Hierarchy(Sequence):
    """The levels of one mesh, level 0 the input; indexing and iterating give :class:`Level` objects."""

    def __init__(self, levels: Sequence[Level]):
        self._levels = list(levels)

    def __getitem__(self, index):
        return self._levels[index]

    def __len__(self) -> int:
        return len(self._levels)

    def __repr__(self) -> str:
        return f"Hierarchy({' -> '.join(str(level.mesh.n_faces) for level in self._levels)} faces)"

    def records(self, index: int) -> list[CollapseRecord]:
        """The records that lead from the input level to level ``index``."""
        return [level.record for level in self._levels[:index]]

    def input_to_level(self, index: int) -> np.ndarray | None:
        """The face of level ``index`` that each input face became (None for the input level itself)."""
        return compose(self.records(index)) if index else None

    def labels_on(self, index: int, labels: np.ndarray, n_classes: int) -> np.ndarray:
        """Input-face ``labels`` on level ``index``: each face takes the area majority of the input faces it stands for."""
        return pool_labels(self.records(index), labels, self[0].mesh.face_areas, n_classes) if index else labels

    def labels_on_every_level(self, labels: np.ndarray, n_classes: int) -> list[np.ndarray]:
        """:meth:`labels_on` for each level: the training targets of the coarse levels."""
        return [self.labels_on(index, labels, n_classes) for index in range(len(self))]

    def upsample(self, index: int, probs: np.ndarray) -> np.ndarray:
        """Class probabilities of level ``index`` carried back to the input faces."""
        return upsample_through(self.records(index), probs) if index else probs

    def round_trip(self, index: int, labels: np.ndarray, n_classes: int) -> np.ndarray:
        """Input-face ``labels`` taken to level ``index`` and carried back: the best that level can do."""
        return round_trip_labels(self.records(index), labels, self[0].mesh.face_areas, n_classes)


# --------------------------------------------------------------------------- chains of records
def compose(records: CollapseRecord | Sequence[CollapseRecord]) -> np.ndarray:
    """(F_0,) the face of the last level that stands for each face of level 0, through stacked records."""
    records = _as_list(records)
    face_map = records[0].fine_to_coarse
    for record in records[1:]:
        face_map = record.fine_to_coarse[face_map]
    return face_map


def _as_list(records) -> list[CollapseRecord]:
    records = [records] if isinstance(records, CollapseRecord) else list(records)
    if not records:
        raise ValueError("need at least one CollapseRecord")
    for i, (finer, coarser) in enumerate(zip(records, records[1:])):
        if finer.n_coarse_faces != coarser.n_fine_faces:
            raise ValueError(
                f"records {i} and {i + 1} do not chain: {finer.n_coarse_faces} coarse faces vs {coarser.n_fine_faces} fine faces"
            )
    return records


def pool(records: CollapseRecord | Sequence[CollapseRecord], values, weights) -> np.ndarray:
    """Weighted mean of fine-face ``values`` (F,) or (F, D) over the fine faces each coarse face stands for.

    ``records`` is one record or the records of successive cycles (level 0
    first); ``weights`` (F,) are usually the level-0 face areas. Returns
    (F_coarse,) or (F_coarse, D).
    """
    from scipy.sparse import csr_matrix

    face_map = compose(records)
    n_coarse = _as_list(records)[-1].n_coarse_faces
    values = np.asarray(values, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    if values.shape[:1] != face_map.shape or values.ndim not in (1, 2):
        raise ValueError(f"values must have shape ({len(face_map)},) or ({len(face_map)}, D), got {values.shape}")
    if weights.shape != face_map.shape or not np.isfinite(weights).all() or (weights < 0).any():
        raise ValueError(f"weights must be {len(face_map)} finite non-negative numbers, got shape {weights.shape}")
    total = np.bincount(face_map, weights=weights, minlength=n_coarse)
    if (total <= 0).any():
        raise ValueError(f"{int((total <= 0).sum())} coarse faces stand only for fine faces of zero weight")
    spread = csr_matrix((weights / total[face_map], (face_map, np.arange(len(face_map)))), shape=(n_coarse, len(face_map)))
    return spread @ values


def one_hot(labels, n_classes: int) -> np.ndarray:
    """(F, n_classes) float one-hot rows of integer labels in [0, n_classes)."""
    labels = np.asarray(labels)
    if labels.ndim != 1 or not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"labels must be a 1-D integer array, got {labels.dtype} {labels.shape}")
    if len(labels) and (labels.min() < 0 or labels.max() >= n_classes):
        raise ValueError(f"labels must lie in [0, {n_classes}), found [{labels.min()}, {labels.max()}]")
    out = np.zeros((len(labels), n_classes))
    out[np.arange(len(labels)), labels] = 1.0
    return out


def pool_labels(records: CollapseRecord | Sequence[CollapseRecord], labels, areas, n_classes: int) -> np.ndarray:
    """(F_coarse,) the area-weighted majority label of the fine faces each coarse face stands for (ties: lowest class)."""
    return np.argmax(pool(records, one_hot(labels, n_classes), areas), axis=1)


def upsample_through(records: Sequence[CollapseRecord], coarse_probs) -> np.ndarray:
    """:func:`upsample` from the last level of ``records`` (level 0 first) back to level 0."""
    probs = coarse_probs
    for record in reversed(_as_list(records)):
        probs = upsample(record, probs)
    return probs


def round_trip_labels(records: Sequence[CollapseRecord], labels, areas, n_classes: int) -> np.ndarray:
    """(F,) ``labels`` pooled to the last level of ``records`` and carried back by the vote.

    The best any labelling of that coarse level can do once upsampled: the
    faces it gets wrong are those whose label did not survive the collapses.
    No records (the input level itself): the labels as they are.
    """
    if not len(records):
        return np.asarray(labels).copy()
    coarse = pool_labels(records, labels, areas, n_classes)
    return upsample_through(records, one_hot(coarse, n_classes)).argmax(axis=1)
