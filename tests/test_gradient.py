"""The per-face gradient: exact for a linear field away from the boundary, and the features read it frame-free."""

from __future__ import annotations

import numpy as np
import torch
from conftest import grid_mesh

from anseg.geometry.gradient import face_gradient
from anseg.mesh import Mesh
from anseg.model import SpectralDiffusion, SpectralInput


def frames(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    first = mesh.vertices[mesh.faces[:, 1]] - mesh.vertices[mesh.faces[:, 0]]
    t1 = first / np.linalg.norm(first, axis=1, keepdims=True)
    return t1, np.cross(mesh.face_normals, t1)


def test_the_gradient_of_a_linear_field_is_its_slope_along_each_face():
    mesh = grid_mesh(6)
    mesh = Mesh(mesh.vertices + np.outer(mesh.vertices[:, 0], [0, 0, 0.3]), mesh.faces)  # a tilted plane
    slope = np.array([0.7, -1.3, 0.4])
    g = face_gradient(mesh) @ (mesh.face_centroids @ slope)
    t1, t2 = frames(mesh)
    interior = (mesh.face_neighbors >= 0).all(axis=1)
    assert np.allclose(g[0::2][interior], t1[interior] @ slope, atol=1e-6)
    assert np.allclose(g[1::2][interior], t2[interior] @ slope, atol=1e-6)
    assert np.isfinite(g).all()  # boundary faces too


def test_gradient_features_do_not_depend_on_the_faces_frames():
    torch.manual_seed(0)
    mesh = grid_mesh(5, closed=True)
    operator = face_gradient(mesh).toarray()
    angle = np.random.default_rng(1).uniform(0, 2 * np.pi, mesh.n_faces)  # turn every face's frame by its own angle
    turned = operator.copy()
    turned[0::2] = np.cos(angle)[:, None] * operator[0::2] - np.sin(angle)[:, None] * operator[1::2]
    turned[1::2] = np.sin(angle)[:, None] * operator[0::2] + np.cos(angle)[:, None] * operator[1::2]
    block = SpectralDiffusion(8, gradients=True)
    k = 6
    basis = torch.randn(mesh.n_faces, k)
    spectrum = dict(basis=basis, values=torch.linspace(0, 50, k), mass=torch.full((mesh.n_faces,), 1 / mesh.n_faces))
    e = torch.randn(mesh.n_faces, 8)
    here = block(e, SpectralInput(**spectrum, gradient=torch.as_tensor(operator, dtype=torch.float32).to_sparse()))
    there = block(e, SpectralInput(**spectrum, gradient=torch.as_tensor(turned, dtype=torch.float32).to_sparse()))
    assert torch.allclose(here, there, atol=1e-5)
    plain = SpectralDiffusion(8)
    assert plain.rotate is None and plain.mlp[0].in_features == 16
