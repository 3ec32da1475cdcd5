"""Per-face descriptors (Algorithm 1, line 1; section III-A) and their on-disk cache.

Every group is computed on a copy of the mesh scaled to unit total area and centred
(:meth:`Mesh.unit_area`), so all are scale invariant, and all are rotation invariant (the SDF
rays are laid out in each face's own frame). Nothing is random, so results are deterministic.
Groups (columns: :func:`feature_names`; each group function's docstring gives its formulas):
``edge`` the paper's edge-encoded vector of the three lengths; ``angles`` the sorted inner angles;
``ratios`` the sorted lengths' ratios; ``gc`` Gaussian curvature, signed-log and signed rank;
``sdf`` the Shape Diameter Function (:mod:`anseg.geometry.sdf`); ``agd`` the Average Geodesic
Distance (:mod:`anseg.geometry.geodesic`); optional ``smooth``, those three diffused at a few
radii (:mod:`anseg.geometry.diffusion`) so a face sees its wide neighbourhood; optional ``hks``,
the Heat Kernel Signature at fixed times, which says where a face sits on the whole shape.

No per-mesh z-score: absolute values on the unit-area mesh say how thick, curved or far out a face is
relative to its whole shape, which compares across a category's meshes; each shape descriptor also has
a per-mesh relative column, robust to other proportions. Standardising is the model's job (training set).

Meshes above :data:`anseg.geometry.proxy.LARGE_MESH_FACES` faces (scans, CAD; no benchmark mesh)
take faster paths: embree casts the SDF rays, and the AGD, the HKS and the ``smooth`` diffusion
are computed on one uniform collapse of the mesh (:class:`_Geometry`), keyed apart in the cache.
:data:`LOCAL_GROUPS` are cheap and recomputed on every coarse mesh; :data:`GLOBAL_GROUPS` describe
the original shape and are pooled from its faces on coarse levels. Measurements: ``docs/decisions.md``.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, fields
from functools import cached_property
from pathlib import Path

import numpy as np

from anseg import kernels
from anseg.cache import (
    atomic_write,
    cache_dir,
    library_versions,
    read_checked_array,
    write_checked_array,
)
from anseg.geometry import diffusion, geodesic, proxy, rays, sdf
from anseg.geometry.spectral import (
    SPECTRUM_PAIRS,
    SPECTRUM_VERSION,
    laplacian_eigenpairs,
)
from anseg.mesh import Mesh, MeshError
from anseg.parallel import run_parallel
from anseg.progress import progress as progress_bar

FEATURES_VERSION = 2  # the feature code as a whole; stored keys and model files name it (see :func:`code`)
# Version 2 added the stray-piece rule alone (:attr:`anseg.mesh.Mesh.stray_faces`: a speck or a far facet sets no
# scale or range of the rest), which computes a mesh without stray pieces bit for bit as version 1 did. No mesh of
# the benchmark data sets has one (tests/test_datasets.py), so the results and models of version 1 stand for
# version 2 (:func:`comparable`): the same keys, the same models.
SAME_WITHOUT_STRAYS = (1, 2)

GROUPS = ("edge", "angles", "ratios", "gc", "sdf", "agd", "smooth", "hks")
# Each group's version: raise it whenever the group's output on a fixed mesh changes, however little
# (tests/test_feature_versions.py holds the digest of each group's output and fails until both agree).
GROUP_VERSIONS = {"edge": 1, "angles": 1, "ratios": 1, "gc": 1, "sdf": 1, "agd": 1, "smooth": 1, "hks": 1}
DEFAULT_GROUPS = ("edge", "angles", "ratios", "gc", "sdf", "agd")
LOCAL_GROUPS = ("edge", "angles", "ratios", "gc")
GLOBAL_GROUPS = ("sdf", "agd", "smooth", "hks")
HKS_EIGENPAIRS = SPECTRUM_PAIRS  # one eigensolve serves the HKS and the network's spectrum
HKS_TIMES = (0.002, 0.004, 0.008, 0.016, 0.032, 0.064, 0.128, 0.256)  # unit-area mesh: 1/lambda_64 .. beyond 1/lambda_1
# The paper's Fig. 12 feature sets.
ABLATION_SETS = {
    "edge": ("edge",),
    "edge+gc": ("edge", "gc"),
    "edge+gc+sdf": ("edge", "gc", "sdf"),
    "edge+gc+sdf+agd": ("edge", "gc", "sdf", "agd"),
}

_FIXED_COLUMNS = {
    "edge": ("edge_sum", "edge_pair_sum", "edge_product"),
    "angles": ("angle_min", "angle_mid", "angle_max"),
    "ratios": ("ratio_min_mid", "ratio_mid_max", "ratio_min_max"),
    "gc": ("gc_slog", "gc_rank"),
    "sdf": ("sdf", "sdf_lognorm"),
    "agd": ("agd", "agd_rel"),
}
_SMOOTHED = ("sdf", "gc_slog", "agd")

# |angle defect| below this (radians) counts as flat: keeps round-off from deciding signed ranks
_FLAT_DEFECT = 1e-9
PROGRESS_MIN_FACES = 100_000  # a single mesh shows a progress bar from this size (tens of seconds of work)
POOL_MIN_FACES = 50_000  # compute_many works in-process below this many faces in all (about a second of work)


def _threads_allowed() -> int:
    """How many threads this process may compute with: numba's count, which parallel workers set to 1."""
    return max(1, rays.numba_threads())


@dataclass(frozen=True)
class FeatureSettings:
    """Knobs of the descriptors; ``compute(..., **settings)`` takes these names.

    The ray and source counts trade accuracy against time: the defaults keep
    the SDF and the AGD close to a dense reference at a fraction of its cost
    (``benchmarks/features.py --studies``; the figures: ``docs/decisions.md``).
    """

    sdf_rays: int = 16
    sdf_cone_degrees: float = 120.0
    agd_sources: int = 64
    smooth_radii: tuple[float, ...] = (0.03, 0.1, 0.3)

    def __post_init__(self):
        if not (isinstance(self.sdf_rays, int) and self.sdf_rays >= 1):
            raise ValueError(f"sdf_rays must be a positive integer, got {self.sdf_rays!r}")
        if not 0.0 < self.sdf_cone_degrees < 180.0:
            raise ValueError(f"sdf_cone_degrees must lie in (0, 180), got {self.sdf_cone_degrees!r}")
        if not (isinstance(self.agd_sources, int) and self.agd_sources >= 1):
            raise ValueError(f"agd_sources must be a positive integer, got {self.agd_sources!r}")
        radii = tuple(float(r) for r in self.smooth_radii)
        if not radii or min(radii) <= 0:
            raise ValueError(f"smooth_radii must be a non-empty tuple of positive radii, got {self.smooth_radii!r}")
        object.__setattr__(self, "smooth_radii", radii)


def _settings(settings: dict) -> FeatureSettings:
    valid = [f.name for f in fields(FeatureSettings)]
    unknown = sorted(set(settings) - set(valid))
    if unknown:
        raise ValueError(f"unknown feature settings {unknown}; valid ones: {valid}")
    return FeatureSettings(**settings)


def _check_groups(groups) -> tuple[str, ...]:
    groups = (groups,) if isinstance(groups, str) else tuple(groups)
    if not groups:
        raise ValueError(f"no feature groups given; valid ones: {list(GROUPS)}")
    unknown = [g for g in groups if g not in GROUPS]
    if unknown:
        raise ValueError(f"unknown feature groups {unknown}; valid ones: {list(GROUPS)} (ablation sets: ABLATION_SETS)")
    if len(set(groups)) != len(groups):
        raise ValueError(f"feature groups repeat: {list(groups)}")
    return groups


def _group_columns(group: str, settings: FeatureSettings) -> tuple[str, ...]:
    if group == "smooth":
        return tuple(f"smooth_{name}_r{r:g}" for name in _SMOOTHED for r in settings.smooth_radii)
    if group == "hks":
        return tuple(f"hks_t{t:g}" for t in HKS_TIMES)
    return _FIXED_COLUMNS[group]


def feature_names(groups: Sequence[str] = DEFAULT_GROUPS, **settings) -> list[str]:
    """Column names of ``compute(mesh, groups, **settings)``, in order."""
    cfg = _settings(settings)
    return [name for g in _check_groups(groups) for name in _group_columns(g, cfg)]


# ---------------------------------------------------------------- geometry
class _Geometry:
    """The unit-area, centred mesh and the quantities several groups share, each computed once."""

    def __init__(self, mesh: Mesh, settings: FeatureSettings):
        self.mesh = mesh.unit_area()
        self.settings = settings
        # the faces that set each descriptor's range: all of them, or those of the mesh without its stray pieces
        self.shape = None if self.mesh.stray_faces is None else ~self.mesh.stray_faces

    @cached_property
    def edge_vectors(self) -> np.ndarray:
        """(F, 3, 3): local edge k runs from corner k to corner k+1."""
        v = self.mesh.vertices[self.mesh.faces]
        return np.roll(v, -1, axis=1) - v

    @cached_property
    def sorted_lengths(self) -> np.ndarray:
        return np.sort(np.linalg.norm(self.edge_vectors, axis=2), axis=1)

    @cached_property
    def corner_angles(self) -> np.ndarray:
        """(F, 3) inner angle at corner k, from atan2 (accurate for needles and flat corners)."""
        out_edge = self.edge_vectors
        in_edge = -np.roll(out_edge, 1, axis=1)
        sine = np.linalg.norm(np.cross(out_edge, in_edge), axis=2)
        cosine = (out_edge * in_edge).sum(axis=2)
        return np.arctan2(sine, cosine)

    @cached_property
    def outward_normals(self) -> np.ndarray:
        """Face normals flipped, if need be, so that the signed volume is positive (outward on closed meshes)."""
        m = self.mesh
        volume = (m.face_centroids * m.face_normals * m.frame_areas[:, None]).sum()
        return -m.face_normals if volume < 0 else m.face_normals

    @cached_property
    def face_gaussian_curvature(self) -> np.ndarray:
        import igl

        m = self.mesh
        defect = 2.0 * np.pi - np.bincount(m.faces.ravel(), self.corner_angles.ravel(), minlength=m.n_vertices)
        defect[np.abs(defect) < _FLAT_DEFECT] = 0.0
        area = igl.massmatrix(m.vertices, m.faces, igl.MASSMATRIX_TYPE_VORONOI).diagonal()
        curvature = defect / area
        interior = np.ones(m.n_vertices, dtype=bool)
        interior[m.edges[m.edge_face_counts == 1].ravel()] = False
        weight = interior[m.faces]
        total = (curvature[m.faces] * weight).sum(axis=1)
        count = weight.sum(axis=1)
        return np.divide(total, count, out=np.zeros(m.n_faces), where=count > 0)

    @cached_property
    def gc_slog(self) -> np.ndarray:
        k = self.face_gaussian_curvature
        return np.sign(k) * np.log1p(np.abs(k))

    @cached_property
    def longest_edge_directions(self) -> np.ndarray:
        """(F, 3) unit vector along each face's longest edge: an in-plane axis that rotates with the mesh."""
        lengths = np.linalg.norm(self.edge_vectors, axis=2)
        longest = self.edge_vectors[np.arange(self.mesh.n_faces), np.argmax(lengths, axis=1)]
        return longest / np.linalg.norm(longest, axis=1, keepdims=True)

    @cached_property
    def sdf(self) -> np.ndarray:
        return sdf.shape_diameter(self.mesh, self.outward_normals, self.longest_edge_directions, self.settings.sdf_rays,
                                  self.settings.sdf_cone_degrees, _threads_allowed())

    def sdf_with_agd_beside(self) -> None:
        """Compute ``sdf`` and ``agd`` at once, the AGD on a second thread while the SDF's rays are cast.

        The heat method's solves (potpourri3d) hold the GIL on one core and
        our ray caster releases it, so on two or more numba threads the two
        overlap. Only the cast overlaps: numpy work beside a thread that holds
        the GIL in long C++ calls would wait for it at every call. The values
        are the same either way; with one thread (parallel workers) or the
        large-mesh paths nothing changes.
        """
        if _threads_allowed() < 2 or self.mesh.n_faces > proxy.LARGE_MESH_FACES or {"sdf", "agd"} & self.__dict__.keys():
            return
        self.__dict__["sdf"] = sdf.shape_diameter(self.mesh, self.outward_normals, self.longest_edge_directions,
                                                  self.settings.sdf_rays, self.settings.sdf_cone_degrees,
                                                  _threads_allowed(), beside=lambda: self.agd)

    @cached_property
    def proxy(self) -> tuple["_Geometry", np.ndarray]:
        """The mesh's :func:`anseg.geometry.proxy.collapse_to_proxy`, and each input face's face on it.

        For meshes above :data:`anseg.geometry.proxy.LARGE_MESH_FACES` faces: the smooth
        global descriptors (``agd``, ``hks``, the ``smooth`` group's diffusion)
        are computed there, whose cost grows faster than the mesh.
        """
        coarse, face_of = proxy.collapse_to_proxy(self.mesh)
        return _Geometry(coarse, self.settings), face_of

    @cached_property
    def agd(self) -> np.ndarray:
        """Per-face AGD; above :data:`anseg.geometry.proxy.LARGE_MESH_FACES` faces, that of the face's face on the :attr:`proxy`.

        The heat method's factorisation grows faster than the mesh. AGD is
        smooth over the surface, and the heat method's own error scales with
        the edge length, so the values of a collapse to
        :data:`anseg.geometry.proxy.PROXY_FACES` faces are as close to those of
        the benchmark meshes the models learn from as the full mesh's, at a
        fraction of the time (measured: ``docs/decisions.md``).
        Meshes at or below the threshold are computed as they always were.
        """
        if self.mesh.n_faces > proxy.LARGE_MESH_FACES:
            coarse, face_of = self.proxy
            return coarse.agd[face_of]
        per_vertex = geodesic.average_geodesic_distance(self.mesh, self.settings.agd_sources)
        return per_vertex[self.mesh.faces].mean(axis=1)

    @cached_property
    def hks(self) -> np.ndarray:
        """Per-face HKS; above :data:`anseg.geometry.proxy.LARGE_MESH_FACES` faces, that of the face's face on the :attr:`proxy`.

        The shift-invert eigensolve factorises the Laplacian and its cost
        grows faster than the mesh, while the lowest :data:`HKS_EIGENPAIRS`
        eigenfunctions are smooth, so the proxy's columns follow the full
        mesh's, least closely at the shortest times (detail finer than a proxy
        face), for a much smaller eigensolve (measured: ``docs/decisions.md``).
        The AGD shares the proxy, so its collapse is paid once.
        """
        if self.mesh.n_faces > proxy.LARGE_MESH_FACES:
            coarse, face_of = self.proxy
            return coarse.hks[face_of]
        if self.shape is None:
            per_vertex = _heat_kernel_signature(self.mesh, HKS_EIGENPAIRS, np.array(HKS_TIMES))
            return per_vertex[self.mesh.faces].mean(axis=1)
        # the spectrum of the shape alone (a stray piece's own modes would enter the heat trace); stray faces take
        # the least value of each column, where the shape's heat leaves fastest
        shape, _ = self.mesh.submesh(self.shape)
        on_shape = _heat_kernel_signature(shape, HKS_EIGENPAIRS, np.array(HKS_TIMES))[shape.faces].mean(axis=1)
        out = np.empty((self.mesh.n_faces, on_shape.shape[1]))
        out[self.shape], out[~self.shape] = on_shape, on_shape.min(axis=0)
        return out


# ------------------------------------------------------------------- groups
def _edge(g: _Geometry) -> np.ndarray:
    """The paper's edge-encoded vector (a+b+c, ab+bc+ca, abc) of the three edge lengths.

    Unchanged when the edges are reordered. On the unit-area mesh lengths go
    as 1/sqrt(faces), so these also tell a coarse level from a fine one.
    """
    a, b, c = g.sorted_lengths.T
    return np.stack([a + b + c, a * b + b * c + c * a, a * b * c], axis=1)


def _angles(g: _Geometry) -> np.ndarray:
    """The three inner angles (radians), sorted ascending."""
    return np.sort(g.corner_angles, axis=1)


def _ratios(g: _Geometry) -> np.ndarray:
    """Edge-length ratios of the sorted lengths a <= b <= c: a/b, b/c, a/c."""
    a, b, c = g.sorted_lengths.T
    return np.stack([a / b, b / c, a / c], axis=1)


def _gc(g: _Geometry) -> np.ndarray:
    """Gaussian curvature K: angle defect over the mixed Voronoi vertex area, averaged over the face's interior vertices.

    A boundary vertex's defect is boundary turning, not curvature, so it is
    left out. Two transforms so that spikes do not dominate: ``gc_slog`` =
    sign(K) log(1 + |K|) and ``gc_rank``, the signed rank (positive K ranked
    among positives into (0, 1], negative among negatives into [-1, 0), flat
    faces 0).
    """
    return np.stack([g.gc_slog, _signed_rank(g.face_gaussian_curvature, g.shape)], axis=1)


def _sdf(g: _Geometry) -> np.ndarray:
    """Shape Diameter Function (Shapira et al. 2008; :mod:`anseg.geometry.sdf`).

    The cosine-weighted mean length of the rays cast from each face's
    centroid over a cone (``sdf_cone_degrees``) around the inward normal;
    normals are taken outward (flipped when the signed volume is negative).
    ``sdf`` is the absolute value, ``sdf_lognorm`` Shapira's log-normalisation
    log(1 + 4 s) / log 5 of the per-mesh robust (1st-99th percentile) min-max
    scaled value s (the percentiles of the shape's faces, :attr:`Mesh.stray_faces` apart).
    """
    s = g.sdf
    low, high = np.percentile(s if g.shape is None else s[g.shape], [1.0, 99.0])
    scaled = np.clip((s - low) / (high - low), 0.0, 1.0) if high > low else np.zeros_like(s)
    return np.stack([s, np.log1p(4.0 * scaled) / np.log(5.0)], axis=1)


def _agd(g: _Geometry) -> np.ndarray:
    """Average Geodesic Distance (:mod:`anseg.geometry.geodesic`): the area-weighted mean heat-method distance to the shape.

    ``agd`` is the absolute value, ``agd_rel`` = (agd - min) / (max - min) per
    mesh: 0 at the geodesic centre, 1 at the farthest extremity. The minimum
    and maximum are the shape's: a stray piece (:attr:`Mesh.stray_faces`) has a
    small AGD of its own, which would squeeze the shape's values into a corner
    of the range; its faces are clipped into the shape's range instead.
    """
    a = g.agd
    reference = a if g.shape is None else a[g.shape]
    span = reference.max() - reference.min()
    relative = (a - reference.min()) / span if span > 0 else np.zeros_like(a)
    if g.shape is not None:
        relative = np.clip(relative, 0.0, 1.0)
    return np.stack([a, relative], axis=1)


def _smooth(g: _Geometry) -> np.ndarray:
    """``sdf``, ``gc_slog`` and ``agd`` diffused over the surface at the geodesic radii ``smooth_radii``.

    Optional (not in :data:`DEFAULT_GROUPS`): a face sees its wide
    neighbourhood (:mod:`anseg.geometry.diffusion`).
    """
    signals = np.stack([g.sdf, g.gc_slog, g.agd], axis=1)
    if g.mesh.n_faces > proxy.LARGE_MESH_FACES:
        coarse, face_of = g.proxy
        per_radius = diffusion.diffuse_through_proxy(g.mesh, coarse.mesh, face_of, signals, g.settings.smooth_radii,
                                                     _threads_allowed())
    else:
        per_radius = diffusion.diffuse_on_faces(g.mesh, signals, g.settings.smooth_radii, _threads_allowed())
    # columns ordered signal-major, as _group_columns names them
    return np.stack(per_radius, axis=2).reshape(g.mesh.n_faces, -1)


def _hks(g: _Geometry) -> np.ndarray:
    """The Heat Kernel Signature (Sun, Ovsjanikov and Guibas 2009), optional.

    From the first :data:`HKS_EIGENPAIRS` eigenpairs of the cotan Laplacian
    (Voronoi masses) of the unit-area mesh, at the fixed diffusion times
    :data:`HKS_TIMES`, each divided by its heat trace (the mean over the
    surface of that time's signature) and logged: log(hks(x, t) / sum_i
    exp(-lambda_i t)). Intrinsic, so unchanged by the pose and by the
    inconsistent orientations of PSB, and it says where a face sits on the
    whole shape (a tip, a junction, a trunk), which local descriptors cannot.
    Fixed times on unit-area meshes make the columns comparable across meshes.
    """
    return g.hks


_GROUP_FUNCTIONS = {"edge": _edge, "angles": _angles, "ratios": _ratios, "gc": _gc, "sdf": _sdf, "agd": _agd,
                    "smooth": _smooth, "hks": _hks}


def _signed_rank(values: np.ndarray, shape: np.ndarray | None = None) -> np.ndarray:
    """``gc_rank`` (see :func:`_gc`); with a ``shape`` mask, ranks among the shape's faces, the others placed among them."""
    from scipy.stats import rankdata

    out = np.zeros(len(values))
    for sign in (1.0, -1.0):
        side = sign * values > 0
        ranked = np.flatnonzero(side if shape is None else side & shape)
        if len(ranked):
            out[ranked] = sign * rankdata(np.abs(values[ranked])) / len(ranked)
        if shape is not None and len(ranked):
            placed = np.flatnonzero(side & ~shape)
            out[placed] = sign * np.searchsorted(np.sort(np.abs(values[ranked])), np.abs(values[placed]), "right") / len(ranked)
    return out


def _heat_kernel_signature(mesh: Mesh, n_pairs: int, times: np.ndarray) -> np.ndarray:
    """(V, len(times)) log heat-trace-normalised HKS from the low end of the spectrum (see ``_hks``)."""
    values, vectors = laplacian_eigenpairs(mesh, n_pairs)
    decay = np.exp(-np.outer(values, times))  # (k, T)
    signature = (vectors**2) @ decay  # (V, T)
    total_area = mesh.face_areas.sum()
    return np.log(np.maximum(signature * total_area / decay.sum(axis=0), 1e-12))


# ------------------------------------------------------------------ public
def code() -> dict:
    """What decides the features beside the mesh: the code's version, the default settings and any raised group version.

    Experiment keys and model files carry it, so that no stored result or model
    is reused on other features. A group at version 1 stays out, so the keys
    of results stored before group versions existed are unchanged.
    """
    raised = {f"{group}_version": v for group, v in GROUP_VERSIONS.items() if v != 1}
    return {"version": FEATURES_VERSION, **asdict(FeatureSettings()), **raised}


def comparable(code: dict) -> dict:
    """``code`` as :func:`code` or a model file records it (its version under ``version`` or ``features``), with a
    version of :data:`SAME_WITHOUT_STRAYS` written as the last of them: what decides whether stored work stands for
    today's."""
    last = SAME_WITHOUT_STRAYS[-1]
    return {k: last if k in ("version", "features") and v in SAME_WITHOUT_STRAYS else v for k, v in code.items()}


def fingerprint(settings: FeatureSettings | None = None) -> str:
    """A short hash of everything that computes the features: every group's version, the settings, the
    eigenbasis's version, the numeric libraries' releases and their kernels (:func:`anseg.kernels.feature_kernels`:
    NumPy's AVX-512 loops give the Gaussian curvature other last bits than its AVX2 ones).

    It keys the cache (a cache filled by other code is never read) and every
    stored run names it (``environment()["features"]``), so a result says which
    features it was trained and scored on.
    """
    text = json.dumps({"features": FEATURES_VERSION, "groups": GROUP_VERSIONS, "spectrum": SPECTRUM_VERSION,
                       "settings": asdict(settings or FeatureSettings()), "libraries": library_versions(),
                       **kernels.feature_kernels()},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def compute_groups(mesh: Mesh, groups: Sequence[str] = DEFAULT_GROUPS, cache: bool = False, progress: bool = False,
                   **settings) -> dict[str, np.ndarray]:
    """Each requested group's (F, d) float32 block, by name, in the order asked.

    With ``cache=True`` the blocks come from the disk cache when it holds them
    (one entry per mesh and set of groups, as :func:`compute` keeps it) and go
    into it when computed; the default recomputes (what coarse, throw-away
    meshes want). ``progress`` shows a bar, group by group, for a mesh of at
    least :data:`PROGRESS_MIN_FACES` faces when stderr is a terminal.
    Raises MeshError for a mesh that fails ``validate()`` (or, should it
    happen, whose features come out non-finite) and ValueError for unknown
    groups or settings.
    """
    groups = _check_groups(groups)
    cfg = _settings(settings)
    mesh.validate()
    widths = [len(_group_columns(g, cfg)) for g in groups]
    path = _cache_path(mesh, groups, cfg) if cache else None
    matrix = read_checked_array(path, (mesh.n_faces, sum(widths))) if path is not None else None
    if matrix is not None:
        return dict(zip(groups, np.split(matrix, np.cumsum(widths)[:-1], axis=1)))
    geometry = _Geometry(mesh, cfg)
    # a bar, group by group, only where it is worth watching: a large mesh, and stderr a terminal (tqdm's None)
    show = None if progress and mesh.n_faces >= PROGRESS_MIN_FACES else False
    if all(name in groups or "smooth" in groups for name in ("sdf", "agd")):
        geometry.sdf_with_agd_beside()
    blocks = {g: np.ascontiguousarray(_GROUP_FUNCTIONS[g](geometry), dtype=np.float32)
              for g in progress_bar(groups, show=show, desc="features", unit="group", leave=False)}
    bad = [g for g, block in blocks.items() if not np.isfinite(block).all()]
    if bad:
        raise MeshError(f"feature groups {bad} came out non-finite for {mesh!r}; please report the mesh")
    if path is not None:
        matrix = np.concatenate(list(blocks.values()), axis=1)
        atomic_write(path, lambda tmp: write_checked_array(tmp, matrix))
    return blocks


def compute(mesh: Mesh, groups: Sequence[str] = DEFAULT_GROUPS, cache: bool = True, progress: bool = False,
            **settings) -> np.ndarray:
    """(F, D) float32 per-face features, the groups' columns side by side (:func:`feature_names`).

    Cached on disk under ``cache_dir("features")``, keyed by the mesh arrays,
    the groups and the :func:`fingerprint` of the code and settings; a damaged entry is
    reported (RuntimeWarning), removed and recomputed. ``cache=False``
    neither reads nor writes the cache. Settings are the fields of
    :class:`FeatureSettings`; errors as in :func:`compute_groups`.
    """
    return np.concatenate(list(compute_groups(mesh, groups, cache, progress, **settings).values()), axis=1)


def compute_many(
    meshes: Iterable[Mesh],
    groups: Sequence[str] = DEFAULT_GROUPS,
    workers: int | None = None,
    progress: bool = True,
    cache: bool = True,
    **settings,
) -> list[np.ndarray]:
    """:func:`compute` for many meshes, in input order, over a pool of processes.

    ``workers=None`` picks min(cpu_count, meshes to compute), or this
    process alone when they total under ``POOL_MIN_FACES`` faces (starting
    a worker costs seconds of imports); 1 always runs here, 2 or more always
    use a pool. Cached meshes are read here without starting workers.
    The pool is :func:`anseg.parallel.run_parallel`'s, so a plain script
    needs no ``if __name__ == "__main__":`` guard.
    """
    meshes = list(meshes)
    groups = _check_groups(groups)
    cfg = _settings(settings)
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    width = len(feature_names(groups, **settings))
    results: list[np.ndarray | None] = [None] * len(meshes)
    todo = []
    for i, mesh in enumerate(meshes):
        mesh.validate()
        if cache:
            results[i] = read_checked_array(_cache_path(mesh, groups, cfg), (mesh.n_faces, width))
        if results[i] is None:
            todo.append(i)
    if workers is None:
        small = sum(meshes[i].n_faces for i in todo) < POOL_MIN_FACES
        workers = 1 if small else min(os.cpu_count() or 1, len(todo))
    calls = [(_compute_arrays, (meshes[i].vertices, meshes[i].faces, groups, cache, settings)) for i in todo]
    with progress_bar(total=len(meshes), initial=len(meshes) - len(todo), desc="features", show=progress) as bar:
        for index, matrix in run_parallel(calls, workers):
            if isinstance(matrix, Exception):
                raise matrix
            results[todo[index]] = matrix
            bar.update()
    return results


def _compute_arrays(vertices, faces, groups, cache, settings) -> np.ndarray:
    """Worker entry point: plain arrays travel better than a Mesh with its cached tables."""
    return compute(Mesh(vertices, faces), groups, cache=cache, **settings)


# -------------------------------------------------------------------- cache
def _cache_path(mesh: Mesh, groups: tuple[str, ...], settings: FeatureSettings) -> Path:
    digest = hashlib.sha256(f"anseg-features {fingerprint(settings)}|{groups}|".encode())
    if mesh.n_faces > proxy.LARGE_MESH_FACES:  # the large-mesh paths compute otherwise than before they existed
        digest.update(f"large mesh: embree sdf, agd, hks and smooth proxy {proxy.PROXY_FACES}|".encode())
    digest.update(f"{mesh.vertices.shape}{mesh.faces.shape}".encode())
    digest.update(mesh.vertices.tobytes())
    digest.update(mesh.faces.tobytes())
    return cache_dir("features") / f"{digest.hexdigest()}.npy"
