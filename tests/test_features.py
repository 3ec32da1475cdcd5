"""Per-face features: invariances, known shapes, the cache, parallel computation and bad input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from conftest import grid_mesh, with_caps
from scipy.spatial.transform import Rotation
from scipy.stats import spearmanr

from anseg import cache, collapse, features
from anseg.geometry import diffusion, geodesic, proxy
from anseg.mesh import Mesh, MeshError

FAST = {"sdf_rays": 8, "agd_sources": 16}  # cheaper than the defaults, same code paths


def blob() -> Mesh:
    """A closed, stretched and bumpy sphere: no symmetry, so no ties that rounding could break."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    bumps = 1.0 + 0.04 * np.random.default_rng(0).standard_normal(len(sphere.vertices))
    return Mesh(sphere.vertices * bumps[:, None] * [1.6, 1.0, 0.7], sphere.faces)


def open_cap() -> Mesh:
    """A curved surface with one boundary loop: an icosphere with its bottom cut away."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    keep = sphere.vertices[sphere.faces].mean(axis=1)[:, 2] > -0.3
    used, faces = np.unique(sphere.faces[keep], return_inverse=True)
    return Mesh(sphere.vertices[used], faces.reshape(-1, 3))


def cylinder(radius: float, offset: float) -> trimesh.Trimesh:
    shape = trimesh.creation.cylinder(radius=radius, height=2.0, sections=24)
    shape = shape.subdivide_to_size(0.25)
    shape.apply_translation([offset, 0.0, 0.0])
    return shape


def assert_same_features(a: np.ndarray, b: np.ndarray, tol: float) -> None:
    """Equal up to ``tol`` relative to each value and to its column's spread."""
    scale = np.abs(b) + b.std(axis=0) + 1e-12
    worst = np.max(np.abs(a - b) / scale)
    assert worst <= tol, f"features differ by {worst:.2e} (relative), more than {tol:.0e}"


# ------------------------------------------------------------- invariances
@pytest.mark.parametrize("group", ["edge", "angles", "ratios"])
def test_local_groups_ignore_the_order_of_a_faces_vertices(group):
    mesh = blob()
    rolled = Mesh(mesh.vertices, np.roll(mesh.faces, 1, axis=1))
    a = features.compute_groups(mesh, [group])[group]
    b = features.compute_groups(rolled, [group])[group]
    assert_same_features(b, a, tol=1e-5)


@pytest.mark.parametrize("group", features.GROUPS)
def test_every_group_is_scale_invariant(group):
    mesh = blob()
    scaled = Mesh(mesh.vertices * 7.3 + [1.0, -2.0, 0.5], mesh.faces)
    a = features.compute(mesh, [group], cache=False, **FAST)
    b = features.compute(scaled, [group], cache=False, **FAST)
    assert_same_features(b, a, tol=1e-4)


@pytest.mark.parametrize("group", features.GROUPS)
def test_every_group_is_rotation_invariant(group):
    mesh = blob()
    rotated = Mesh(mesh.vertices @ Rotation.from_euler("xyz", [0.3, -1.1, 2.0]).as_matrix().T, mesh.faces)
    a = features.compute(mesh, [group], cache=False, **FAST)
    b = features.compute(rotated, [group], cache=False, **FAST)
    assert_same_features(b, a, tol=1e-3)


def test_features_are_deterministic():
    mesh = blob()
    a = features.compute(mesh, features.GROUPS, cache=False, **FAST)
    b = features.compute(Mesh(mesh.vertices.copy(), mesh.faces.copy()), features.GROUPS, cache=False, **FAST)
    np.testing.assert_array_equal(a, b)


def test_agd_beside_the_ray_cast_gives_the_values_of_one_thread(monkeypatch):
    mesh = blob()
    monkeypatch.setattr(features, "_threads_allowed", lambda: 2)
    overlapped = features.compute(mesh, features.DEFAULT_GROUPS, cache=False, **FAST)
    monkeypatch.setattr(features, "_threads_allowed", lambda: 1)
    one_thread = features.compute(mesh, features.DEFAULT_GROUPS, cache=False, **FAST)
    np.testing.assert_array_equal(overlapped, one_thread)


def test_an_agd_failure_beside_the_ray_cast_is_raised(monkeypatch):
    def fail(*args):
        raise RuntimeError("heat method failed")

    monkeypatch.setattr(features, "_threads_allowed", lambda: 2)
    monkeypatch.setattr(geodesic, "average_geodesic_distance", fail)
    with pytest.raises(RuntimeError, match="heat method failed"):
        features.compute(blob(), ("sdf", "agd"), cache=False, **FAST)


# --------------------------------------------------------- shapes and values
@pytest.mark.parametrize(
    "mesh", [grid_mesh(6), grid_mesh(4, closed=True), open_cap(), blob()], ids=["grid", "sphere", "open-cap", "blob"]
)
def test_all_groups_finite_with_named_columns(mesh):
    x = features.compute(mesh, features.GROUPS, cache=False, **FAST)
    assert x.shape == (mesh.n_faces, len(features.feature_names(features.GROUPS)))
    assert x.dtype == np.float32
    assert np.isfinite(x).all()


def test_feature_names_follow_groups_and_settings():
    names = features.feature_names(("edge", "smooth"), smooth_radii=(0.1, 0.2))
    assert names[:3] == ["edge_sum", "edge_pair_sum", "edge_product"]
    assert len(names) == 3 + 3 * 2 and "smooth_sdf_r0.2" in names
    blocks = features.compute_groups(blob(), ("edge", "smooth"), smooth_radii=(0.1, 0.2), **FAST)
    assert [b.shape[1] for b in blocks.values()] == [3, 6]


def test_edge_encoding_matches_the_paper_on_the_unit_area_mesh():
    mesh = grid_mesh(2)  # right isosceles triangles; total area 4 -> legs 1/2 after normalisation
    edge = features.compute_groups(mesh, ["edge"])["edge"]
    a, c = 0.5, 0.5 * np.sqrt(2.0)
    np.testing.assert_allclose(edge, np.tile([2 * a + c, a * a + 2 * a * c, a * a * c], (mesh.n_faces, 1)), rtol=1e-6)
    angles = features.compute_groups(mesh, ["angles"])["angles"]
    np.testing.assert_allclose(angles, np.tile([np.pi / 4, np.pi / 4, np.pi / 2], (mesh.n_faces, 1)), rtol=1e-6)


def test_gaussian_curvature_of_a_sphere_is_constant_and_positive():
    sphere = trimesh.creation.icosphere(subdivisions=4)
    gc = features.compute_groups(Mesh(sphere.vertices, sphere.faces), ["gc"])["gc"]
    # unit area: radius 1/sqrt(4 pi), so K = 4 pi everywhere
    np.testing.assert_allclose(gc[:, 0], np.log1p(4 * np.pi), rtol=0.03)
    assert (gc[:, 1] > 0).all()


def test_gaussian_curvature_of_a_flat_grid_is_zero():
    gc = features.compute_groups(grid_mesh(6), ["gc"])["gc"]
    np.testing.assert_array_equal(gc, 0.0)


def test_gaussian_curvature_signs_on_a_saddle_and_a_bump():
    n = 12
    xs, ys = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1), indexing="ij")
    grid = grid_mesh(n)
    saddle = Mesh(np.stack([xs.ravel(), ys.ravel(), 0.3 * (xs**2 - ys**2).ravel()], axis=1), grid.faces)
    bump = Mesh(np.stack([xs.ravel(), ys.ravel(), -0.3 * (xs**2 + ys**2).ravel()], axis=1), grid.faces)
    centre = np.argmin(np.linalg.norm(saddle.face_centroids[:, :2], axis=1))
    assert features.compute_groups(saddle, ["gc"])["gc"][centre, 0] < 0
    assert features.compute_groups(bump, ["gc"])["gc"][centre, 0] > 0


def test_sdf_of_a_thin_cylinder_is_smaller_than_of_a_fat_one():
    shape = trimesh.util.concatenate([cylinder(0.1, -2.0), cylinder(0.5, 2.0)])
    mesh = Mesh(shape.vertices, shape.faces)
    sdf = features.compute_groups(mesh, ["sdf"])["sdf"]
    thin = mesh.face_centroids[:, 0] < 0
    assert np.median(sdf[thin, 0]) < 0.4 * np.median(sdf[~thin, 0])
    assert np.median(sdf[thin, 1]) < np.median(sdf[~thin, 1])


def test_sdf_of_a_sphere_is_close_to_its_diameter_scaled_by_the_cone():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    sdf = features.compute_groups(Mesh(sphere.vertices, sphere.faces), ["sdf"])["sdf"][:, 0]
    # a chord at angle a to the inward normal of a sphere of diameter D is D cos a; unit area: D = 1/sqrt(pi)
    diameter = 1.0 / np.sqrt(np.pi)
    assert 0.7 * diameter < sdf.min() and sdf.max() < diameter


def test_agd_is_highest_at_the_ends_of_an_elongated_shape():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    mesh = Mesh(sphere.vertices * [3.0, 1.0, 1.0], sphere.faces)
    agd = features.compute_groups(mesh, ["agd"], agd_sources=32)["agd"]
    x = np.abs(mesh.face_centroids[:, 0])
    assert spearmanr(agd[:, 0], x).statistic > 0.95
    assert x[np.argmax(agd[:, 0])] > 0.9 * x.max()
    assert agd[:, 1].min() == 0.0 and agd[:, 1].max() == 1.0


def test_hks_is_flat_on_a_sphere_and_peaks_at_the_tips_of_an_elongated_shape():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    flat = features.compute_groups(Mesh(sphere.vertices, sphere.faces), ["hks"])["hks"]
    assert flat.std(axis=0).max() < 0.05 and np.abs(flat).max() < 0.1  # every point alike: hks equals the mean
    mesh = Mesh(sphere.vertices * [3.0, 1.0, 1.0], sphere.faces)
    hks = features.compute_groups(mesh, ["hks"])["hks"]
    x = np.abs(mesh.face_centroids[:, 0])
    middle = features.HKS_TIMES.index(0.032)
    assert spearmanr(hks[:, middle], x).statistic > 0.9  # heat stays longer at the tips
    assert hks.shape[1] == len(features.HKS_TIMES)


def test_agd_stays_within_each_connected_component():
    sphere = trimesh.creation.icosphere(subdivisions=2)
    far = sphere.copy()
    far.apply_translation([10.0, 0.0, 0.0])
    both = trimesh.util.concatenate([sphere, far])
    agd = features.compute_groups(Mesh(both.vertices, both.faces), ["agd"], agd_sources=16)["agd"][:, 0]
    half = len(sphere.faces)
    # two equal spheres: equal AGD, and on the unit-area pair each is 1/sqrt(2) of a unit sphere's pi/2 * radius
    np.testing.assert_allclose(agd[:half].mean(), agd[half:].mean(), rtol=0.02)
    radius = 1.0 / np.sqrt(8 * np.pi)
    np.testing.assert_allclose(agd.mean(), np.pi / 2 * radius, rtol=0.05)


def with_a_far_facet(mesh: Mesh, size: float = 0.05) -> Mesh:
    """``mesh`` and one triangle of its own far from it: a stray piece (less than 1 % of the mesh's area)."""
    corner = mesh.vertices.max(axis=0) + 5.0
    facet = corner + size * np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return Mesh(np.vstack([mesh.vertices, facet]), np.vstack([mesh.faces, mesh.n_vertices + np.arange(3)[None]]))


@pytest.mark.parametrize("group", features.GROUPS)
def test_a_stray_facet_leaves_the_features_of_the_shape(group):
    """No group lets a stray piece set a scale, frame, range or basis of the shape (before: agd_rel, sdf_lognorm's
    percentiles, gc_rank, the unit-area scale and centre, the HKS's heat trace)."""
    shape = blob()
    alone = features.compute_groups(shape, [group], **FAST)[group]
    beside = features.compute_groups(with_a_far_facet(shape), [group], **FAST)[group]
    assert_same_features(beside[:-1], alone, 1e-6)
    if group == "agd":  # the facet's own AGD is small: its agd_rel is clipped to the shape's 0, not below it
        assert beside[-1, 1] == 0.0


def test_stray_pieces_are_small_beside_the_largest_and_set_no_frame():
    shape = blob()
    assert shape.stray_faces is None and shape.frame_areas is shape.face_areas
    two = trimesh.util.concatenate([trimesh.creation.icosphere(2), trimesh.creation.icosphere(2).apply_translation([5, 0, 0])])
    assert Mesh(two.vertices, two.faces).stray_faces is None  # a shape of two equal parts has no stray piece
    stray = with_a_far_facet(shape)
    assert stray.stray_faces.sum() == 1 and stray.stray_faces[-1] and stray.frame_areas[-1] == 0
    np.testing.assert_allclose(stray.unit_area().vertices[: shape.n_vertices], shape.unit_area().vertices, atol=1e-12)


@pytest.mark.parametrize("group", ["sdf", "agd", "smooth", "hks"])
def test_caps_leave_the_global_groups_finite_and_as_they_were(group):
    """CAD-style caps (angles near 180 degrees): the cotan Laplacian's factorisation was singular, and smooth and hks
    failed; the intrinsic mollified Laplacian (spectral.cotan_laplacian) computes them, close to the shape's own."""
    shape = blob()
    capped = with_caps(shape, 10)
    alone = features.compute_groups(shape, [group], **FAST)[group]
    beside = features.compute_groups(capped, [group], **FAST)[group]
    assert np.isfinite(beside).all()
    untouched = np.setdiff1d(np.arange(shape.n_faces), np.linspace(0, shape.n_faces - 1, 10).astype(int))
    for column in range(alone.shape[1]):
        assert np.corrcoef(alone[untouched, column], beside[untouched, column])[0, 1] > 0.98


def test_smoothing_keeps_the_integral_and_lowers_the_spread():
    mesh = blob()
    blocks = features.compute_groups(mesh, ["gc", "smooth"], smooth_radii=(0.05, 0.3), **FAST)
    area = mesh.unit_area().face_areas
    raw, small, large = blocks["gc"][:, 0], blocks["smooth"][:, 2], blocks["smooth"][:, 3]  # gc_slog at r=0.05, 0.3
    for smoothed in (small, large):
        np.testing.assert_allclose((smoothed * area).sum(), (raw * area).sum(), rtol=1e-4)
    assert large.std() < small.std() < raw.std()


# ------------------------------------------------------------------- cache
@pytest.fixture
def cache_root(tmp_path, monkeypatch):
    monkeypatch.setenv("ANSEG_CACHE", str(tmp_path))
    return tmp_path / "features"


def test_diffusion_by_multigrid_cg_matches_a_direct_solve(monkeypatch):
    import igl
    from scipy.sparse.linalg import spsolve

    sphere = trimesh.creation.icosphere(subdivisions=3)
    mesh = Mesh(sphere.vertices * [2.0, 1.0, 1.0], sphere.faces).unit_area()
    signals = np.random.default_rng(0).random((mesh.n_faces, 2))
    monkeypatch.setattr(diffusion, "DIRECT_SOLVE_MAX_VERTICES", 0)  # the iterative path, as on a large mesh
    got = diffusion.diffuse_on_faces(mesh, signals, [0.05, 0.3])
    mass = igl.massmatrix(mesh.vertices, mesh.faces, igl.MASSMATRIX_TYPE_BARYCENTRIC)
    laplacian = igl.cotmatrix(mesh.vertices, mesh.faces)
    corner = np.repeat(mesh.face_areas / 3.0, 3)[:, None]
    rhs = np.zeros((mesh.n_vertices, 2))
    np.add.at(rhs, mesh.faces.ravel(), np.repeat(signals, 3, axis=0) * corner)
    for radius, block in zip([0.05, 0.3], got):
        direct = spsolve((mass - radius**2 / 4 * laplacian).tocsc(), rhs)[mesh.faces].mean(axis=1)
        np.testing.assert_allclose(block, direct, rtol=1e-7, atol=1e-9)


def ellipsoid() -> Mesh:
    """A 5120-face ellipsoid: above the 4000-face threshold of :func:`take_the_large_mesh_paths`."""
    sphere = trimesh.creation.icosphere(subdivisions=4)
    return Mesh(sphere.vertices * [2.0, 1.0, 0.7], sphere.faces)


def take_the_large_mesh_paths(monkeypatch) -> None:
    """Meshes above 4000 faces take the large-mesh paths, with a 1200-face proxy."""
    monkeypatch.setattr(proxy, "LARGE_MESH_FACES", 4000)
    monkeypatch.setattr(proxy, "PROXY_FACES", 1200)


def test_agd_of_a_large_mesh_comes_from_its_collapse_and_keys_its_own_cache_entry(cache_root, monkeypatch):
    mesh = ellipsoid()
    settings = features.FeatureSettings(**FAST)
    direct = features.compute_groups(mesh, ["agd"], **FAST)["agd"]
    path, small_path = features._cache_path(mesh, ("agd",), settings), features._cache_path(blob(), ("agd",), settings)
    take_the_large_mesh_paths(monkeypatch)
    proxy = features.compute_groups(mesh, ["agd"], **FAST)["agd"]
    assert not np.array_equal(proxy, direct)
    assert np.corrcoef(proxy[:, 0], direct[:, 0])[0, 1] > 0.99
    assert np.median(np.abs(proxy[:, 0] / direct[:, 0] - 1)) < 0.05
    assert features._cache_path(mesh, ("agd",), settings) != path
    assert blob().n_faces <= 4000  # under the threshold nothing changes, the cache entry included
    assert features._cache_path(blob(), ("agd",), settings) == small_path


def test_hks_with_our_spd_factor_is_eigsh_with_its_own():
    import igl
    from scipy.sparse.linalg import eigsh

    mesh = blob()
    ours = features._heat_kernel_signature(mesh, 16, np.array(features.HKS_TIMES))
    stiffness = -igl.cotmatrix(mesh.vertices, mesh.faces)
    mass = igl.massmatrix(mesh.vertices, mesh.faces, igl.MASSMATRIX_TYPE_VORONOI)
    values, vectors = eigsh(stiffness.tocsc(), k=16, M=mass.tocsc(), sigma=-1e-3, which="LM")
    decay = np.exp(-np.outer(np.maximum(values, 0.0), features.HKS_TIMES))
    theirs = np.log(np.maximum((vectors**2) @ decay * mesh.face_areas.sum() / decay.sum(axis=0), 1e-12))
    # ours asks for eigenvalues to spectral.EIGEN_TOLERANCE only: the same signature to well under float32 resolution
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-6)


def test_hks_of_a_large_mesh_comes_from_the_collapse_the_agd_uses(monkeypatch):
    mesh = ellipsoid()
    direct = features.compute_groups(mesh, ["hks"], **FAST)["hks"]
    take_the_large_mesh_paths(monkeypatch)
    collapses = []
    downsample = collapse.downsample
    monkeypatch.setattr(collapse, "downsample", lambda *a, **kw: collapses.append(1) or downsample(*a, **kw))
    both = features.compute_groups(mesh, ["agd", "hks"], **FAST)
    assert len(collapses) == 1  # one proxy for both groups
    proxy = both["hks"]
    assert proxy.shape == direct.shape and not np.array_equal(proxy, direct)
    # within 2 % everywhere (log values); the pattern is kept where heat spreads beyond a proxy face (t >= 0.008)
    assert np.median(np.abs(proxy - direct), axis=0).max() < 0.02
    for column in range(2, direct.shape[1]):
        assert np.corrcoef(proxy[:, column], direct[:, column])[0, 1] > 0.97


def test_smooth_group_of_a_large_mesh_diffuses_on_the_proxy_keeping_constants_and_integrals(monkeypatch):
    mesh = ellipsoid()
    direct = features.compute_groups(mesh, ["smooth"], **FAST)["smooth"]
    take_the_large_mesh_paths(monkeypatch)
    proxy = features.compute_groups(mesh, ["smooth"], **FAST)["smooth"]
    assert proxy.shape == direct.shape and not np.array_equal(proxy, direct)
    for column in range(direct.shape[1]):
        assert np.corrcoef(proxy[:, column], direct[:, column])[0, 1] > 0.99

    geometry = features._Geometry(mesh, features.FeatureSettings(**FAST))
    area = geometry.mesh.face_areas
    signal = np.stack([np.ones(mesh.n_faces), geometry.mesh.face_centroids[:, 0] ** 2], axis=1)
    coarse, face_of = geometry.proxy
    for block in diffusion.diffuse_through_proxy(geometry.mesh, coarse.mesh, face_of, signal, (0.05, 0.3)):
        np.testing.assert_allclose(block[:, 0], 1.0, rtol=1e-9)
        np.testing.assert_allclose((block[:, 1] * area).sum(), (signal[:, 1] * area).sum(), rtol=1e-9)
        assert block[:, 1].std() < signal[:, 1].std()


def test_second_call_reads_the_cache(cache_root, monkeypatch):
    mesh = blob()
    first = features.compute(mesh, **FAST)
    assert len(list(cache_root.glob("*.npy"))) == 1

    def refuse(*args, **kwargs):
        raise AssertionError("recomputed although cached")

    monkeypatch.setattr(features, "_Geometry", refuse)  # where every computation starts
    np.testing.assert_array_equal(features.compute(mesh, **FAST), first)
    with pytest.raises(AssertionError, match="recomputed"):
        features.compute(mesh, ["edge"], **FAST)  # other groups, other key
    with pytest.raises(AssertionError, match="recomputed"):
        features.compute(mesh, cache=False, **FAST)


def _flip_a_bit(data: bytes) -> bytes:
    middle = len(data) // 2  # inside the array's data, past the .npy header
    return data[:middle] + bytes([data[middle] ^ 1]) + data[middle + 1:]


@pytest.mark.parametrize(
    "damage",
    [
        lambda path: path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2]),
        lambda path: path.write_bytes(path.read_bytes()[:-1]),
        lambda path: np.save(path, np.zeros((3, 3), dtype=np.float32)),
        lambda path: cache.write_checked_array(path, np.full(np.load(path).shape, np.nan, dtype=np.float32)),
        lambda path: cache.write_checked_array(path, np.zeros((3, 3), dtype=np.float32)),
        lambda path: path.write_bytes(_flip_a_bit(path.read_bytes())),
    ],
    ids=["truncated", "checksum-cut", "no-checksum", "non-finite", "wrong-shape", "flipped-bit"],
)
def test_a_damaged_cache_entry_is_detected_and_recomputed(cache_root, damage):
    mesh = blob()
    first = features.compute(mesh, **FAST)
    (entry,) = cache_root.glob("*.npy")
    damage(entry)
    with pytest.warns(RuntimeWarning, match="damaged cache entry"):
        again = features.compute(mesh, **FAST)
    np.testing.assert_array_equal(again, first)
    np.testing.assert_array_equal(np.load(entry), first)


def test_compute_groups_can_cut_blocks_from_the_cache(cache_root):
    mesh = blob()
    blocks = features.compute_groups(mesh, ["edge", "agd"], cache=True, **FAST)
    assert len(list(cache_root.glob("*.npy"))) == 1
    fresh = features.compute_groups(mesh, ["edge", "agd"], **FAST)
    for name in ("edge", "agd"):
        np.testing.assert_array_equal(blocks[name], fresh[name])


def test_compute_many_keeps_input_order(cache_root):
    meshes = [blob(), open_cap(), grid_mesh(5)]
    expected = [features.compute(m, cache=False, **FAST) for m in meshes]
    parallel = features.compute_many(meshes, workers=2, progress=False, **FAST)
    for got, want in zip(parallel, expected):
        np.testing.assert_array_equal(got, want)
    cached = features.compute_many(meshes[::-1], workers=2, progress=False, **FAST)
    for got, want in zip(cached, expected[::-1]):
        np.testing.assert_array_equal(got, want)


def test_compute_many_keeps_small_jobs_in_this_process(cache_root, monkeypatch):
    def no_pool(*args, **kwargs):
        raise AssertionError("started a process pool for a small job")

    from anseg import parallel

    monkeypatch.setattr(parallel, "_on_loky", no_pool)
    meshes = [blob(), grid_mesh(5)]
    got = features.compute_many(meshes, progress=False, cache=False, **FAST)
    for mesh, x in zip(meshes, got):
        np.testing.assert_array_equal(x, features.compute(mesh, cache=False, **FAST))
    with pytest.raises(ValueError, match="workers"):
        features.compute_many(meshes, workers=0)


# -------------------------------------------------------------- bad input
def test_unknown_group_lists_the_valid_ones():
    with pytest.raises(ValueError, match="valid ones.*'edge'"):
        features.compute(blob(), ["edge", "curvature"], cache=False)
    with pytest.raises(ValueError, match="unknown feature groups"):
        features.feature_names("edge+gc")


def test_unknown_or_bad_settings_are_refused():
    with pytest.raises(ValueError, match="unknown feature settings"):
        features.compute(blob(), cache=False, rays=3)
    with pytest.raises(ValueError, match="sdf_cone_degrees"):
        features.compute(blob(), cache=False, sdf_cone_degrees=200)


def test_invalid_mesh_raises_mesh_error():
    mesh = grid_mesh(3)
    vertices = mesh.vertices.copy()
    vertices[0] = np.nan
    with pytest.raises(MeshError, match="NaN"):
        features.compute(Mesh(vertices, mesh.faces), cache=False)
    with pytest.raises(MeshError, match="of zero area"):
        features.compute_groups(Mesh(mesh.vertices, np.vstack([mesh.faces, [[0, 0, 1]]])), ["edge"])


def test_ablation_sets_grow_from_edge_to_all_four_descriptors():
    sets = list(features.ABLATION_SETS.values())
    assert sets[0] == ("edge",) and sets[-1] == ("edge", "gc", "sdf", "agd")
    assert all(set(a) < set(b) for a, b in zip(sets, sets[1:]))
    assert set(features.LOCAL_GROUPS) | set(features.GLOBAL_GROUPS) == set(features.GROUPS)


# --------------------------------------------------------------- real data
@pytest.mark.realdata
def test_real_meshes_give_finite_features(psb_sample):
    for category, items in psb_sample.items():
        mesh = items[0].mesh
        x = features.compute(mesh, cache=False)
        assert x.shape == (mesh.n_faces, len(features.feature_names())), category
        assert np.isfinite(x).all(), category


def test_sdf_of_a_large_mesh_through_embree_matches_our_ray_caster(monkeypatch):
    mesh = blob()
    ours = features.compute_groups(mesh, ["sdf"], **FAST)["sdf"]
    monkeypatch.setattr(proxy, "LARGE_MESH_FACES", mesh.n_faces - 1)
    embree = features.compute_groups(mesh, ["sdf"], **FAST)["sdf"]
    np.testing.assert_allclose(embree[:, 0], ours[:, 0], rtol=1e-4)
    for threads in (1, 3):  # the rays split between threads: the same hits
        monkeypatch.setattr(features, "_threads_allowed", lambda: threads)
        np.testing.assert_array_equal(features.compute_groups(mesh, ["sdf"], **FAST)["sdf"], embree)
