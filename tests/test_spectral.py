"""The shared eigenbasis: the per-face spectrum the network reads, its cache, and its small-mesh padding."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from anseg.geometry import spectral
from anseg.mesh import Mesh


@pytest.fixture(autouse=True)
def own_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("ANSEG_CACHE", str(tmp_path))


def blob(subdivisions: int = 3) -> Mesh:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    bumps = 1.0 + 0.04 * np.random.default_rng(0).standard_normal(len(sphere.vertices))
    return Mesh(sphere.vertices * bumps[:, None] * [1.6, 1.0, 0.7], sphere.faces)


def test_face_basis_is_orthonormal_under_the_face_areas_of_the_unit_area_mesh():
    mesh = blob()
    spectrum = spectral.face_spectrum(mesh, 16, cache=False)
    area = mesh.face_areas / mesh.face_areas.sum()
    gram = spectrum.basis.T.astype(np.float64) @ (area[:, None] * spectrum.basis)
    # corners averaged to faces: orthogonal still, norms shrunk a little where a vector varies fastest
    np.testing.assert_allclose(gram - np.diag(np.diag(gram)), 0.0, atol=0.01)
    assert 0.9 < np.diag(gram).min() and np.diag(gram).max() < 1.0 + 1e-3
    assert spectrum.values[0] == pytest.approx(0.0, abs=1e-6)
    assert (np.diff(spectrum.values) >= 0).all()
    assert np.ptp(spectrum.basis[:, 0]) < 1e-3  # the constant eigenvector


def test_spectrum_is_scale_free_and_cached(monkeypatch):
    mesh = blob()
    first = spectral.face_spectrum(mesh, 8)
    scaled = spectral.face_spectrum(Mesh(mesh.vertices * 7.0, mesh.faces), 8, cache=False)
    np.testing.assert_allclose(scaled.values, first.values, rtol=1e-4, atol=1e-6)
    monkeypatch.setattr(spectral, "laplacian_eigenpairs", lambda *a: pytest.fail("solved again instead of reading the cache"))
    again = spectral.face_spectrum(mesh, 8)
    np.testing.assert_array_equal(again.basis, first.basis)
    np.testing.assert_array_equal(again.values, first.values)


def test_a_mesh_too_small_for_the_pairs_gets_zero_columns():
    tetra = trimesh.creation.icosphere(subdivisions=0)  # 12 vertices: 10 eigenpairs at most
    spectrum = spectral.face_spectrum(Mesh(tetra.vertices, tetra.faces), 16, cache=False)
    assert spectrum.basis.shape == (20, 16)
    assert np.abs(spectrum.basis[:, 10:]).max() == 0
    assert np.isfinite(spectrum.values).all()


def test_the_hks_and_the_spectrum_of_one_mesh_share_one_solve(monkeypatch):
    from anseg import features

    calls = []
    solve = spectral._solve
    monkeypatch.setattr(spectral, "_solve", lambda *a: calls.append(1) or solve(*a))
    spectral._LAST_SOLVE.clear()
    mesh = blob(2)
    features.compute_groups(mesh, ["hks"], sdf_rays=4, agd_sources=4)
    spectral.face_spectrum(mesh, features.HKS_EIGENPAIRS, cache=False)
    assert len(calls) == 1
    spectral.face_spectrum(blob(3), 8, cache=False)
    assert len(calls) == 2


def test_a_large_mesh_takes_its_basis_from_the_proxy_collapse(monkeypatch):
    from anseg.geometry import proxy

    sphere = trimesh.creation.icosphere(subdivisions=4)
    mesh = Mesh(sphere.vertices * [2.0, 1.0, 0.7], sphere.faces)  # distinct axes: the low eigenvalues are simple
    direct = spectral.face_spectrum(mesh, 6, cache=False)
    monkeypatch.setattr(proxy, "LARGE_MESH_FACES", 4000)
    monkeypatch.setattr(proxy, "PROXY_FACES", 1200)
    through = spectral.face_spectrum(mesh, 6, cache=False)
    np.testing.assert_allclose(through.values[1:4], direct.values[1:4], rtol=0.05)
    for k in (1, 2, 3):  # the same vectors up to sign, sampled from the coarse faces
        assert abs(np.corrcoef(through.basis[:, k], direct.basis[:, k])[0, 1]) > 0.98
