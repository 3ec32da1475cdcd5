"""Segmentation accuracy: the paper's Eq. 5 and the figures reported beside it.

Eq. 5 is the area-weighted fraction of correctly labelled faces. Pooled over
a category it can be read two ways, and the PSB files come in arbitrary
units, so this module reports both and says which is which:

* ``unit_area`` (the primary figure): each mesh scaled to unit total area,
  then pooled, i.e. the mean of the per-mesh area-weighted accuracies;
* ``raw_area``: the literal pooling of raw face areas over all test faces;
* ``faces``: the plain fraction of correctly labelled faces, pooled.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def _check(predicted, truth, face_areas=None):
    predicted = np.asarray(predicted)
    truth = np.asarray(truth)
    if predicted.shape != truth.shape or predicted.ndim != 1:
        raise ValueError(f"predicted {predicted.shape} and truth {truth.shape} must be equal-length 1-D arrays")
    if face_areas is not None:
        face_areas = np.asarray(face_areas, dtype=np.float64)
        if face_areas.shape != truth.shape:
            raise ValueError(f"face_areas {face_areas.shape} must match the labels {truth.shape}")
        if (face_areas < 0).any() or not np.isfinite(face_areas).all() or face_areas.sum() <= 0:
            raise ValueError("face_areas must be finite, non-negative and not all zero")
    return predicted, truth, face_areas


def accuracy(predicted, truth, face_areas) -> float:
    """Eq. 5 on one mesh: the area-weighted fraction of faces whose label is right."""
    predicted, truth, face_areas = _check(predicted, truth, face_areas)
    return float(face_areas[predicted == truth].sum() / face_areas.sum())


def pooled_accuracy(
    predicted: Sequence[np.ndarray], truth: Sequence[np.ndarray], face_areas: Sequence[np.ndarray]
) -> dict[str, float]:
    """Eq. 5 pooled over the meshes of a category, in the three readings above."""
    if not (len(predicted) == len(truth) == len(face_areas)) or not predicted:
        raise ValueError("need the same, non-zero number of predictions, truths and area arrays")
    checked = [_check(p, t, a) for p, t, a in zip(predicted, truth, face_areas)]
    right_area = sum(a[p == t].sum() for p, t, a in checked)
    total_area = sum(a.sum() for _, _, a in checked)
    right_faces = sum(int((p == t).sum()) for p, t, _ in checked)
    total_faces = sum(len(t) for _, t, _ in checked)
    return {
        "unit_area": float(np.mean([a[p == t].sum() / a.sum() for p, t, a in checked])),
        "raw_area": float(right_area / total_area),
        "faces": right_faces / total_faces,
    }


def confusion_matrix(predicted, truth, n_classes: int, face_areas=None) -> np.ndarray:
    """(n_classes, n_classes) matrix, rows true class, columns predicted; area-weighted when areas are given."""
    predicted, truth, face_areas = _check(predicted, truth, face_areas)
    if len(truth) and (min(predicted.min(), truth.min()) < 0 or max(predicted.max(), truth.max()) >= n_classes):
        raise ValueError(f"labels must lie in [0, {n_classes})")
    weights = np.ones(len(truth)) if face_areas is None else face_areas
    out = np.zeros((n_classes, n_classes))
    np.add.at(out, (truth, predicted), weights)
    return out
