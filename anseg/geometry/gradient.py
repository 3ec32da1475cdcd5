"""The gradient of a per-face field, in each face's own tangent frame: what DiffusionNet's gradient features read.

DiffusionNet (Sharp et al. 2022) gives its diffusion blocks the inner
products of each point's feature gradients with a learned rotation of
them: a sense of direction along the surface that diffusion alone, being
isotropic, lacks. Our network works on faces, so the gradient of a per-face
field is fitted at each face from the faces across its edges: the
least-squares plane through the differences to those neighbours, along the
centroid offsets projected into the face's frame (the first edge and the
normal's cross product with it). The frame's choice does not matter to the
features, which are invariant to a rotation of every frame.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from anseg.mesh import Mesh

RIDGE = 1e-6  # relative to the squared neighbour distance: keeps a boundary face with one neighbour solvable


def face_gradient(mesh: Mesh) -> sp.csr_matrix:
    """(2F, F) sparse: rows 2f and 2f + 1 give the field's gradient at face f along its frame's two axes."""
    centroids, normals = mesh.face_centroids, mesh.face_normals
    first = mesh.vertices[mesh.faces[:, 1]] - mesh.vertices[mesh.faces[:, 0]]
    t1 = first / np.linalg.norm(first, axis=1, keepdims=True)
    t2 = np.cross(normals, t1)
    neighbors = mesh.face_neighbors  # (F, 3), -1 on the boundary
    present = neighbors >= 0
    offset = centroids[np.where(present, neighbors, 0)] - centroids[:, None, :]  # (F, 3, 3)
    d = np.stack([(offset * t1[:, None]).sum(axis=2), (offset * t2[:, None]).sum(axis=2)], axis=2) * present[..., None]
    scale = (d**2).sum(axis=(1, 2)) / np.maximum(present.sum(axis=1), 1)
    normal_matrix = np.einsum("fki,fkj->fij", d, d) + RIDGE * np.maximum(scale, 1e-30)[:, None, None] * np.eye(2)
    weights = np.linalg.solve(normal_matrix, np.transpose(d, (0, 2, 1)))  # (F, 2, 3): gradient = weights @ (u_n - u_f)
    rows = np.repeat(np.arange(2 * mesh.n_faces), 3).reshape(mesh.n_faces, 2, 3)
    cols = np.broadcast_to(np.where(present, neighbors, 0)[:, None, :], rows.shape)
    keep = np.broadcast_to(present[:, None, :], rows.shape)
    to_neighbors = sp.csr_matrix((weights[keep], (rows[keep], cols[keep])), shape=(2 * mesh.n_faces, mesh.n_faces))
    own = sp.csr_matrix((-weights.sum(axis=2).ravel(), (np.arange(2 * mesh.n_faces), np.repeat(np.arange(mesh.n_faces), 2))),
                        shape=(2 * mesh.n_faces, mesh.n_faces))
    return (to_neighbors + own).tocsr()
