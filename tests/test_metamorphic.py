"""Metamorphic guard: a rigid motion of a mesh must not move its labels (benchmarks/metamorphic.py's transforms).

A segmentation is a function of the surface, so rotating and shifting the
mesh should leave every label in place. Today it does not quite: the patch
layout of the tokens comes from coordinates (k-means, a space-filling curve
in xyz), so a rotated mesh is cut into other patches. This test is a
regression guard at today's level, not the goal (later work will tighten
the tolerance to 99 %).

Measured (this code, the tiny model below, vessel_002 and vessel_003 under
the rigid motions of seeds 0-3): agreement with the unmoved labels 99.64,
100, 100, 87.42 % and 100, 100, 92.80, 92.80 % of the surface area; worst
87.42 %. Tolerance: every case at least ``TOLERANCE`` = 85 %.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from anseg import datasets
from anseg.pipeline import SegmentConfig, segment
from anseg.train import TrainConfig, fit

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from metamorphic import TRANSFORMS, agreement, rigid_motion, to_original, transformed  # noqa: E402

TOLERANCE = 0.85  # worst agreement measured today: 87.42 % (module docstring)
SEEDS = range(4)
FAST = SegmentConfig(cycles=2, clusters=4, patch_size=16)


@pytest.fixture(scope="module")
def shapes():
    return datasets.load("synthetic", category="vessel", split="all", n_shapes=4, progress=False)


@pytest.fixture(scope="module")
def model(shapes):
    torch.set_num_threads(1)  # two threads on a loaded 2-core machine run slower than one
    return fit(shapes[:2], shapes[0].label_names, FAST, TrainConfig(epochs=2, width=32), progress=False)


def labels(mesh, model):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # small meshes: a cycle may collapse less than asked
        return segment(mesh, model).labels


def test_rigid_motion_keeps_the_labels_within_tolerance(model, shapes):
    worst = 1.0
    for item in shapes[2:]:
        base, areas = labels(item.mesh, model), item.mesh.face_areas
        for seed in SEEDS:
            worst = min(worst, agreement(labels(rigid_motion(item.mesh, seed), model), base, areas))
    assert worst >= TOLERANCE, f"a rigid motion changed the labels of {100 * (1 - worst):.2f} % of the surface"


def test_rigid_motion_is_rigid(shapes):
    mesh = shapes[2].mesh
    moved = rigid_motion(mesh, seed=3)
    assert np.allclose(moved.face_areas, mesh.face_areas) and np.array_equal(moved.faces, mesh.faces)
    assert np.allclose(moved.dihedral_angles, mesh.dihedral_angles, atol=1e-6)
    assert np.linalg.norm(moved.face_centroids.mean(0) - mesh.face_centroids.mean(0)) > 5 * np.ptp(mesh.vertices, 0).max()


@pytest.mark.parametrize("name", list(TRANSFORMS))
def test_transforms_keep_the_surface_and_map_faces_back(name, shapes):
    """Every transform keeps the surface's shape (areas up to the scale, the outward side but for ``flip``)."""
    mesh = shapes[2].mesh
    moved, origin = transformed(mesh, name)
    moved.validate()
    scale = 1e6 if name == "scale_shift" else 1.0
    assert np.allclose(to_original(moved.face_areas, origin), scale * mesh.face_areas)
    # the signed volume says which way the faces point: as before unless flipped
    assert np.sign(signed_volume(moved)) == (-1 if name == "flip" else 1) * np.sign(signed_volume(mesh))


def signed_volume(mesh) -> float:
    """Six times the enclosed volume, positive when a closed mesh's faces point outward."""
    a, b, c = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c)))
