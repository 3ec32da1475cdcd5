"""Eq. 5 and the pooled readings."""

import numpy as np
import pytest

from anseg.metrics import accuracy, confusion_matrix, pooled_accuracy


def test_accuracy_weights_by_area():
    truth = np.array([0, 0, 1, 1])
    pred = np.array([0, 1, 1, 1])
    areas = np.array([1.0, 3.0, 1.0, 1.0])
    assert accuracy(pred, truth, areas) == pytest.approx(3 / 6)


def test_pooled_readings_differ_as_documented():
    # a large mesh all right, a small mesh all wrong
    pred = [np.array([0, 0]), np.array([1, 1, 1])]
    truth = [np.array([0, 0]), np.array([0, 0, 0])]
    areas = [np.array([50.0, 50.0]), np.array([0.1, 0.1, 0.1])]
    out = pooled_accuracy(pred, truth, areas)
    assert out["unit_area"] == pytest.approx(0.5)
    assert out["raw_area"] == pytest.approx(100 / 100.3)
    assert out["faces"] == pytest.approx(2 / 5)


def test_confusion_matrix():
    cm = confusion_matrix(np.array([0, 1, 1, 2]), np.array([0, 1, 2, 2]), 3)
    assert cm.tolist() == [[1, 0, 0], [0, 1, 0], [0, 1, 1]]
    weighted = confusion_matrix(np.array([0, 1]), np.array([0, 0]), 2, face_areas=np.array([2.0, 3.0]))
    assert weighted.tolist() == [[2, 3], [0, 0]]


@pytest.mark.parametrize(
    "call",
    [
        lambda: accuracy(np.array([0, 1]), np.array([0]), np.array([1.0])),
        lambda: accuracy(np.array([0]), np.array([0]), np.array([0.0])),
        lambda: accuracy(np.array([0]), np.array([0]), np.array([np.nan])),
        lambda: pooled_accuracy([], [], []),
        lambda: confusion_matrix(np.array([0, 3]), np.array([0, 1]), 2),
    ],
)
def test_bad_input_raises(call):
    with pytest.raises(ValueError):
        call()
