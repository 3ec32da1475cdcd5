"""The embedded synthetic data set: seeded, labelled part-based shapes, no download.

Every stage and notebook can run on it in minutes on a small CPU. Two categories of closed
manifold meshes, each aiming at a face count drawn from ``FACE_RANGE``:

* ``figure``: articulated figures (ellipsoid torso, neck and head, tapered limbs, hands, feet) of varying
  proportions and pose, drawn again where limbs would touch, so of genus 0. Labels: head (with the neck),
  torso, upper_arm, lower_arm, hand, upper_leg, lower_leg, foot; left and right share one, as in PSB Human.
* ``vessel``: vases and jugs, a profile (foot, body, shoulder, neck, flared lip) turned about
  the vertical axis, with one or two handles (genus = handles). Labels: base, body, neck, lip, handle.

A shape is an implicit solid, the smooth union of its parts' distance functions; marching cubes
(libigl) meshes it on a grid contracted about the part junctions, so edges there are up to
``_REFINE`` times shorter, as on real models, and weighted tangential smoothing turns the slivers
into well-shaped triangles. A face takes the label of the part nearest its centroid. A shape that
fails its checks (valid, closed, expected genus, every label present) is drawn again.

Shape ``i`` of a category comes from ``numpy.random.default_rng([seed, category_number, i])``, so
it does not depend on how many shapes are asked for. The ``N_SPLITS`` fixed splits form a
partition: split ``k`` tests the shapes whose index is ``k`` modulo ``N_SPLITS`` and trains on the
rest. Label sets differ by category, so train and evaluate per category; ``category=None`` returns
both, for looking. Sizes and mesh quality as measured: ``docs/decisions.md``.
"""

from __future__ import annotations

import numpy as np

from anseg.datasets.common import SPLITS, DatasetError, LabeledMesh, progress_bar
from anseg.datasets.implicit import Ellipsoid, Junction, Revolved, Shape, Tube, TubePath, unit
from anseg.mesh import Mesh, MeshError, repair

CATEGORIES = ("figure", "vessel")
LABEL_NAMES = {
    "figure": ["head", "torso", "upper_arm", "lower_arm", "hand", "upper_leg", "lower_leg", "foot"],
    "vessel": ["base", "body", "neck", "lip", "handle"],
}
N_SHAPES = 16
N_SPLITS = 4
DEFAULT_SEED = 0
FACE_RANGE = (2500, 4500)  # each shape aims at a face count drawn from this range

# Marching-cubes faces per grid cell area on the surface, measured on the generator's output (the
# refined-area estimate counts rings as if they refined both ways, so vessels get fewer; docs/decisions.md).
_FACES_PER_CELL = 0.7
# How much finer the tessellation is at a junction centre than far from junctions (edge length ratio).
_REFINE = 4.0
_PULL = 1.0 - 1.0 / _REFINE  # the grid contraction's strength at a junction centre
_RELAX_STEPS = 5
_RELAX_RATE = 0.5
_MAX_DRAWS = 40


class SyntheticShapeError(RuntimeError):
    """The generator found no valid shape for a seed within its allowed number of draws."""


# ---------------------------------------------------------------- figure
def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation of ``v`` about the unit ``axis`` (Rodrigues)."""
    return v * np.cos(angle) + np.cross(axis, v) * np.sin(angle) + axis * (axis @ v) * (1 - np.cos(angle))


def _bend(direction: np.ndarray, towards: np.ndarray, angle: float) -> np.ndarray:
    """``direction`` turned by ``angle`` in the plane it spans with ``towards``."""
    perpendicular = towards - (towards @ direction) * direction
    return np.cos(angle) * direction + np.sin(angle) * unit(perpendicular)


def _figure(rng: np.random.Generator) -> Shape | None:
    """Draw proportions and a pose; None when two parts that must stay apart come too close."""
    lab = {name: i for i, name in enumerate(LABEL_NAMES["figure"])}
    uniform = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    angle = lambda lo, hi: np.deg2rad(uniform(lo, hi))  # noqa: E731
    up, forward, sideways = np.eye(3)[2], np.eye(3)[1], np.eye(3)[0]

    thigh, shin = uniform(0.38, 0.48), uniform(0.36, 0.46)
    upper_arm, forearm = uniform(0.26, 0.34), uniform(0.23, 0.3)
    arm_r, thigh_r, head_r = uniform(0.04, 0.055), uniform(0.055, 0.075), uniform(0.09, 0.13)
    hip_offset = thigh_r * uniform(1.15, 1.4)
    torso_radii = np.array([max(uniform(0.14, 0.19), hip_offset / 0.7), uniform(0.08, 0.12), uniform(0.3, 0.38)])
    hip_z = thigh + shin + 0.06
    torso_c = np.array([0.0, 0.0, hip_z + 0.55 * torso_radii[2]])

    def torso_half_width(z: float) -> float:
        return torso_radii[0] * np.sqrt(max(1.0 - ((z - torso_c[2]) / torso_radii[2]) ** 2, 0.0))

    neck_base = torso_c + np.array([0.0, 0.0, 0.9 * torso_radii[2]])
    neck_dir = unit(up + np.array([uniform(-0.25, 0.25), uniform(-0.15, 0.3), 0.0]))
    head_c = neck_base + neck_dir * (0.1 + head_r)
    neck = Tube(neck_base - 0.04 * neck_dir, head_c, 0.05 + 0.2 * head_r, 0.5 * head_r, lab["head"])
    head = Ellipsoid(head_c, head_r * np.array([0.9, 1.0, 1.15]), lab["head"])
    parts = [Ellipsoid(torso_c, torso_radii, lab["torso"]), neck, head]
    blends = [0.04, 0.03]
    touching = [(0, 1), (1, 2)]
    junctions = [Junction(neck_base, 2.5 * neck.ra)]

    shoulder_z = torso_c[2] + 0.62 * torso_radii[2]
    for side in (-1.0, 1.0):
        outward = side * sideways
        # arm: abduction from hanging down, a forward or backward swing, then the elbow
        shoulder = np.array([side * 0.8 * torso_half_width(shoulder_z), 0.0, shoulder_z])
        d = _rotate(_bend(-up, outward, angle(30, 95)), sideways, angle(-35, 60))
        elbow = shoulder + upper_arm * d
        bend_towards = _rotate(forward, d, angle(-40, 40)) if abs(d @ forward) < 0.95 else up
        f = _bend(d, bend_towards, angle(0, 110))
        wrist = elbow + forearm * f
        hand_len = uniform(0.08, 0.11)
        palm = unit(np.cross(f, forward if abs(f @ forward) < 0.95 else up))
        hand_frame = np.stack([f, palm, np.cross(f, palm)], axis=1)
        first = len(parts)
        parts += [
            Tube(shoulder, elbow, arm_r * 1.15, arm_r, lab["upper_arm"]),
            Tube(elbow, wrist, arm_r, 0.85 * arm_r, lab["lower_arm"]),
            Ellipsoid(wrist + 0.8 * hand_len * f, hand_len * np.array([1.0, 0.6, 0.4]), lab["hand"], hand_frame),
        ]
        blends += [0.06, 0.5 * arm_r, 0.4 * arm_r]
        touching += [(0, first), (first, first + 1), (first + 1, first + 2)]
        junctions += [Junction(shoulder, 3.0 * arm_r), Junction(elbow, 2.5 * arm_r), Junction(wrist, 2.5 * arm_r)]

        # leg: spread and swing at the hip, the knee bends backwards, the foot points forwards
        hip = np.array([side * hip_offset, 0.0, hip_z])
        d = _rotate(_bend(-up, outward, angle(3, 22)), sideways, angle(-25, 65))
        knee = hip + thigh * d
        s = _bend(d, -forward, angle(0, 95))
        ankle = knee + shin * s
        toe = ankle + uniform(0.17, 0.24) * _bend(s, forward, angle(75, 100))
        first = len(parts)
        parts += [
            Tube(hip, knee, thigh_r, 0.8 * thigh_r, lab["upper_leg"]),
            Tube(knee, ankle, 0.8 * thigh_r, 0.6 * thigh_r, lab["lower_leg"]),
            Tube(ankle, toe, 0.65 * thigh_r, 0.55 * thigh_r, lab["foot"]),
        ]
        blends += [0.06, 0.4 * thigh_r, 0.3 * thigh_r]
        touching += [(0, first), (first, first + 1), (first + 1, first + 2)]
        junctions += [Junction(hip, 2.5 * thigh_r), Junction(knee, 2.5 * thigh_r), Junction(ankle, 2.5 * thigh_r)]
    if not _parts_apart(parts, touching, gap=0.04):
        return None
    return Shape(parts, blends, junctions, genus=0)


def _parts_apart(parts: list, touching: list[tuple[int, int]], gap: float) -> bool:
    """Whether every pair of parts not allowed to touch keeps ``gap`` between their surfaces (checked along skeletons)."""
    allowed = set(touching) | {(j, i) for i, j in touching}
    for j, other in enumerate(parts):
        points, radii = other.skeleton()
        for i, part in enumerate(parts):
            if i != j and (i, j) not in allowed and (part.distance(points) < radii + gap).any():
                return False
    return True


# ---------------------------------------------------------------- vessel
def _vessel(rng: np.random.Generator) -> Shape | None:
    """Draw a profile and one or two handles; None when a handle would be too short or cut into the opening."""
    from scipy.interpolate import PchipInterpolator

    lab = {name: i for i, name in enumerate(LABEL_NAMES["vessel"])}
    uniform = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731

    height = uniform(1.6, 2.2)
    foot_top = uniform(0.06, 0.12) * height
    body_max = foot_top + uniform(0.2, 0.35) * height
    neck_low = uniform(0.6, 0.7) * height
    lip_low = uniform(0.85, 0.92) * height
    r_body = uniform(0.45, 0.7)
    r_neck = uniform(0.35, 0.55) * r_body
    r_foot = uniform(0.5, 0.8) * r_body
    r_lip = r_neck * uniform(1.15, 1.5)
    knots_z = [0.0, foot_top, body_max, 0.5 * (body_max + neck_low), neck_low, 0.5 * (neck_low + lip_low), lip_low, height]
    knots_r = [r_foot, uniform(0.7, 0.9) * r_foot, r_body, uniform(0.7, 0.9) * r_body, r_neck * uniform(1.0, 1.1), r_neck,
               r_neck * uniform(0.95, 1.05), r_lip]  # fmt: skip
    radius_at = PchipInterpolator(knots_z, knots_r)

    # handles: tubes along curves from the upper body to the neck, bulging outwards
    tube = min(uniform(0.07, 0.095), 0.4 * r_neck)
    z1 = uniform(body_max, 0.5 * (body_max + neck_low) + 0.05)
    z2 = uniform(neck_low + 0.05, lip_low - 0.05)
    n_handles = int(rng.integers(1, 3))
    first_angle = uniform(0, 2 * np.pi)
    if z2 - z1 < 5.0 * tube:  # the hole would be too small
        return None

    # profile: flat bottom, rounded base rim, outer wall, a round lip of radius lip_r, then the
    # opening: a round-bottomed cup with a wall of 2 lip_r that stops above the handle roots
    lip_r = min(uniform(0.06, 0.09), 0.3 * r_neck)
    rim = height - lip_r
    cup_bottom = max(rim - uniform(0.1, 0.25) * height, z2 + 2.0 * tube)
    if cup_bottom > rim - 0.05:
        return None
    corner = 0.06
    z = np.linspace(corner, rim, 60)
    outer = np.stack([radius_at(z), z], axis=1)
    base_angles = np.linspace(-np.pi / 2, 0.0, 8)[:-1]
    base = np.array([radius_at(corner) - corner, corner]) + corner * np.stack([np.cos(base_angles), np.sin(base_angles)], axis=1)
    lip_angles = np.linspace(0.0, np.pi, 11)[1:]
    lip = np.array([radius_at(rim) - lip_r, rim]) + lip_r * np.stack([np.cos(lip_angles), np.sin(lip_angles)], axis=1)
    t = np.linspace(0.0, 1.0, 25)[1:]
    cup_z = rim - (rim - cup_bottom) * t
    cup = np.stack([(radius_at(cup_z) - 2 * lip_r) * np.sqrt(1 - t**4), cup_z], axis=1)
    profile = np.concatenate([[[0.0, 0.0]], base, outer, lip, cup])
    midpoint_z = 0.5 * (profile[:-1, 1] + profile[1:, 1])
    segment_labels = np.select(
        [midpoint_z < foot_top, midpoint_z < neck_low, midpoint_z < lip_low], [lab["base"], lab["body"], lab["neck"]], lab["lip"]
    )
    segment_labels[len(base) + len(outer) :] = lab["lip"]  # over the rim and into the opening
    profile, segment_labels = _resample(profile, segment_labels, spacing=0.01)
    parts = [Revolved(profile, segment_labels)]
    blends = []
    junctions = [Junction(np.array([0.0, 0.0, zj]), 0.08 * height, float(radius_at(zj))) for zj in (foot_top, neck_low, lip_low)]
    # not a junction, but a thin rounded feature that real models tessellate finely too
    junctions.append(Junction(np.array([0.0, 0.0, rim]), 2.5 * lip_r, float(radius_at(rim)) - lip_r))

    # a handle leaves the body and enters the neck along the wall's normal (square to the axis
    # on the neck, so it cannot reach the opening) and sweeps out far enough to clear the wall
    root_depth = 1.5 * tube
    roots = np.array([[float(radius_at(z)) - root_depth, z] for z in (z1, z2)])
    slopes = radius_at.derivative()([z1, z2])
    normals = unit(np.stack([np.ones(2), -slopes], axis=1))
    between = np.linspace(z1, z2, 20)
    bulge = max((radius_at(between) - np.interp(between, [z1, z2], roots[:, 0])).max(), 0.0)
    # a cubic Bezier curve reaches about 3/4 of the way to its middle control points
    reach_out = (bulge + 2.5 * tube + uniform(0.08, 0.25)) / 0.75
    controls = np.array([roots[0], roots[0] + reach_out * normals[0], roots[1] + reach_out * normals[1], roots[1]])
    t = np.linspace(0.0, 1.0, 17)[:, None]
    bernstein = np.concatenate([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t**2, t**3], axis=1)
    curve = bernstein @ controls
    for turn in first_angle + np.pi * np.arange(n_handles):
        outward = np.array([np.cos(turn), np.sin(turn), 0.0])
        path = curve[:, :1] * outward + curve[:, 1:] * np.array([0.0, 0.0, 1.0])
        parts.append(TubePath(path, tube, lab["handle"]))
        blends.append(0.6 * tube)
        junctions += [Junction(path[i] + root_depth * outward, 3.0 * tube) for i in (0, -1)]
    return Shape(parts, blends, junctions, genus=n_handles)


def _resample(polyline: np.ndarray, segment_labels: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Split every segment into pieces no longer than ``spacing``, keeping their labels."""
    lengths = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
    pieces = np.maximum(np.ceil(lengths / spacing).astype(int), 1)
    t = np.concatenate([np.arange(n) / n for n in pieces])
    start = np.repeat(np.arange(len(pieces)), pieces)
    points = polyline[start] + t[:, None] * (polyline[start + 1] - polyline[start])
    return np.concatenate([points, polyline[-1:]]), segment_labels[start]


_BUILDERS = {"figure": _figure, "vessel": _vessel}


# ---------------------------------------------------------------- meshing
def _junction_weights(points: np.ndarray, junctions: list[Junction]) -> tuple[np.ndarray, np.ndarray]:
    """For each junction, the offset of every point from it (J, N, 3) and a Gaussian weight of that offset (J, N)."""
    offsets = np.stack([points - junction.nearest(points) for junction in junctions])
    reach = np.array([junction.reach for junction in junctions])[:, None]
    return offsets, np.exp(-(offsets * offsets).sum(axis=-1) / reach**2)


def _contract(points: np.ndarray, junctions: list[Junction]) -> np.ndarray:
    """Pull points towards the junctions, so that a regular grid so mapped has cells _REFINE times finer at a junction.

    A single junction's map is one-to-one (its pull is below 1).
    """
    offsets, weights = _junction_weights(points, junctions)
    return points - _PULL * (weights[..., None] * offsets).sum(axis=0)


def _edge_density(points: np.ndarray, junctions: list[Junction]) -> np.ndarray:
    """Edges per unit length that the contracted grid gives, relative to far from every junction (_REFINE at a junction)."""
    return 1.0 / (1.0 - _PULL * np.minimum(_junction_weights(points, junctions)[1].sum(axis=0), 1.0))


def _refined_area(shape: Shape, lower: np.ndarray, upper: np.ndarray, n: int = 32) -> float:
    """The surface integral of the squared edge density: the area in units of far-field cells.

    Measured on a coarse grid as the volume of a thin shell about the zero set over its thickness.
    """
    axes = [np.linspace(lo, hi, n) for lo, hi in zip(lower, upper)]
    spacing = (upper - lower) / (n - 1)
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    thickness = float(spacing.mean())
    shell = points[np.abs(shape.field(points)) < 0.5 * thickness]
    return float((_edge_density(shell, shape.junctions) ** 2).sum() * np.prod(spacing) / thickness)


def _largest_component(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rows, cols = np.r_[faces[:, 0], faces[:, 0]], np.r_[faces[:, 1], faces[:, 2]]
    _, component = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_vertices,) * 2), directed=False)
    face_component = component[faces[:, 0]]
    return faces[face_component == np.bincount(face_component).argmax()]


def _project(shape: Shape, points: np.ndarray) -> np.ndarray:
    """One Newton step of each point onto the zero set, along the field's (finite-difference) gradient."""
    step = 1e-5
    value = shape.field(points)
    gradient = np.stack([(shape.field(points + offset) - value) / step for offset in np.eye(3) * step], axis=1)
    return points - (value / np.maximum((gradient * gradient).sum(axis=1), 1e-12))[:, None] * gradient


def _relax(mesh: Mesh, shape: Shape, steps: int) -> Mesh:
    """Even out the marching-cubes slivers while keeping the junction refinement.

    Each step moves every vertex, in its tangent plane, towards the average of
    its neighbours weighted by the squared target edge density (so that edges
    tend to the local target length rather than to one length), then projects
    it back onto the surface.
    """
    from scipy.sparse import coo_matrix

    edges = mesh.edges
    rows, cols = np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]]
    incidence = coo_matrix((np.ones(3 * mesh.n_faces), (mesh.faces.ravel(), np.repeat(np.arange(mesh.n_faces), 3)))).tocsr()
    vertices = mesh.vertices
    for _ in range(steps):
        density = _edge_density(vertices, shape.junctions)
        weights = coo_matrix((density[rows] * density[cols], (rows, cols)), shape=(len(vertices),) * 2).tocsr()
        move = (weights @ vertices) / np.asarray(weights.sum(axis=1)) - vertices
        normals = unit(incidence @ Mesh(vertices, mesh.faces).face_normals + 1e-12)
        move -= (move * normals).sum(axis=1, keepdims=True) * normals
        vertices = _project(shape, vertices + _RELAX_RATE * move)
    return Mesh(vertices, mesh.faces)


def _mesh_shape(shape: Shape, n_faces: int) -> Mesh:
    """Marching cubes on a grid contracted about the junctions, sized for about ``n_faces`` away from them; then relaxed."""
    import igl

    lower, upper = shape.bounds()
    cell = np.sqrt(_FACES_PER_CELL * _refined_area(shape, lower, upper) / n_faces)
    # the contraction moves grid points by less than 0.43 reach per junction: pad so that the surface stays inside
    pad = 3 * cell + max(junction.reach for junction in shape.junctions)
    counts = np.ceil((upper - lower + 2 * pad) / cell).astype(int) + 1
    axes = [lo - pad + np.arange(n) * cell for lo, n in zip(lower, counts)]
    zz, yy, xx = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")  # x fastest, as libigl wants
    grid = _contract(np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1), shape.junctions)
    values = shape.field(grid)
    # a grid value of exactly zero would make coincident vertices
    values[np.abs(values) < 1e-9 * cell] = 1e-9 * cell
    vertices, faces, _ = igl.marching_cubes(values, grid, int(counts[0]), int(counts[1]), int(counts[2]), 0.0)
    mesh, _ = repair(Mesh(vertices, _largest_component(faces, len(vertices))), drop_slivers=True)
    mesh = _relax(mesh, shape, _RELAX_STEPS)
    if _signed_volume(mesh) < 0:
        mesh = Mesh(mesh.vertices, mesh.faces[:, ::-1])
    return mesh


def _signed_volume(mesh: Mesh) -> float:
    v = mesh.vertices[mesh.faces]
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)


def _problem(mesh: Mesh, labels: np.ndarray, shape: Shape, n_labels: int) -> str | None:
    """Why a generated mesh is unusable, or None."""
    try:
        mesh.validate()
    except MeshError as exc:
        return str(exc)
    if mesh.boundary_loop_count:
        return f"{mesh.boundary_loop_count} boundary loops"
    if mesh.euler_characteristic != 2 - 2 * shape.genus:
        return f"Euler characteristic {mesh.euler_characteristic}, expected {2 - 2 * shape.genus}"
    if len(np.unique(labels)) != n_labels:
        return f"only {len(np.unique(labels))} of {n_labels} labels present"
    return None


# ---------------------------------------------------------------- public API
def generate(category: str, index: int, seed: int = DEFAULT_SEED) -> LabeledMesh:
    """Shape ``index`` of ``category`` for ``seed``: a closed manifold labelled mesh named like ``figure_007``."""
    if category not in CATEGORIES:
        raise DatasetError(f"unknown synthetic category {category!r}; valid: {', '.join(CATEGORIES)}")
    if index < 0:
        raise DatasetError(f"shape index must be non-negative, got {index}")
    rng = np.random.default_rng([seed, CATEGORIES.index(category), index])
    names = LABEL_NAMES[category]
    problem = "no shape drawn"
    for _ in range(_MAX_DRAWS):
        n_faces = int(rng.integers(FACE_RANGE[0], FACE_RANGE[1] + 1))
        shape = _BUILDERS[category](rng)
        if shape is None:
            continue
        mesh = _mesh_shape(shape, n_faces)
        labels = shape.labels(mesh.face_centroids)
        problem = _problem(mesh, labels, shape, len(names))
        if problem is None:
            return LabeledMesh(mesh, labels, list(names), f"{category}_{index:03d}")
    raise SyntheticShapeError(f"{category} {index} (seed {seed}): no valid shape in {_MAX_DRAWS} draws; last problem: {problem}")


def split_indices(n_shapes: int, split: str, split_index: int) -> list[int]:
    """The shape indices of ``split`` ("train", "test" or "all") in fixed split ``split_index`` (0..N_SPLITS-1)."""
    if split not in SPLITS:
        raise DatasetError(f"unknown split {split!r}; valid splits: {', '.join(SPLITS)}")
    if not 0 <= split_index < N_SPLITS:
        raise DatasetError(f"synthetic split_index must be in 0..{N_SPLITS - 1}, got {split_index}")
    if n_shapes < N_SPLITS:
        raise DatasetError(f"n_shapes must be at least {N_SPLITS} (one test shape per split), got {n_shapes}")
    everything = range(n_shapes)
    if split == "all":
        return list(everything)
    return [i for i in everything if (i % N_SPLITS == split_index) == (split == "test")]


def load(
    category: str | None = None,
    split: str = "train",
    split_index: int = 0,
    root=None,
    n_shapes: int = N_SHAPES,
    seed: int = DEFAULT_SEED,
    progress: bool = True,
) -> list[LabeledMesh]:
    """The synthetic shapes of ``category`` (None: every category) in ``split`` of fixed split ``split_index``.

    ``n_shapes`` shapes per category are split into train and test; ``seed``
    picks another family of shapes. ``root`` is accepted for a uniform call
    and ignored: nothing is read from disk. See the module docstring for the
    shapes, labels, seeds and splits.
    """
    categories = CATEGORIES if category is None else (category,)
    for name in categories:
        if name not in CATEGORIES:
            raise DatasetError(f"unknown synthetic category {name!r}; valid: {', '.join(CATEGORIES)}")
    indices = split_indices(n_shapes, split, split_index)
    jobs = [(name, i) for name in categories for i in indices]
    return [generate(name, i, seed) for name, i in progress_bar(jobs, f"synthetic {category or 'all'} {split}", progress)]
