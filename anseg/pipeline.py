"""Algorithm 1 end to end: features -> N x (cluster, attend, collapse) -> classify -> upsample -> smooth.

``build_levels`` runs the downsampling units and keeps every level (mesh, features, patch
layout, attention, collapse record) for training and the figures; ``segment`` adds the
classification, the upsampling through the collapse records and the graph cut. Choices:

* Coarse levels recompute the local groups and pool the global ones, area-weighted, from the
  faces each coarse face stands for; a last column (level / cycles) tells the one shared
  network how coarse its input is. Features are standardised with statistics stored in the
  model (from the training meshes), so a mesh reads the same at training and test time.
* Groups: the paper's plus the wide-neighbourhood ``smooth`` and ``hks``; every default of :class:`SegmentConfig`
  and :class:`~anseg.train.TrainConfig` comes from cross-validation on training meshes (:mod:`anseg.study.validate`).
* ``combine``: ``"all"`` (default) averages the class probabilities of every level carried up
  to the input faces, keeping the coarse levels' context and the fine level's detail; the
  paper's ``"coarsest"`` lets one heavily collapsed face mislabel every input face it stands
  for. ``"decay"`` weighs level i by 2^-i, so the input level keeps half the vote; ``"finest"``
  takes the input level alone.
* ``local_scale``: on the unit-area mesh the ``edge`` values grow as levels coarsen, far outside
  the level-0 statistics. ``"relative"`` (default) reads them against the level's median edge
  length l (log(e_k / l^k) / k), so a giant face shows as a few units, not thousands;
  ``"unit_area"`` keeps the cached values (the paper's reading and ``v1``).
* **Large meshes**: the network reads about :data:`NETWORK_FACES` faces at most, about the largest
  benchmark mesh the models learn from. A larger mesh (a scan, a subdivided model) is first
  collapsed uniformly (shortest edge first) to that many faces and segmented there, features
  and all; its class probabilities come back to every input face through that collapse's record
  (the vote of :func:`anseg.collapse.upsample`, as between levels) and the graph cut runs on the
  input mesh, so that boundaries follow its edges. Every stage then grows with the faces no faster
  than the collapse, the carrying back and the graph cut, which are near linear, where the
  network's global attention over the input level's tokens grows with their square. Meshes at or
  below the limit (every benchmark mesh) are segmented exactly as before.
Measured gains behind these choices: ``docs/decisions.md``; the large meshes' times and labels: ``docs/usage.md``.
"""

from __future__ import annotations

import math
import os
import pickle
import warnings
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import torch

from anseg import collapse, features
from anseg.cache import atomic_write
from anseg.cluster import FRAMES, PatchLayout, canonical_mesh, layout
from anseg.geometry import proxy, spectral
from anseg.geometry.gradient import face_gradient
from anseg.graphcut import DEFAULT_CONCAVE_DISCOUNT
from anseg.graphcut import smooth as graph_cut
from anseg.hierarchy import Hierarchy, Level, pool
from anseg.mesh import Mesh
from anseg.model import AttentionSegmenter, Output, SpectralInput, model_config
from anseg.progress import progress as progress_bar
from anseg.refine import Refiner

# how Algorithm 1 downsamples: attentive, uniform, or not at all (the input mesh classified directly)
DOWNSAMPLING_MODES = ("nonuniform", "uniform", "none")
COMBINE = ("coarsest", "all", "decay", "finest")
LOCAL_SCALES = ("unit_area", "relative")
PASS_SEED_STEP = 1000  # pass p of a test-time ensemble segments with seed + p * this (a collapse uses seed + level)
# the most faces the network reads (module docstring): at the large-mesh threshold of the features, above every benchmark mesh
NETWORK_FACES = proxy.LARGE_MESH_FACES
# SegmentConfig's settings that came after model files and results were written, with the value those ran with: a
# file or record that lacks one ran with that value, whatever today's default is.
SEGMENT_SETTINGS_ADDED_LATER = {"once_per_pass": False, "local_scale": "unit_area", "priority": "score",
                                "density_range": float("inf"), "concave_discount": 3.0,
                                "passes": 1, "layout_frame": "xyz", "canonical": False}


@dataclass
class SegmentConfig:
    """The switches of Algorithm 1 (the paper's 4 cycles at ratio 0.5), at the validated defaults.

    :mod:`anseg.configs` names the older readings: ``paper`` and ``v1`` (the
    defaults before validation, kept for the record).

    ``once_per_pass`` is passed to :func:`anseg.collapse.downsample` (off by
    default, as in the committed results), and so is ``priority`` (the
    paper's ``"score"`` order, or ``"weighted"`` decimation, whose weights
    :func:`collapse_weights` clips to ``density_range``); ``combine`` and
    ``local_scale`` are read in the module docstring; ``smooth_weight`` and
    ``concave_discount`` are the graph cut's (:mod:`anseg.graphcut`).
    ``passes`` > 1 segments the mesh that many times, each pass with other
    K-means starts and collapse seeds (so other tokens and another
    hierarchy), and averages their class probabilities before the graph cut:
    a test-time ensemble of one trained model, at a pass's cost each.
    ``layout_frame`` is the frame of the token order (:func:`anseg.cluster.layout`):
    the coordinates as given, the surface's principal axes, which do not
    depend on the pose or on the file's face order, or a rotation drawn from
    ``seed`` (each pass of ``passes`` then orders the tokens in another frame).
    ``canonical`` segments the mesh in :func:`anseg.cluster.canonical_mesh`
    (a pose and an order of vertices, faces and corners fixed by the
    surface), so that neither the mesh's placement nor the file's order nor
    the faces' orientation can change a label; the returned levels are then
    the canonical mesh's, their coordinates turned back to the input's pose.
    """

    cycles: int = 4
    ratio: float = 0.5
    mode: str = "nonuniform"
    groups: tuple[str, ...] = features.DEFAULT_GROUPS + ("smooth", "hks")
    clusters: int = 8
    patch_size: int = 16
    smooth_weight: float = 2.0
    concave_discount: float = DEFAULT_CONCAVE_DISCOUNT
    combine: str = "all"
    once_per_pass: bool = False
    local_scale: str = "relative"
    priority: str = "weighted"
    density_range: float = 8.0
    passes: int = 1
    layout_frame: str = "xyz"
    canonical: bool = False
    seed: int = 0

    def __post_init__(self):
        if self.mode not in DOWNSAMPLING_MODES:
            raise ValueError(f"mode must be one of {DOWNSAMPLING_MODES}, got {self.mode!r}")
        if self.combine not in COMBINE:
            raise ValueError(f"combine must be one of {COMBINE}, got {self.combine!r}")
        if self.priority not in collapse.PRIORITIES:
            raise ValueError(f"priority must be one of {collapse.PRIORITIES}, got {self.priority!r}")
        if not (self.smooth_weight >= 0 and self.concave_discount >= 0):
            raise ValueError("smooth_weight and concave_discount must be >= 0, "
                             f"got {self.smooth_weight}, {self.concave_discount}")
        if not self.density_range >= 1.0:
            raise ValueError(f"density_range must be at least 1 (inf: no clip), got {self.density_range}")
        if self.local_scale not in LOCAL_SCALES:
            raise ValueError(f"local_scale must be one of {LOCAL_SCALES}, got {self.local_scale!r}")
        if not 0.0 < self.ratio < 1.0:
            raise ValueError(f"ratio must lie in (0, 1), got {self.ratio}")
        if self.cycles < 0:
            raise ValueError(f"cycles must be >= 0, got {self.cycles}")
        if self.passes < 1:
            raise ValueError(f"passes must be >= 1, got {self.passes}")
        if self.layout_frame not in FRAMES:
            raise ValueError(f"layout_frame must be one of {FRAMES}, got {self.layout_frame!r}")
        self.groups = tuple(self.groups)

    @property
    def n_levels(self) -> int:
        return 1 if self.mode == "none" else self.cycles + 1


@dataclass(eq=False)
class Segmenter:
    """A trained model ready to segment: the network, the feature statistics it was trained with, its settings."""

    network: AttentionSegmenter
    config: SegmentConfig
    feature_mean: np.ndarray
    feature_std: np.ndarray
    label_names: list[str]
    refiner: Refiner | None = None  # the second stage (anseg.refine), where the model was trained with one

    @property
    def n_classes(self) -> int:
        return self.network.config.n_classes

    def standardize(self, x: np.ndarray) -> np.ndarray:
        """Features standardised with the training statistics."""
        if x.shape[1] != len(self.feature_mean):
            raise ValueError(f"the model expects {len(self.feature_mean)} feature columns, got {x.shape[1]}")
        return ((x - self.feature_mean) / self.feature_std).astype(np.float32)

    def __call__(self, **inputs):
        return self.network(**inputs)

    def save(self, path: str | os.PathLike) -> None:
        """Write everything needed to segment later, atomically."""
        data = self.to_bytes()
        atomic_write(path, lambda tmp: tmp.write_bytes(data))

    def to_bytes(self, half: bool = False) -> bytes:
        """The model file's content (what :meth:`save` writes), e.g. to send from a worker process.

        ``half`` stores the weights in float16 (half the bytes; they are read
        back as float32), for the pretrained models shipped with the package.
        The file records the feature code the model was trained on, so that
        it is never applied to other features.
        """
        import io

        state = self.network.state_dict()
        payload = {
            "network_config": asdict(self.network.config),
            "state_dict": {k: v.half() if half and v.is_floating_point() else v for k, v in state.items()},
            "feature_code": feature_code(),
            "segment_config": asdict(self.config),
            "feature_mean": torch.as_tensor(self.feature_mean),
            "feature_std": torch.as_tensor(self.feature_std),
            "label_names": list(self.label_names),
            **({"refiner": self.refiner.to_payload()} if self.refiner is not None else {}),
        }
        buffer = io.BytesIO()
        torch.save(payload, buffer)
        return buffer.getvalue()

    @classmethod
    def pretrained(cls, name: str, device="cpu") -> "Segmenter":
        """A model shipped with the package, by its name in ``anseg models`` (:mod:`anseg.pretrained`)."""
        from anseg import pretrained

        return cls.load(pretrained.path(name), device)

    @classmethod
    def load(cls, path: str | os.PathLike, device="cpu") -> "Segmenter":
        """Read a model written by :meth:`save`."""
        try:
            payload = torch.load(path, map_location=device, weights_only=True)
            network = AttentionSegmenter(model_config(payload["network_config"]))
            reference = network.state_dict()
            network.load_state_dict({k: v.to(reference[k].dtype) for k, v in payload["state_dict"].items()})
        except (OSError, KeyError, TypeError, RuntimeError, pickle.UnpicklingError) as exc:
            # in our words: torch's own message advises an unsafe load
            raise ValueError(f"{path}: not a model written by anseg, or a damaged one ({type(exc).__name__})") from exc
        trained_on = payload.get("feature_code")  # absent in files written before it was recorded
        if trained_on is not None and features.comparable(trained_on) != features.comparable(feature_code()):
            raise ValueError(f"{path}: trained on other features ({_differences(trained_on, feature_code())}) "
                             "than this anseg computes; retrain it, or use the anseg version it was made with")
        return cls(
            network=network.to(device).eval(),
            config=SegmentConfig(**{**SEGMENT_SETTINGS_ADDED_LATER, **payload["segment_config"]}),
            feature_mean=payload["feature_mean"].numpy(),
            feature_std=payload["feature_std"].numpy(),
            label_names=list(payload["label_names"]),
            refiner=Refiner.from_payload(payload["refiner"]).to(device) if "refiner" in payload else None,
        )


def feature_code() -> dict:
    """What decides the features a model reads, as model files record it: :func:`anseg.features.code` (its
    ``version`` named ``features``) and the eigenbasis's version."""
    code = features.code()
    return {"features": code.pop("version"), **code, "spectrum": spectral.SPECTRUM_VERSION}


def _differences(theirs: dict, ours: dict) -> str:
    keys = sorted(set(theirs) | set(ours))
    return ", ".join(f"{k} {theirs.get(k)!r} here {ours.get(k)!r}" for k in keys if theirs.get(k) != ours.get(k))


def level_features(level: Level, index: int, n_levels: int, local_scale: str = "unit_area") -> np.ndarray:
    """The model's raw input on level ``index``: the feature groups side by side (as :func:`input_groups` reads them),
    then the level column."""
    column = np.full((level.mesh.n_faces, 1), index / max(1, n_levels - 1))
    return np.concatenate([face_features(level.groups, local_scale), column], axis=1).astype(np.float32)


def face_features(groups: dict[str, np.ndarray], local_scale: str) -> np.ndarray:
    """A level's feature groups side by side, as the network reads them (:func:`input_groups`): what K-means
    clusters, and, on the input level, what the second stage reads beside its anchors."""
    return np.concatenate(list(input_groups(groups, local_scale).values()), axis=1)


def input_groups(groups: dict[str, np.ndarray], local_scale: str) -> dict[str, np.ndarray]:
    """The feature groups as the network reads them (``local_scale``: see the module docstring)."""
    if local_scale == "unit_area" or "edge" not in groups:
        return groups
    edge = groups["edge"]
    power = np.arange(1, edge.shape[1] + 1)
    typical = max(float(np.median(edge[:, 0])) / 3, 1e-12)  # median edge length of the level
    relative = np.log(np.maximum(edge, 1e-30) / typical ** power) / power
    return {**groups, "edge": relative}


@dataclass
class Segmentation:
    """What ``segment`` returns: labels and probabilities on the original faces, and every level.

    ``level_faces``: the input face that each face of ``levels[0]`` is, where
    the levels were built on other faces than the input's (a canonical mesh,
    whose faces come in another order; the shape without its stray pieces);
    None where they are the input's. :meth:`on_levels` reads input-face values
    there.
    """

    labels: np.ndarray
    probabilities: np.ndarray
    unsmoothed_labels: np.ndarray
    levels: Hierarchy = field(repr=False)
    level_faces: np.ndarray | None = field(default=None, repr=False)

    def on_levels(self, per_input_face: np.ndarray) -> np.ndarray:
        """Values of the input's faces (labels, probabilities) on the faces of ``levels[0]``."""
        return per_input_face if self.level_faces is None else per_input_face[self.level_faces]


def coarse_groups(level: Level, coarse: Mesh, record: collapse.CollapseRecord, names) -> dict[str, np.ndarray]:
    """Feature groups of the next level: local ones recomputed, global ones pooled from ``level``."""
    local = [g for g in names if g in features.LOCAL_GROUPS]
    out = features.compute_groups(coarse, local) if local else {}
    for g in names:
        if g not in out:
            out[g] = pool(record, level.groups[g], level.mesh.face_areas)
    return {g: out[g] for g in names}


def model_inputs(model: Segmenter, level: Level, index: int, n_levels: int, device) -> dict:
    """The network's arguments for one level: its standardised features (a tensor on ``device``) and its patch layout."""
    x = model.standardize(level_features(level, index, n_levels, model.config.local_scale))
    inputs = {"x": torch.as_tensor(x, device=device), "layout": level.layout}
    if model.network.config.spectral_pairs:
        area = level.mesh.frame_areas  # a stray piece is outside the basis and weighs nothing (Mesh.stray_faces)
        gradient = None
        if model.network.config.diffusion_gradients:
            operator = face_gradient(level.mesh.unit_area()).tocoo()
            gradient = torch.sparse_coo_tensor(np.vstack([operator.row, operator.col]), operator.data.astype(np.float32),
                                               operator.shape, device=device, check_invariants=False).coalesce()
        inputs["spectrum"] = SpectralInput(*(torch.as_tensor(a, dtype=torch.float32, device=device) for a in
                                             (level.spectrum.basis, level.spectrum.values, area / area.sum())), gradient)
    return inputs


def collapse_weights(attention: np.ndarray, density_range: float) -> np.ndarray:
    """The weighted collapse's per-face scores: attention clipped to ``density_range`` around its median.

    Face density follows the weight, so the clip bounds how much coarser a
    low-attention region may get than the uniform collapse would make it
    (the supervised attention spans several orders of magnitude: unclipped,
    one coarse face stood for 30 times as many input faces as under the
    uniform collapse). ``inf`` leaves the attention as it is.
    """
    median = float(np.median(attention))
    low, high = median / np.sqrt(density_range), median * np.sqrt(density_range)
    return np.clip(attention, max(low, 1e-6 * max(median, 1e-12)), high)


def build_levels(mesh: Mesh, model: Segmenter, config: SegmentConfig, groups: dict[str, np.ndarray] | None = None,
                 device="cpu", progress: bool = False, first_layout: PatchLayout | None = None) -> Hierarchy:
    """Run the N downsampling units; attention comes from ``model`` (no gradients).

    ``groups`` are the level-0 features (computed, with the cache, when not
    given; ``progress`` shows their bar on a large mesh). ``first_layout``:
    the input level's patch layout when it is known already (it depends on
    the features alone, so training's rebuilds reuse it instead of clustering
    again). Raises MeshError for a mesh that fails ``validate()``.
    """
    mesh.validate()
    if groups is None:
        groups = features.compute_groups(mesh, config.groups, cache=True, progress=progress)
    levels = []
    current, current_groups = mesh, groups
    current_spectrum = spectral.face_spectrum(mesh) if model.network.config.spectral_pairs else None
    for index in range(config.n_levels):
        if index == 0 and first_layout is not None:
            patches = first_layout
        else:
            patches = layout(current, face_features(current_groups, config.local_scale), k=config.clusters,
                             patch_size=config.patch_size, seed=config.seed, frame=config.layout_frame)
        level = Level(current, current_groups, patches, spectrum=current_spectrum)
        levels.append(level)
        if index == config.n_levels - 1:
            break
        if config.mode == "nonuniform":
            model.network.eval()
            with torch.no_grad():
                out = model(**model_inputs(model, level, index, config.n_levels, device))
            level.attention, level.logits = out.attention.cpu().numpy(), out.logits
            scores = collapse_weights(level.attention, config.density_range) if config.priority == "weighted" else level.attention
        else:
            scores = None
        current, level.record = collapse.downsample(current, scores, ratio=config.ratio, mode=config.mode,
                                                    seed=config.seed + index, once_per_pass=config.once_per_pass,
                                                    priority=config.priority)
        current_groups = coarse_groups(level, current, level.record, config.groups)
        if current_spectrum is not None:
            current_spectrum = spectral.Spectrum(current_spectrum.values, pool(
                level.record, current_spectrum.basis, level.mesh.face_areas).astype(np.float32))
    return Hierarchy(levels)


def fill_attention(model: Segmenter, levels: Hierarchy, device="cpu") -> Hierarchy:
    """Give every level its attention: build_levels computes it only where it drives a collapse.

    The coarsest level, and every level of a uniform or random hierarchy, get
    the model's attention from one forward pass each; returns ``levels``. The
    input level of a mesh above :data:`NETWORK_FACES` faces has none: the
    network read its collapse, the next level.
    """
    model.network.eval()
    with torch.no_grad():
        for index, level in enumerate(levels):
            if level.attention is None and level.layout is not None:  # no layout: a large mesh the network never read
                level.attention = model(**model_inputs(model, level, index, len(levels), device)).attention.cpu().numpy()
    return levels


def level_output(model: Segmenter, levels: Hierarchy, index: int, device="cpu") -> Output:
    """The network's Output on one level, reusing the logits that build_levels kept from its attention pass.

    A kept Output carries no attention (the level has it already). Call it in
    eval mode, without gradients.
    """
    level = levels[index]
    if level.logits is not None:
        return Output(level.logits, None)
    return model(**model_inputs(model, level, index, len(levels), device))


def class_probabilities(model: Segmenter, levels: Hierarchy, config: SegmentConfig, device="cpu") -> np.ndarray:
    """Class probabilities on the original faces, carried up from the coarsest level (or all levels, or the input level)."""
    model.network.eval()
    wanted = {"coarsest": [len(levels) - 1], "finest": [0]}.get(config.combine, range(len(levels)))
    per_level, weights = [], []
    with torch.no_grad():
        for index in wanted:  # only the levels whose labels count, reusing the pass that computed their attention
            out = level_output(model, levels, index, device)
            if levels[index].attention is None:
                levels[index].attention = out.attention.cpu().numpy()
            probs = torch.softmax(out.logits, dim=1).cpu().numpy().astype(np.float64)
            per_level.append(levels.upsample(index, probs))
            weights.append(0.5 ** index if config.combine == "decay" else 1.0)
    return np.average(per_level, axis=0, weights=weights)


def segment(mesh: Mesh, model: Segmenter, config: SegmentConfig | None = None, groups=None, device="cpu",
            progress: bool | None = False, ensemble: tuple[Segmenter, ...] = (),
            network_faces: float | None = None) -> Segmentation:
    """Segment one mesh with a trained model: Algorithm 1, lines 1-9.

    ``config`` defaults to the model's own (the settings it was trained with);
    pass another to change, e.g., the smoothing weight or the mode.
    ``progress``: the bars of long work on stderr (a large mesh's steps, its
    feature groups): ``None`` where stderr is a terminal, ``True`` wherever
    it is (the feature groups' bar stays on terminals), ``False`` never.
    ``network_faces``: the most faces the network reads (``None``:
    :data:`NETWORK_FACES`; ``math.inf``: every face, however many); a larger
    mesh is segmented through one collapse to that many faces (module
    docstring), and the returned levels start with the input mesh, which no
    network read (no features, layout nor attention), its record leading to
    that collapse, and ``groups`` is not read.
    ``ensemble``: more models trained on the same classes and features (other
    seeds); each builds its own hierarchy, and the class probabilities of all
    of them are averaged before the graph cut. The levels returned are
    ``model``'s. Raises MeshError for a mesh that fails ``validate()``.
    ``groups``: the input level's features, if already computed; with
    ``canonical`` they are computed on the canonical mesh instead and
    ``groups`` is not read, because the input mesh's features differ from
    those in the last bits (the pose, the corners' order), which the
    collapse can amplify, and the labels would hang on the input's pose.
    """
    config = config or model.config
    if (stray := mesh.stray_faces) is not None:
        # the shape is segmented as a file of it alone would be, and each face of a stray piece (a speck, a far
        # facet: Mesh.stray_faces) takes the labels of the shape's face nearest to it
        from scipy.spatial import cKDTree

        shape = np.flatnonzero(~stray)
        result = segment(mesh.submesh(~stray)[0], model, config, None if groups is None else
                         {g: block[shape] for g, block in groups.items()}, device, progress, ensemble, network_faces)
        nearest = np.empty(mesh.n_faces, dtype=np.int64)
        nearest[shape] = np.arange(len(shape))
        nearest[stray] = cKDTree(mesh.face_centroids[shape]).query(mesh.face_centroids[stray])[1]
        return Segmentation(labels=result.labels[nearest], probabilities=result.probabilities[nearest],
                            unsmoothed_labels=result.unsmoothed_labels[nearest], levels=result.levels,
                            level_faces=shape[result.on_levels(np.arange(len(shape)))])
    if config.canonical:
        canonical, input_face, pose = canonical_mesh(mesh)
        result = segment(canonical, model, replace(config, canonical=False), None, device, progress, ensemble,
                         network_faces)
        back = np.empty_like(input_face)
        back[input_face] = np.arange(len(input_face))
        levels = Hierarchy([replace(level, mesh=Mesh(pose.undo(level.mesh.vertices), level.mesh.faces))
                            for level in result.levels])
        return Segmentation(labels=result.labels[back], probabilities=result.probabilities[back],
                            unsmoothed_labels=result.unsmoothed_labels[back], levels=levels,
                            level_faces=input_face[result.on_levels(np.arange(len(input_face)))])
    for other in ensemble:
        if other.n_classes != model.n_classes or other.config.groups != model.config.groups:
            raise ValueError("an ensemble's models must share their classes and feature groups")
    network_faces = NETWORK_FACES if network_faces is None else network_faces
    if mesh.n_faces > network_faces:
        return _segment_collapsed(mesh, model, config, int(network_faces), device, progress, ensemble)
    levels = build_levels(mesh, model, config, groups, device, progress is not False)
    groups = levels[0].groups
    idle = sum(level.record.n_collapses == 0 for level in levels[:-1])
    if idle:
        warnings.warn(f"{mesh.n_faces} faces are too few for {config.cycles} cycles at ratio {config.ratio}: "
                      f"{idle} of them collapsed nothing (the coarsest level has {levels[-1].mesh.n_faces} faces)",
                      collapse.CollapseWarning, stacklevel=2)
    probs = 0
    for member in (model, *ensemble):
        for index in range(config.passes):  # the test-time ensemble (SegmentConfig.passes)
            again = replace(config, seed=config.seed + index * PASS_SEED_STEP)
            hierarchy = levels if member is model and index == 0 else build_levels(mesh, member, again, groups, device)
            probs = probs + class_probabilities(member, hierarchy, again, device)
    probs = probs / (config.passes * (1 + len(ensemble)))
    if model.refiner is not None:  # the second stage reads where each face sits relative to the parts found
        own = face_features(groups, config.local_scale)
        probs = model.refiner.refine(mesh, own, probs)
    return _smoothed(mesh, probs, config, levels)


def _smoothed(mesh: Mesh, probs: np.ndarray, config: SegmentConfig, levels: Hierarchy) -> Segmentation:
    """The segmentation of ``mesh`` from its faces' class probabilities: their argmax, smoothed by the graph cut."""
    raw = probs.argmax(axis=1)
    labels = (graph_cut(mesh, probs, weight=config.smooth_weight, concave_discount=config.concave_discount)
              if config.smooth_weight > 0 else raw)
    return Segmentation(labels=labels, probabilities=probs, unsmoothed_labels=raw, levels=levels)


def _segment_collapsed(mesh: Mesh, model: Segmenter, config: SegmentConfig, network_faces: int, device,
                       progress: bool | None, ensemble: tuple[Segmenter, ...]) -> Segmentation:
    """:func:`segment` for a mesh above ``network_faces`` faces: on :func:`network_mesh`, the class probabilities
    carried back to its faces and smoothed there (module docstring)."""
    mesh.validate()
    with progress_bar(total=3, desc=f"segment {mesh.n_faces} faces", unit="step", show=progress, leave=False) as bar:
        bar.set_postfix_str(f"collapse to {network_faces} faces")
        coarse, record = network_mesh(mesh, network_faces)
        bar.update()
        bar.set_postfix_str("segment the collapse")
        inner = segment(coarse, model, replace(config, smooth_weight=0.0), None, device, progress, ensemble,
                        network_faces=math.inf)
        bar.update()
        bar.set_postfix_str("graph cut")
        levels = Hierarchy([Level(mesh, {}, None, record=record), *inner.levels])
        result = _smoothed(mesh, collapse.upsample(record, inner.probabilities), config, levels)
        bar.update()
    return result


def network_mesh(mesh: Mesh, faces: int) -> tuple[Mesh, collapse.CollapseRecord]:
    """The uniform collapse of ``mesh`` to ``faces`` faces that a larger mesh is segmented on, and its record.

    The target is a budget, so stopping a few faces above it (no valid
    collapse left) changes nothing and is not warned of; a mesh with few
    collapsible edges (most of its faces on boundaries) keeps more.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", collapse.CollapseWarning)
        return collapse.downsample(mesh, None, ratio=faces / mesh.n_faces, mode="uniform")
