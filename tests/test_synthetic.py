"""The embedded synthetic data set: valid closed meshes, labels, junction refinement, seeds and splits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from anseg import datasets
from anseg.datasets import DatasetError, LabeledMesh, synthetic

SHAPES = [("figure", 0), ("figure", 1), ("vessel", 0), ("vessel", 3)]


@pytest.fixture(scope="module")
def shapes() -> dict[tuple[str, int], LabeledMesh]:
    return {(category, index): synthetic.generate(category, index) for category, index in SHAPES}


def face_components(mesh, keep: np.ndarray) -> int:
    """Number of edge-connected components among the faces where ``keep`` is true."""
    pairs = mesh.face_adjacency
    pairs = pairs[keep[pairs[:, 0]] & keep[pairs[:, 1]]]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(mesh.n_faces,) * 2)
    _, component = connected_components(graph, directed=False)
    return len(np.unique(component[keep]))


def test_same_seed_gives_the_same_shape_and_another_seed_another(shapes):
    again = synthetic.generate("figure", 1)
    first = shapes[("figure", 1)]
    assert np.array_equal(again.mesh.vertices, first.mesh.vertices)
    assert np.array_equal(again.mesh.faces, first.mesh.faces)
    assert np.array_equal(again.labels, first.labels)
    other = synthetic.generate("figure", 1, seed=1)
    assert other.mesh.n_faces != first.mesh.n_faces or not np.allclose(other.mesh.vertices, first.mesh.vertices)


@pytest.mark.parametrize("key", SHAPES, ids=[f"{c}_{i}" for c, i in SHAPES])
def test_shape_is_a_valid_closed_manifold_of_the_expected_genus(shapes, key):
    shape = shapes[key]
    mesh = shape.mesh
    mesh.validate()
    assert (mesh.edge_face_counts == 2).all(), "every edge has exactly two faces: closed, manifold"
    assert face_components(mesh, np.ones(mesh.n_faces, dtype=bool)) == 1
    handle = shape.label_names.index("handle") if "handle" in shape.label_names else None
    # figures are sphere-like; each vessel handle adds one to the genus
    genus = 0 if handle is None else face_components(mesh, shape.labels == handle)
    assert mesh.euler_characteristic == 2 - 2 * genus
    assert key[0] == "figure" or genus in (1, 2)
    # outward orientation: positive enclosed volume
    v = mesh.vertices[mesh.faces]
    assert np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() > 0


@pytest.mark.parametrize("key", SHAPES, ids=[f"{c}_{i}" for c, i in SHAPES])
def test_shape_has_every_label_a_few_thousand_faces_and_a_name(shapes, key):
    category, index = key
    shape = shapes[key]
    assert shape.name == f"{category}_{index:03d}"
    assert shape.label_names == synthetic.LABEL_NAMES[category]
    assert 1500 <= shape.mesh.n_faces <= 6000
    assert set(np.unique(shape.labels)) == set(range(len(shape.label_names)))


@pytest.mark.parametrize("key", SHAPES, ids=[f"{c}_{i}" for c, i in SHAPES])
def test_faces_at_part_junctions_are_smaller(shapes, key):
    shape = shapes[key]
    mesh, labels = shape.mesh, shape.labels
    at_junction = (labels[mesh.face_neighbors] != labels[:, None]).any(axis=1)
    ratio = mesh.face_areas[~at_junction].mean() / mesh.face_areas[at_junction].mean()
    assert ratio > 1.3, f"faces away from part boundaries are only {ratio:.2f} times larger"


def test_triangles_are_well_shaped(shapes):
    for shape in shapes.values():
        v = shape.mesh.vertices[shape.mesh.faces]
        edges = [np.linalg.norm(v[:, (k + 1) % 3] - v[:, k], axis=1) for k in range(3)]
        # the smallest angle is opposite the shortest edge; its sine is 2 area / (product of the other two)
        shortest = np.argmin(edges, axis=0)
        others = np.prod(edges, axis=0) / np.choose(shortest, edges)
        smallest_angle = np.degrees(np.arcsin(np.clip(2 * shape.mesh.face_areas / others, 0, 1)))
        assert (smallest_angle < 10).mean() < 0.02, shape.name


def test_splits_are_disjoint_and_the_test_sets_cover_every_shape():
    tested = []
    for k in range(synthetic.N_SPLITS):
        train = synthetic.split_indices(16, "train", k)
        test = synthetic.split_indices(16, "test", k)
        assert (len(train), len(test)) == (12, 4)
        assert not set(train) & set(test)
        assert sorted(train + test) == synthetic.split_indices(16, "all", k) == list(range(16))
        tested += test
    assert sorted(tested) == list(range(16))


def test_load_through_the_registry_picks_the_split_shapes(shapes):
    loaded = datasets.load("synthetic", category="figure", split="test", split_index=1, n_shapes=4, progress=False)
    assert [m.name for m in loaded] == ["figure_001"]
    # a shape does not depend on how many shapes are asked for
    assert np.array_equal(loaded[0].mesh.vertices, shapes[("figure", 1)].mesh.vertices)


def test_load_without_category_returns_every_category():
    loaded = synthetic.load(category=None, split="test", split_index=0, n_shapes=4, progress=False)
    assert [m.name for m in loaded] == ["figure_000", "vessel_000"]
    assert [m.label_names for m in loaded] == [synthetic.LABEL_NAMES["figure"], synthetic.LABEL_NAMES["vessel"]]


@pytest.mark.parametrize(
    "options",
    [
        {"category": "chair"},
        {"category": "figure", "split": "validation"},
        {"category": "figure", "split_index": synthetic.N_SPLITS},
        {"category": "figure", "n_shapes": synthetic.N_SPLITS - 1},
    ],
)
def test_bad_requests_raise_a_dataset_error(options):
    with pytest.raises(DatasetError):
        synthetic.load(progress=False, **options)


def test_revolved_profile_distance_has_the_right_sign():
    """Inside/outside of the turned profile agrees with a point-in-polygon test of the half-section."""
    from matplotlib.path import Path

    rng = np.random.default_rng(0)
    shape = None
    while shape is None:
        shape = synthetic._vessel(rng)
    body = shape.parts[0]
    lower, upper = body.bounds()
    rho = rng.uniform(0.0, upper[0] + 0.2, 20000)
    z = rng.uniform(lower[2] - 0.2, upper[2] + 0.2, 20000)
    angle = rng.uniform(0.0, 2 * np.pi, 20000)
    points = np.stack([rho * np.cos(angle), rho * np.sin(angle), z], axis=1)
    inside = Path(body.profile).contains_points(np.stack([rho, z], axis=1))
    distance = body.distance(points)
    clear = np.abs(distance) > 1e-6
    assert np.array_equal((distance < 0)[clear], inside[clear])
