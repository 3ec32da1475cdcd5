"""Shared fixtures. Real-data fixtures skip, with the reason, when the archives are absent."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from anseg.mesh import Mesh

NO_DATA = (
    "real benchmark data absent: set ANSEG_DATA to the folder holding psb_labeled.tar.gz, "
    "coseg.tar.gz and human_seg.tar.gz (or their extracted folders); .ci/run does so when ../shared/datasets exists"
)


@pytest.fixture(scope="session")
def data_root() -> Path:
    root = os.environ.get("ANSEG_DATA")
    if not root or not Path(root).is_dir():
        pytest.skip(NO_DATA)
    return Path(root)


@pytest.fixture(scope="session")
def psb_sample(data_root):
    """Two test meshes each of PSB Teddy and Airplane (split 0), as LabeledMesh objects."""
    from anseg import datasets

    return {c: datasets.load("psb", category=c, split="test", root=data_root)[:2] for c in ("Teddy", "Airplane")}


def screenshot_folder(default: Path) -> Path:
    """Where a browser test keeps its screenshots: ``$ANSEG_SCREENSHOTS`` when set, else ``default`` (made if need be)."""
    folder = Path(os.environ.get("ANSEG_SCREENSHOTS", default))
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def grid_mesh(n: int = 4, closed: bool = False) -> Mesh:
    """A small regular mesh: an n x n grid of squares split into triangles, or a closed octahedron-like sphere."""
    if closed:
        import trimesh

        sphere = trimesh.creation.icosphere(subdivisions=max(0, n - 3))
        return Mesh(sphere.vertices, sphere.faces)
    xs, ys = np.meshgrid(np.arange(n + 1, dtype=float), np.arange(n + 1, dtype=float), indexing="ij")
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return Mesh(vertices, faces)
