"""Edge-collapse downsampling, its record (exact undo, face map), pooling and upsampling."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from conftest import grid_mesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from anseg.collapse import COLLAPSE_MODES, PRIORITIES, CollapseWarning, downsample, rings_to_other_label, upsample
from anseg.hierarchy import compose, one_hot, pool, pool_labels, round_trip_labels, upsample_through
from anseg.mesh import Mesh, MeshError

TETRA = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float),
             np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))


# ----------------------------------------------------------------------------- mesh makers
def bumpy_grid(n, rng, hole=False):
    """An n x n grid with jittered vertices; with a hole, one interior cell removed (two boundary loops)."""
    grid = grid_mesh(n)
    vertices = grid.vertices + np.c_[0.2 * rng.random((grid.n_vertices, 2)), 0.3 * rng.random(grid.n_vertices)]
    faces = grid.faces
    if hole:
        cell = (n // 2) * n + n // 2  # grid_mesh numbers cells row-major, the two triangles of a cell n*n apart
        faces = np.delete(faces, [cell, cell + n * n], axis=0)
    return Mesh(vertices, faces)


def bumpy_sphere(subdivisions, rng):
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    return Mesh(sphere.vertices * (1 + 0.1 * rng.random((len(sphere.vertices), 1))), sphere.faces)


def bumpy_torus(rng):
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35,
                                   major_sections=int(rng.integers(12, 24)), minor_sections=8)
    return Mesh(torus.vertices + 0.02 * rng.random(torus.vertices.shape), torus.faces)


def two_components(rng):
    a, b = bumpy_sphere(2, rng), bumpy_grid(6, rng)
    return Mesh(np.vstack([a.vertices, b.vertices + [3.0, 0, 0]]), np.vstack([a.faces, b.faces + a.n_vertices]))


def shuffled(mesh, rng):
    """The same surface with faces, vertices and each face's corner order permuted."""
    relabel = rng.permutation(mesh.n_vertices)
    faces = relabel[mesh.faces][rng.permutation(mesh.n_faces)]
    faces = np.roll(faces, int(rng.integers(3)), axis=1)
    vertices = np.empty_like(mesh.vertices)
    vertices[relabel] = mesh.vertices
    return Mesh(vertices, faces)


@st.composite
def meshes(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    kind = draw(st.sampled_from(["grid", "holed grid", "sphere", "torus", "two components"]))
    if kind == "grid":
        mesh = bumpy_grid(draw(st.integers(3, 10)), rng)
    elif kind == "holed grid":
        mesh = bumpy_grid(draw(st.integers(4, 10)), rng, hole=True)
    elif kind == "sphere":
        mesh = bumpy_sphere(draw(st.integers(1, 3)), rng)
    elif kind == "torus":
        mesh = bumpy_torus(rng)
    else:
        mesh = two_components(rng)
    return shuffled(mesh, rng)


# ----------------------------------------------------------------------------- checks
def vertex_manifold(mesh) -> bool:
    """Whether the faces around every vertex form a single fan (corners joined across shared edges)."""
    faces, pairs = mesh.faces, mesh.face_adjacency
    shared = mesh.edges[mesh.interior_edges]
    rows, cols = [], []
    for end in range(2):
        v = shared[:, end : end + 1]
        rows.append(3 * pairs[:, 0] + np.argmax(faces[pairs[:, 0]] == v, axis=1))
        cols.append(3 * pairs[:, 1] + np.argmax(faces[pairs[:, 1]] == v, axis=1))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * mesh.n_faces,) * 2)
    fan = connected_components(graph, directed=False)[1]
    vertex_fan = np.unique(np.c_[faces.ravel(), fan], axis=0)
    return bool((np.bincount(vertex_fan[:, 0]) <= 1).all())


def check_cycle(fine, coarse, record, warned):
    """The invariants every downsampling cycle must keep."""
    target = record.target_faces
    if record.reached_target:
        assert 0 <= coarse.n_faces - target <= max(1, 0.01 * target)
        assert not warned
    else:
        assert warned and coarse.n_faces > target + 1
    assert coarse.n_faces == fine.n_faces - 2 * record.n_collapses
    assert (coarse.edge_face_counts <= 2).all()
    assert vertex_manifold(coarse)
    assert (coarse.face_areas > 0).all()
    assert coarse.euler_characteristic == fine.euler_characteristic
    assert coarse.boundary_loop_count == fine.boundary_loop_count
    assert len(np.unique(coarse.faces)) == coarse.n_vertices  # compacted: every vertex used
    back = record.replay()
    np.testing.assert_array_equal(back.faces, fine.faces)
    np.testing.assert_array_equal(back.vertices, fine.vertices)
    face_map = record.fine_to_coarse
    assert face_map.shape == (fine.n_faces,) and face_map.min() >= 0 and face_map.max() < coarse.n_faces
    np.testing.assert_array_equal(face_map[record.coarse_face_ids], np.arange(coarse.n_faces))


def run_cycle(mesh, mode, ratio, rng, **options):
    scores = np.exp(rng.normal(size=mesh.n_faces)) if mode == "nonuniform" else None  # positive, for either priority
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        coarse, record = downsample(mesh, scores, ratio=ratio, mode=mode, seed=int(rng.integers(100)), **options)
    return coarse, record, any(issubclass(w.category, CollapseWarning) for w in caught)


# ----------------------------------------------------------------------------- properties
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mesh=meshes(), mode=st.sampled_from(COLLAPSE_MODES), ratio=st.floats(0.3, 0.9), seed=st.integers(0, 1000),
       once_per_pass=st.booleans(), priority=st.sampled_from(PRIORITIES))
def test_cycles_keep_topology_and_undo_exactly(mesh, mode, ratio, seed, once_per_pass, priority):
    rng = np.random.default_rng(seed)
    records, current = [], mesh
    for _ in range(2):
        coarse, record, warned = run_cycle(current, mode, ratio, rng, once_per_pass=once_per_pass, priority=priority)
        check_cycle(current, coarse, record, warned)
        records.append(record)
        current = coarse
    # the stacked map and the multi-level upsample agree with their one-level steps
    np.testing.assert_array_equal(compose(records), records[1].fine_to_coarse[records[0].fine_to_coarse])
    probs = rng.random((current.n_faces, 3))
    np.testing.assert_array_equal(upsample_through(records, probs), upsample(records[0], upsample(records[1], probs)))


@settings(max_examples=15, deadline=None)
@given(mesh=meshes(), mode=st.sampled_from(COLLAPSE_MODES), label=st.integers(0, 3))
def test_constant_labels_survive_the_round_trip(mesh, mode, label):
    rng = np.random.default_rng(0)
    records, current = [], mesh
    for _ in range(2):
        current, record, _ = run_cycle(current, mode, 0.5, rng)
        records.append(record)
    labels = np.full(mesh.n_faces, label)
    coarse_labels = pool_labels(records, labels, mesh.face_areas, n_classes=4)
    np.testing.assert_array_equal(coarse_labels, label)
    np.testing.assert_array_equal(upsample_through(records, one_hot(coarse_labels, 4)), one_hot(labels, 4))
    np.testing.assert_array_equal(round_trip_labels(records, labels, mesh.face_areas, 4), labels)


@settings(max_examples=15, deadline=None)
@given(mesh=meshes(), mode=st.sampled_from(COLLAPSE_MODES), seed=st.integers(0, 2**16))
def test_the_round_trip_keeps_labels_of_faces_no_collapse_touched(mesh, mode, seed):
    """A face that survives every cycle keeps the coarse label it pooled to; with one label per face, its own."""
    rng = np.random.default_rng(seed)
    records, current = [], mesh
    for _ in range(2):
        current, record, _ = run_cycle(current, mode, 0.5, rng)
        records.append(record)
    labels = rng.integers(0, 3, mesh.n_faces)
    back = round_trip_labels(records, labels, mesh.face_areas, 3)
    assert back.shape == labels.shape and set(np.unique(back)) <= set(np.unique(labels))
    alone = np.bincount(compose(records), minlength=current.n_faces)[compose(records)] == 1  # stands for itself alone
    np.testing.assert_array_equal(back[alone], labels[alone])
    np.testing.assert_array_equal(round_trip_labels([], labels, mesh.face_areas, 3), labels)  # the input level


@pytest.mark.parametrize("mode", COLLAPSE_MODES)
def test_closed_meshes_reach_the_target_each_cycle(mode):
    rng = np.random.default_rng(1)
    mesh = bumpy_sphere(4, rng)  # 5120 faces
    for _ in range(4):
        coarse, record, warned = run_cycle(mesh, mode, 0.5, rng)
        assert record.reached_target and coarse.n_faces == round(0.5 * mesh.n_faces)
        check_cycle(mesh, coarse, record, warned)
        mesh = coarse


# ----------------------------------------------------------------------------- the record
def test_replay_undoes_from_the_coarse_mesh_it_is_given():
    rng = np.random.default_rng(2)
    mesh = bumpy_sphere(2, rng)
    coarse, record = downsample(mesh, rng.random(mesh.n_faces))
    moved = Mesh(coarse.vertices + 10.0, coarse.faces)
    back = record.replay(moved)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    # collapses restore the positions of the vertices they touched; the others come from the coarse mesh
    touched = np.zeros(mesh.n_vertices, bool)
    touched[record.kept_vertex] = touched[record.removed_vertex] = True
    np.testing.assert_array_equal(back.vertices[touched], mesh.vertices[touched])
    np.testing.assert_array_equal(back.vertices[~touched], mesh.vertices[~touched] + 10.0)
    with pytest.raises(ValueError, match="does not match"):
        record.replay(Mesh(coarse.vertices, np.roll(coarse.faces, 1, axis=0)))
    with pytest.raises(ValueError, match="coarse mesh has"):
        record.replay(mesh)


def test_removed_faces_map_to_an_adjacent_coarse_face():
    """A removed face is stood for by a coarse face that shares a (merged) vertex with it."""
    rng = np.random.default_rng(3)
    mesh = bumpy_sphere(3, rng)
    coarse, record = downsample(mesh, mode="uniform")
    # follow every fine vertex to the coarse vertex it merged into
    merged_into = np.arange(mesh.n_vertices)
    for kept, removed in zip(record.kept_vertex, record.removed_vertex):
        merged_into[merged_into == removed] = kept
    coarse_vertex = np.full(mesh.n_vertices, -1)
    coarse_vertex[record.coarse_vertex_ids] = np.arange(coarse.n_vertices)
    fine_in_coarse = coarse_vertex[merged_into[mesh.faces]]
    stand_in = coarse.faces[record.fine_to_coarse]
    shares = (fine_in_coarse[:, :, None] == stand_in[:, None, :]).any(axis=(1, 2))
    assert shares.all()


def test_nonuniform_collapses_where_scores_are_low():
    rng = np.random.default_rng(4)
    mesh = bumpy_sphere(3, rng)
    x = mesh.face_centroids[:, 0]
    coarse, record = downsample(mesh, scores=x, ratio=0.6)
    removed = np.zeros(mesh.n_faces, bool)
    removed[record.removed_faces.ravel()] = True
    assert removed[x < -0.3].mean() > 0.6 and removed[x > 0.3].mean() < 0.05


def test_once_per_pass_spreads_the_collapses_of_a_low_score_region():
    rng = np.random.default_rng(4)
    mesh = bumpy_sphere(3, rng)
    x = mesh.face_centroids[:, 0]
    largest = {}
    for once in (False, True):
        coarse, record = downsample(mesh, scores=x, ratio=0.6, once_per_pass=once)
        assert record.reached_target
        largest[once] = np.bincount(record.fine_to_coarse).max()  # input faces behind the largest coarse face
    assert largest[True] < largest[False]


def test_weighted_priority_with_a_flat_score_is_the_uniform_collapse():
    mesh = bumpy_sphere(3, np.random.default_rng(5))
    uniform, _ = downsample(mesh, mode="uniform", ratio=0.5)
    flat, _ = downsample(mesh, np.full(mesh.n_faces, 0.7), ratio=0.5, priority="weighted")
    np.testing.assert_array_equal(flat.faces, uniform.faces)
    np.testing.assert_array_equal(flat.vertices, uniform.vertices)


def test_weighted_priority_thins_a_low_score_region_without_giant_faces():
    mesh = bumpy_sphere(3, np.random.default_rng(4))
    x = mesh.face_centroids[:, 0]
    scores = np.where(x < 0, 0.25, 1.0)
    largest, removed = {}, {}
    for priority in PRIORITIES:
        _, record = downsample(mesh, scores, ratio=0.6, priority=priority)
        largest[priority] = np.bincount(record.fine_to_coarse).max()
        gone = np.zeros(mesh.n_faces, bool)
        gone[record.removed_faces.ravel()] = True
        removed[priority] = (gone[x < -0.3].mean(), gone[x > 0.3].mean())
    low, high = removed["weighted"]
    assert low > 2 * high  # density still follows the score...
    assert largest["weighted"] < largest["score"] / 2  # ...but no region is merged into a few faces


def test_uniform_collapses_short_edges_first():
    """On a grid that is dense on the left half, uniform removes the dense faces first."""
    grid = grid_mesh(16)
    vertices = grid.vertices.copy()
    vertices[:, 0] = np.where(vertices[:, 0] <= 8, vertices[:, 0] / 4, 2 + (vertices[:, 0] - 8))
    mesh = Mesh(vertices, grid.faces)
    coarse, record = downsample(mesh, mode="uniform", ratio=0.75)
    removed = np.zeros(mesh.n_faces, bool)
    removed[record.removed_faces.ravel()] = True
    dense = mesh.face_centroids[:, 0] < 1.9
    assert removed[dense].mean() > 0.4 and removed[~dense].mean() < 0.05


def test_random_mode_depends_on_seed_only():
    mesh = bumpy_sphere(2, np.random.default_rng(5))
    a, _ = downsample(mesh, mode="random", seed=1)
    b, _ = downsample(mesh, mode="random", seed=1)
    c, _ = downsample(mesh, mode="random", seed=2)
    np.testing.assert_array_equal(a.faces, b.faces)
    assert a.faces.shape != c.faces.shape or (a.faces != c.faces).any()


# ----------------------------------------------------------------------------- pooling and upsampling
def test_pool_is_the_weighted_mean_over_each_coarse_face():
    rng = np.random.default_rng(6)
    mesh = bumpy_sphere(2, rng)
    coarse, record = downsample(mesh, rng.random(mesh.n_faces))
    values, weights = rng.random((mesh.n_faces, 2)), mesh.face_areas
    pooled = pool(record, values, weights)
    face_map = record.fine_to_coarse
    for i in (0, coarse.n_faces // 2, coarse.n_faces - 1):
        members = face_map == i
        np.testing.assert_allclose(pooled[i], (values[members] * weights[members, None]).sum(0) / weights[members].sum())
    np.testing.assert_allclose(pool(record, values[:, 0], weights), pooled[:, 0])


def test_pool_labels_takes_the_area_majority():
    mesh = bumpy_sphere(2, np.random.default_rng(7))
    coarse, record = downsample(mesh, mode="uniform")
    labels = (mesh.face_centroids[:, 2] > 0).astype(int)
    pooled = pool_labels(record, labels, mesh.face_areas, n_classes=2)
    area_of_one = np.bincount(record.fine_to_coarse, mesh.face_areas * labels, coarse.n_faces)
    area_all = np.bincount(record.fine_to_coarse, mesh.face_areas, coarse.n_faces)
    np.testing.assert_array_equal(pooled, (area_of_one > area_all / 2).astype(int))


def test_upsample_keeps_survivors_and_votes_for_reappearing_faces():
    rng = np.random.default_rng(8)
    mesh = bumpy_sphere(3, rng)
    coarse, record = downsample(mesh, rng.random(mesh.n_faces))
    probs = rng.dirichlet(np.ones(4), size=coarse.n_faces)
    fine = upsample(record, probs)
    np.testing.assert_array_equal(fine[record.coarse_face_ids], probs)
    np.testing.assert_allclose(fine.sum(axis=1), 1.0)
    # the last collapse is undone first: its faces vote with faces that are still coarse faces
    t = record.n_collapses - 1
    coarse_index = {f: i for i, f in enumerate(record.coarse_face_ids)}
    for j in range(2):
        voters = [coarse_index[h] for h in record.outer_neighbors[t, j] if h >= 0]
        expected = probs[voters].sum(0)
        np.testing.assert_allclose(fine[record.removed_faces[t, j]], expected / expected.sum())


def test_oracle_scores_keep_a_two_part_labelling():
    """Collapsing far from the label boundary first loses less than collapsing uniformly (the paper's premise)."""
    rng = np.random.default_rng(9)
    mesh = bumpy_sphere(4, rng)
    labels = (mesh.face_centroids[:, 0] > 0.2).astype(int)
    distance = np.abs(mesh.face_centroids[:, 0] - 0.2)
    accuracy = {}
    for mode in ("nonuniform", "uniform"):
        coarse, record = downsample(mesh, -distance if mode == "nonuniform" else None, ratio=0.25, mode=mode)
        back = upsample(record, one_hot(pool_labels(record, labels, mesh.face_areas, 2), 2)).argmax(1)
        accuracy[mode] = mesh.face_areas[back == labels].sum() / mesh.face_areas.sum()
    assert accuracy["nonuniform"] > accuracy["uniform"]
    assert accuracy["nonuniform"] > 0.995


def test_chained_records_must_fit():
    mesh = bumpy_sphere(2, np.random.default_rng(10))
    first_coarse, first = downsample(mesh, mode="uniform")
    _, second = downsample(first_coarse, mode="uniform")
    with pytest.raises(ValueError, match="do not chain"):
        compose([second, first])
    with pytest.raises(ValueError, match="coarse_probs"):
        upsample(first, np.ones((3, 2)))
    with pytest.raises(ValueError, match="at least one"):
        compose([])


# ----------------------------------------------------------------------------- bad input and dead ends
@pytest.mark.parametrize(
    "scores, mode, message",
    [
        (None, "nonuniform", "needs per-face scores"),
        (np.zeros(7), "nonuniform", "shape"),
        (np.r_[np.nan, np.zeros(79)], "nonuniform", "finite"),
        (np.r_[np.inf, np.zeros(79)], "nonuniform", "finite"),
        (np.zeros(80), "uniform", "only used in nonuniform"),
        (None, "shortest", "mode must be"),
    ],
)
def test_bad_scores_and_modes_raise(scores, mode, message):
    mesh = bumpy_sphere(1, np.random.default_rng(11))  # 80 faces
    with pytest.raises(ValueError, match=message):
        downsample(mesh, scores, mode=mode)
    with pytest.raises(ValueError, match="positive scores"):
        downsample(mesh, np.r_[0.0, np.ones(79)], priority="weighted")
    with pytest.raises(ValueError, match="priority must be"):
        downsample(mesh, np.ones(80), priority="fastest")


def test_bad_ratio_and_meshes_raise():
    mesh = bumpy_sphere(1, np.random.default_rng(12))
    for ratio in (0.0, 1.5):
        with pytest.raises(ValueError, match="ratio"):
            downsample(mesh, mode="uniform", ratio=ratio)
    fin = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1]], [[0, 1, 2], [0, 1, 3], [1, 0, 4]])
    with pytest.raises(MeshError, match="more than two faces"):
        downsample(fin, mode="uniform")
    with pytest.raises(MeshError, match="repeat a vertex"):
        downsample(Mesh(TETRA.vertices, [[0, 1, 1]]), mode="uniform")


@pytest.mark.parametrize("mode", COLLAPSE_MODES)
def test_a_tetrahedron_stops_with_a_warning(mode):
    scores = np.arange(4.0) if mode == "nonuniform" else None
    with pytest.warns(CollapseWarning, match="stopped at 4 faces"):
        coarse, record = downsample(TETRA, scores, ratio=0.5, mode=mode)
    assert not record.reached_target and record.n_collapses == 0
    np.testing.assert_array_equal(coarse.faces, TETRA.faces)
    np.testing.assert_array_equal(record.fine_to_coarse, np.arange(4))


def test_ratio_one_changes_nothing():
    mesh = bumpy_sphere(1, np.random.default_rng(13))
    coarse, record = downsample(mesh, mode="uniform", ratio=1.0)
    assert record.n_collapses == 0 and record.reached_target
    np.testing.assert_array_equal(coarse.faces, mesh.faces)


# ----------------------------------------------------------------------------- real meshes
@pytest.mark.realdata
@pytest.mark.parametrize("mode", ["nonuniform", "uniform"])
def test_real_meshes_four_cycles(psb_sample, mode):
    rng = np.random.default_rng(14)
    for items in psb_sample.values():
        item = items[0]
        records, current = [], item.mesh
        for _ in range(4):
            coarse, record, warned = run_cycle(current, mode, 0.5, rng)
            assert record.reached_target
            check_cycle(current, coarse, record, warned)
            records.append(record)
            current = coarse
        n_classes = len(item.label_names)
        coarse_labels = pool_labels(records, item.labels, item.mesh.face_areas, n_classes)
        back = upsample_through(records, one_hot(coarse_labels, n_classes)).argmax(1)
        assert item.mesh.face_areas[back == item.labels].sum() / item.mesh.face_areas.sum() > 0.9


@pytest.mark.parametrize("mode", COLLAPSE_MODES)
def test_no_face_folds_over_on_a_flat_mesh(mode):
    """A flat mesh stays flat and facing up: a fold-over is a 180-degree normal flip."""
    rng = np.random.default_rng(15)
    grid = grid_mesh(24)
    mesh = Mesh(grid.vertices + np.c_[0.45 * rng.random((grid.n_vertices, 2)), np.zeros(grid.n_vertices)], grid.faces)
    assert (mesh.face_normals[:, 2] > 0).all()
    for _ in range(3):
        mesh, _, _ = run_cycle(mesh, mode, 0.6, rng, max_normal_flip_deg=179.0)
        assert (mesh.face_normals[:, 2] > 0).all()


def test_rings_to_other_label_match_a_breadth_first_search_over_shared_edges():
    from collections import deque

    mesh = grid_mesh(6)
    labels = (mesh.face_centroids[:, 0] > 2.5).astype(int) + 2 * (mesh.face_centroids[:, 1] > 4.2)
    # neighbours from the faces' own edges, not from the mesh's adjacency tables
    by_edge = {}
    for face, corners in enumerate(mesh.faces):
        for a, b in ((0, 1), (1, 2), (2, 0)):
            by_edge.setdefault(tuple(sorted((corners[a], corners[b]))), []).append(face)
    neighbours = {f: set() for f in range(mesh.n_faces)}
    for faces in by_edge.values():
        for f in faces:
            neighbours[f].update(g for g in faces if g != f)
    distance = np.full(mesh.n_faces, np.inf)
    queue = deque()
    for f in range(mesh.n_faces):
        if any(labels[g] != labels[f] for g in neighbours[f]):
            distance[f] = 1
            queue.append(f)
    while queue:
        f = queue.popleft()
        for g in neighbours[f]:
            if distance[g] > distance[f] + 1:
                distance[g] = distance[f] + 1
                queue.append(g)
    np.testing.assert_array_equal(rings_to_other_label(mesh, labels), distance)
