"""The low end of a mesh's Laplace-Beltrami spectrum: one eigensolve shared by the HKS features and the network.

:func:`laplacian_eigenpairs` solves for the smallest eigenpairs of the cotan
Laplacian with Voronoi vertex masses; the ``hks`` feature group
(:mod:`anseg.features`) is built from them. :func:`face_spectrum` gives the
same basis per face, on the unit-area centred mesh, cached on disk: what the
network's spatial context reads (:mod:`anseg.model`: spectral positions of
tokens, learned diffusion), carried to coarse levels through the collapse
records by the pipeline.

On the unit-area mesh the eigenvalues are scale free, and the per-face basis
(each face the mean of its corners) is orthonormal up to discretisation
under the face areas: sum_f a_f phi_j(f) phi_k(f) ~ delta_jk.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from anseg.cache import (
    atomic_write,
    cache_dir,
    library_versions,
    read_checked_array,
    write_checked_array,
)
from anseg.geometry import proxy
from anseg.mesh import STRAY_PIECE_SHARE, Mesh

SPECTRUM_PAIRS = 64  # eigenpairs of the HKS and of the network's spectrum
EIGEN_TOLERANCE = 1e-6  # relative accuracy of the eigenvalues (see laplacian_eigenpairs)
SPECTRUM_VERSION = 1
MOLLIFY_FACTOR = 1e-5  # robust_laplacian's edge lengthening on meshes with slivers, relative to the mean edge (its default)


def factor_spd(matrix):
    """SuperLU factors of a sparse symmetric positive definite matrix (CSC).

    A symmetric ordering and no pivoting keep the factor small: on a 28K-face
    Laplacian 40 % less fill than SuperLU's default column ordering and a
    solve three to four times faster.
    """
    from scipy.sparse.linalg import splu

    return splu(matrix, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})


def cotan_laplacian(mesh: Mesh):
    """The cotan Laplacian (V, V), negative semi-definite as libigl's ``cotmatrix``, which it is on a mesh without slivers.

    On a mesh with slivers (:func:`anseg.mesh.degenerate_faces`: faces with an
    area, however small, thinner than 1e-10 of their longest edge), the
    intrinsic mollified Laplacian of Sharp and Crane (2020, the
    ``robust_laplacian`` package) instead: a cap's angle near 180 degrees has a
    cotangent beyond -1e12, which cancels the other weights at its vertices and
    leaves the factorisations singular; on the intrinsic Delaunay triangulation
    of the same vertices, every edge first lengthened by a tiny epsilon, no
    such angle remains. Every benchmark mesh is without slivers (the data set
    readers drop them), so their operators are libigl's, bit for bit.
    """
    import igl

    from anseg.mesh import degenerate_faces

    if not degenerate_faces(mesh).any():
        return igl.cotmatrix(mesh.vertices, mesh.faces)
    import robust_laplacian

    stiffness, _ = robust_laplacian.mesh_laplacian(mesh.vertices, mesh.faces, mollify_factor=MOLLIFY_FACTOR)
    return -stiffness.tocsc()


def laplacian_eigenpairs(mesh: Mesh, n_pairs: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``n_pairs`` smallest eigenvalues (k,) and mass-orthonormal vertex eigenvectors (V, k) of the cotan Laplacian.

    Fewer (k = V - 2) on a mesh too small for ``n_pairs``. The mesh must have
    no unreferenced vertices (they make the Laplacian singular). The last
    mesh's pairs are kept in memory: segmenting a new mesh asks twice, for
    the HKS features and for the network's spectrum, and the solve is most
    of the cost of either.
    """
    key = (hashlib.sha1(mesh.vertices.tobytes() + mesh.faces.tobytes()).hexdigest(), mesh.vertices.shape, n_pairs)
    if _LAST_SOLVE.get("key") != key:
        _LAST_SOLVE.clear()
        _LAST_SOLVE.update(key=key, pairs=_solve(mesh, n_pairs))
    values, vectors = _LAST_SOLVE["pairs"]
    return values.copy(), vectors.copy()


_LAST_SOLVE: dict = {}


def _solve(mesh: Mesh, n_pairs: int) -> tuple[np.ndarray, np.ndarray]:
    import igl
    from scipy.sparse.linalg import LinearOperator, eigsh

    v, f = mesh.vertices, mesh.faces
    stiffness = -cotan_laplacian(mesh).tocsc()  # positive semi-definite
    mass = igl.massmatrix(v, f, igl.MASSMATRIX_TYPE_VORONOI).tocsc()
    k = min(n_pairs, mesh.n_vertices - 2)
    # shift-invert just below 0: the smallest eigenvalues, with a positive definite factorisation (our SPD
    # factor instead of eigsh's own, SuperLU's default ordering: the same values, to 1e-13, a quarter faster).
    # Ritz values to 1e-6 instead of machine precision: 163 solves instead of 196 on PSB meshes of 14K-49K
    # faces, and the HKS moves by at most 1.4e-7 (relative), below the network's float32 resolution.
    # A fixed start vector: ARPACK's own changes from call to call, which a loose tolerance would let show.
    shift = -1e-3
    inverse = factor_spd((stiffness - shift * mass).tocsc())
    start = np.random.default_rng(0).standard_normal(stiffness.shape[0])
    values, vectors = eigsh(stiffness, k=k, M=mass, sigma=shift, which="LM", tol=EIGEN_TOLERANCE, v0=start,
                            OPinv=LinearOperator(stiffness.shape, matvec=inverse.solve, dtype=float))
    order = np.argsort(values)
    return np.maximum(values[order], 0.0), vectors[:, order]


@dataclass(frozen=True)
class Spectrum:
    """Eigenvalues (k,) and the per-face eigenbasis (F, k) of one mesh (or its pooling onto a coarse level)."""

    values: np.ndarray
    basis: np.ndarray


def face_spectrum(mesh: Mesh, n_pairs: int = SPECTRUM_PAIRS, cache: bool = True) -> Spectrum:
    """The first ``n_pairs`` eigenpairs of the unit-area mesh, the basis per face (float32), cached on disk.

    A mesh with too few vertices for ``n_pairs`` gets zero columns past its
    last eigenvector (they carry nothing through a product with the basis).
    Above :data:`anseg.geometry.proxy.LARGE_MESH_FACES` faces the basis is solved
    on the same uniform collapse the large-mesh HKS uses and each face takes
    its face's values there: the low eigenvectors are smooth. A mesh's stray
    pieces (:attr:`anseg.mesh.Mesh.stray_faces`) are left out of the solve and
    get zero rows: each would bring a zero eigenvalue of its own and push one of
    the shape's modes out of the basis.
    """
    path = _cache_path(mesh, n_pairs) if cache else None
    if path is not None and (stored := read_checked_array(path, (mesh.n_faces + 1, n_pairs))) is not None:
        return Spectrum(stored[0].astype(np.float64), stored[1:])
    surface, face_of = mesh.unit_area(), None
    if surface.n_faces > proxy.LARGE_MESH_FACES:
        coarse, face_of = proxy.collapse_to_proxy(surface)
        surface = coarse.unit_area()
    if surface.stray_faces is None:
        values, vectors = laplacian_eigenpairs(surface, n_pairs)
        per_face = vectors[surface.faces].mean(axis=1)
    else:
        shape, _ = surface.submesh(~surface.stray_faces)
        values, vectors = laplacian_eigenpairs(shape, n_pairs)
        per_face = np.zeros((surface.n_faces, len(values)))
        per_face[~surface.stray_faces] = vectors[shape.faces].mean(axis=1)
    if face_of is not None:
        per_face = per_face[face_of]
    stored = np.zeros((mesh.n_faces + 1, n_pairs), dtype=np.float32)
    stored[0, : len(values)], stored[0, len(values) :] = values, values[-1]
    stored[1:, : len(values)] = per_face
    if path is not None:
        atomic_write(path, lambda tmp: write_checked_array(tmp, stored))
    return Spectrum(stored[0].astype(np.float64), stored[1:])


def _cache_path(mesh: Mesh, n_pairs: int):
    # the stray-piece rule keys the cache too: a mesh with stray pieces was solved whole before it existed
    digest = hashlib.sha256(f"anseg-spectrum v{SPECTRUM_VERSION} strays<{STRAY_PIECE_SHARE}|"
                            f"{sorted(library_versions().items())}|{n_pairs}|"
                            f"{mesh.vertices.shape}{mesh.faces.shape}|".encode())
    digest.update(mesh.vertices.tobytes())
    digest.update(mesh.faces.tobytes())
    return cache_dir("spectra") / f"{digest.hexdigest()}.npy"
