"""Training and evaluation per category (the paper trains and tests per category).

``fit`` trains one :class:`~anseg.pipeline.Segmenter` on a category's
training meshes: cross-entropy at every level of the hierarchy (a coarse
face's target is the area-weighted majority of the original faces it stands
for), each face weighted by its share of the mesh's area, as Eq. 5 weighs it.
Adam, learning rate 1e-3, initial weights N(0, 0.001) (the paper).

The collapse is not differentiable, so the hierarchy is rebuilt from the current attention
every ``recollapse_every`` epochs and kept in between: rebuilding (K-means and coarse features
at every level) costs more than the gradient steps, and the attention moves slowly. The input
level's layout and a hierarchy that attention does not drive never change, so they are built once,
unless ``new_layouts`` asks for other tokens at every rebuild.

The attention gets a training signal of its own (``attention_weight``; 0 gives the paper's
reading, attention trained through the class loss alone, which leaves it nearly flat, so the
collapse wipes whole regions). On every collapsed level a face's attention, as the logit
log(attention), is trained by class-balanced binary cross-entropy to tell faces within
``boundary_rings`` rings of another label from the rest: a score high near label boundaries
keeps labels through the collapses, the behaviour the paper describes (Fig. 4) made explicit.
``evaluate`` segments the test meshes and reports Eq. 5 in the three readings of
:mod:`anseg.metrics`, with and without the graph cut; no model selection is done on the test
meshes (the last epoch's model is evaluated). The measurements behind this: ``docs/decisions.md``.
"""

from __future__ import annotations

import json
import math
import os
import random
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from anseg import collapse, features
from anseg.augment import MAX_STRETCH, augmented
from anseg.cache import atomic_write
from anseg.cluster import PatchLayout
from anseg.geometry.spectral import SPECTRUM_PAIRS
from anseg.metrics import accuracy, pooled_accuracy
from anseg.model import AttentionSegmenter, ModelConfig
from anseg.pipeline import (
    SegmentConfig,
    Segmenter,
    build_levels,
    face_features,
    input_groups,
    model_inputs,
    segment,
)
from anseg.refine import Refiner, anchor_features, fit_refiner

SCHEDULES = ("constant", "cosine")
LAYOUT_SEED_STEP = 7919  # rebuild r of a training with new_layouts lays out with seed + r * this (a pass of a test uses 1000)
# TrainConfig's settings that came after results were stored, with the value those ran with (as for SegmentConfig's,
# anseg.pipeline.SEGMENT_SETTINGS_ADDED_LATER).
TRAIN_SETTINGS_ADDED_LATER = {"embed_norm": False, "schedule": "constant", "detach_share": False, "average_last": 0,
                              "diffusion_blocks": 0, "diffusion_gradients": False, "new_layouts": False,
                              "second_stage_folds": 0, "augment_copies": 0, "augment_stretch": MAX_STRETCH}


@dataclass
class TrainConfig:
    """Optimisation settings; the network's width and depth live here too.

    ``schedule``: ``"constant"`` keeps ``lr`` for every step (the paper);
    ``"cosine"`` decays it from ``lr`` to 0 over the run's steps, so that the
    last epochs, whose model is the one kept, settle instead of moving at
    full step size. ``detach_share``: the
    attention loss does not reach the pooling share directly (:class:`~anseg.model.ModelConfig`).
    ``average_last`` > 0 keeps the average of the weights at the end of each
    of the last that many epochs instead of the last weights (stochastic
    weight averaging at the constant rate): the last epoch's weights still
    move with the step size and the seed. A run of fewer epochs averages all
    of them, so that a short run (a smoke test, the synthetic notebooks) need
    not change the setting. ``diffusion_blocks`` gives the network learned
    heat diffusion through the mesh's Laplacian eigenbasis
    (:class:`~anseg.model.ModelConfig`; off by default), and
    ``diffusion_gradients`` their gradient features (off). ``second_stage_folds``
    > 0 adds the second stage of :mod:`anseg.refine`, cross-fitted over that
    many folds of the training meshes (off by default). ``augment_copies``
    adds that many copies of every training mesh, stretched (by up to
    ``augment_stretch`` either way along each axis of a random frame) and
    tessellated anew (:mod:`anseg.augment`; off by default). ``new_layouts``
    rebuilds every hierarchy, the input level's layout included, every
    ``recollapse_every`` epochs with another layout seed (other K-means
    starts, and with ``layout_frame="random"`` another frame for the token
    order), so that the network learns labels that do not hang on one token
    order (off by default: the layout is built once).
    """

    epochs: int = 60
    lr: float = 1e-3
    schedule: str = "constant"
    width: int = 64
    depth: int = 2
    heads: int = 4
    dropout: float = 0.0
    embed_norm: bool = False
    detach_share: bool = False
    average_last: int = 20
    recollapse_every: int = 5
    attention_weight: float = 1.0
    boundary_rings: int = 2
    diffusion_blocks: int = 0
    diffusion_gradients: bool = False
    new_layouts: bool = False
    second_stage_folds: int = 0
    augment_copies: int = 0
    augment_stretch: float = MAX_STRETCH
    seed: int = 0
    device: str = "auto"

    def __post_init__(self):
        if self.epochs < 1 or self.recollapse_every < 1:
            raise ValueError("epochs and recollapse_every must be >= 1")
        if self.augment_copies < 0:
            raise ValueError(f"augment_copies must be >= 0, got {self.augment_copies}")
        if not self.augment_stretch >= 1.0:
            raise ValueError(f"augment_stretch must be >= 1 (1: no stretch), got {self.augment_stretch}")
        if self.second_stage_folds == 1 or self.second_stage_folds < 0:
            raise ValueError(f"second_stage_folds must be 0 (no second stage) or at least 2, got {self.second_stage_folds}")
        if self.average_last < 0:
            raise ValueError(f"average_last must be >= 0, got {self.average_last}")
        if self.schedule not in SCHEDULES:
            raise ValueError(f"schedule must be one of {SCHEDULES}, got {self.schedule!r}")


def learning_rate(train: TrainConfig, step: int, total_steps: int) -> float:
    """The learning rate of gradient step ``step`` (0-based) of ``total_steps`` under ``train.schedule``."""
    if train.schedule == "cosine":
        return 0.5 * train.lr * (1 + math.cos(math.pi * step / total_steps))
    return train.lr


def resolve_device(device: str) -> torch.device:
    """``auto`` picks CUDA when it is there, else the CPU."""
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(device)


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def level_zero_features(meshes, config: SegmentConfig, progress: bool = True) -> list[dict[str, np.ndarray]]:
    """The (cached) feature groups of every mesh, computed in parallel."""
    matrices = features.compute_many([m.mesh for m in meshes], config.groups, progress=progress)
    widths = np.cumsum([len(features.feature_names([g])) for g in config.groups])[:-1]
    return [dict(zip(config.groups, np.split(x, widths, axis=1))) for x in matrices]


def feature_statistics(groups: list[dict[str, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of every input column over the training faces.

    The last column (level / cycles, already in [0, 1]) is left as it is.
    """
    x = np.concatenate([np.concatenate(list(g.values()), axis=1) for g in groups])
    mean = np.append(x.mean(axis=0), 0.0)
    std = np.append(np.maximum(x.std(axis=0), 1e-6), 1.0)
    return mean, std


@dataclass
class _Example:
    """One training mesh at every level: model inputs, targets and loss weights."""

    inputs: list[dict]
    targets: list[torch.Tensor]
    weights: list[torch.Tensor]
    near_boundary: list[torch.Tensor | None]  # attention targets of the levels that get collapsed
    first_layout: PatchLayout  # the input level's, the same at every rebuild unless new_layouts


def _examples(model: Segmenter, config: SegmentConfig, mesh, labels, groups, train: TrainConfig, device,
              first_layout=None) -> _Example:
    levels = build_levels(mesh, model, config, groups, device, first_layout=first_layout)
    supervise = model.config.mode == "nonuniform" and train.attention_weight > 0
    example = _Example([], [], [], [], levels[0].layout)
    for index, (level, target) in enumerate(zip(levels, levels.labels_on_every_level(labels, model.n_classes))):
        area = level.mesh.face_areas
        example.inputs.append(model_inputs(model, level, index, len(levels), device))
        example.targets.append(torch.as_tensor(target, device=device))
        example.weights.append(torch.as_tensor(area / area.sum(), dtype=torch.float32, device=device))
        band = None
        if supervise and index < len(levels) - 1:
            band = torch.as_tensor(collapse.rings_to_other_label(level.mesh, target) <= train.boundary_rings,
                                   dtype=torch.float32, device=device)
        example.near_boundary.append(band)
    return example


def _attention_loss(attention: torch.Tensor, near_boundary: torch.Tensor) -> torch.Tensor:
    """Class-balanced BCE of log(attention) (mean 1, so logit 0) against the boundary band."""
    positives = near_boundary.sum()
    if positives == 0 or positives == len(near_boundary):
        return attention.new_zeros(())
    pos_weight = (len(near_boundary) - positives) / positives
    return F.binary_cross_entropy_with_logits(torch.log(attention.clamp_min(1e-8)), near_boundary, pos_weight=pos_weight)


def _loss(model: Segmenter, example: _Example, train: TrainConfig) -> tuple[torch.Tensor, float]:
    """Area-weighted cross-entropy averaged over levels (plus the attention term), and the coarsest level's accuracy."""
    total = 0.0
    for inputs, target, weight, band in zip(example.inputs, example.targets, example.weights, example.near_boundary):
        out = model.network(**inputs, need_attention=False, attention_grad=band is not None)
        total = total + (F.cross_entropy(out.logits, target, reduction="none") * weight).sum()
        if band is not None:
            total = total + train.attention_weight * _attention_loss(out.attention, band)
    coarse_accuracy = float((weight * (out.logits.argmax(1) == target)).sum())
    return total / len(example.inputs), coarse_accuracy


def fit(*args, **kwargs) -> Segmenter:
    """Train a Segmenter on labelled meshes: :func:`fit_and_time`'s arguments, the model alone."""
    return fit_and_time(*args, **kwargs)[0]


def fit_and_time(
    train_set,
    label_names: list[str],
    config: SegmentConfig | None = None,
    train: TrainConfig | None = None,
    checkpoint: str | os.PathLike | None = None,
    progress: bool = True,
) -> tuple[Segmenter, float, float]:
    """Train a Segmenter on labelled meshes (``.mesh``, ``.labels``): the model, and the wall and CPU seconds it took.

    With ``checkpoint`` the state is written there atomically after every
    epoch, and a run that finds a checkpoint of the same settings resumes
    from it; the resumed run counts the seconds the checkpoint carries from
    the sessions before, so that a run record states the whole cost.
    """
    from anseg.progress import progress as progress_bar

    started = time.time(), time.process_time()

    config = config or SegmentConfig()
    train = train or TrainConfig()
    if not train_set:
        raise ValueError("no training meshes")
    if train.depth == 0 and config.mode != "none":
        raise ValueError("depth 0 (a per-face classifier without attention) needs mode 'none': nothing would rank the collapses")
    device = resolve_device(train.device)
    seed_everything(train.seed)
    originals = list(train_set)
    copies = (augmented(item, train.augment_copies, train.seed, train.augment_stretch) for item in originals)
    train_set = [*originals, *(copy for made in copies for copy in made)]
    groups = level_zero_features(train_set, config, progress=progress)
    mean, std = feature_statistics([input_groups(g, config.local_scale) for g in groups])
    network = AttentionSegmenter(
        ModelConfig(
            in_features=len(mean), n_classes=len(label_names), width=train.width, depth=train.depth,
            heads=train.heads, patch_size=config.patch_size, dropout=train.dropout, embed_norm=train.embed_norm,
            detach_share=train.detach_share,
            spectral_pairs=SPECTRUM_PAIRS if train.diffusion_blocks else 0, diffusion_blocks=train.diffusion_blocks,
            diffusion_gradients=train.diffusion_gradients,
        )
    ).to(device)
    model = Segmenter(network, config, mean, std, list(label_names))
    optimizer = torch.optim.Adam(network.parameters(), lr=train.lr)
    total_steps = train.epochs * len(train_set)
    settings = {"segment": asdict(config), "train": asdict(train), "meshes": [m.name for m in train_set]}
    order = np.random.default_rng(train.seed)  # the order of the meshes in each epoch
    state = _TrainingState(network, optimizer, order, started)
    start = state.resume(checkpoint, settings) if checkpoint else 0

    bar = progress_bar(range(start, train.epochs), desc="train", show=progress, initial=start, total=train.epochs)
    examples: list[_Example] = []
    for epoch in bar:
        # only attention and new layouts change a hierarchy: a uniform or no collapse is otherwise built once
        rebuilt = config.mode == "nonuniform" or train.new_layouts
        if not examples or (rebuilt and epoch % train.recollapse_every == 0):
            # a run resumed between rebuilds rebuilds with the weights of the last rebuild, as the run it continues did
            with state.weights_of_last_rebuild(epoch % train.recollapse_every == 0):
                rebuild = epoch // train.recollapse_every if train.new_layouts else 0
                layout_config = replace(config, seed=config.seed + rebuild * LAYOUT_SEED_STEP)
                kept = examples if examples and not train.new_layouts else [None] * len(train_set)
                examples = [_examples(model, layout_config, m.mesh, m.labels, g, train, device, e.first_layout if e else None)
                            for m, g, e in zip(train_set, groups, kept)]
        network.train()
        losses, accuracies = [], []
        for step, i in enumerate(order.permutation(len(examples)), start=epoch * len(examples)):
            for group in optimizer.param_groups:
                group["lr"] = learning_rate(train, step, total_steps)
            loss, coarse_accuracy = _loss(model, examples[i], train)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
            accuracies.append(coarse_accuracy)
        bar.set_postfix(loss=f"{np.mean(losses):.3f}", acc=f"{np.mean(accuracies):.3f}")
        if epoch >= train.epochs - train.average_last:
            state.add_to_average()
        if checkpoint:
            state.save(checkpoint, settings, epoch + 1)
    if train.average_last:
        network.load_state_dict(state.averaged())
    network.eval()
    if train.second_stage_folds:
        model.refiner = _second_stage(originals, groups[: len(originals)], label_names, config, train)
    return (model, *state.seconds_spent())


def _second_stage(train_set, groups, label_names, config: SegmentConfig, train: TrainConfig) -> Refiner:
    """The second stage (:mod:`anseg.refine`), cross-fitted: the training meshes in ``second_stage_folds`` folds, each
    labelled by a first stage trained as this one on the other folds, and the refiner trained on those labels.

    The first stage has seen its own training meshes, so its probabilities
    there are better than on a new mesh; a refiner trained on them would
    trust them more than they deserve.
    """
    folds, first_stage, examples = train.second_stage_folds, replace(train, second_stage_folds=0), []
    for fold in range(folds):
        rest = [m for i, m in enumerate(train_set) if i % folds != fold]
        fold_model = fit(rest, label_names, config, first_stage, progress=False)
        for i in range(fold, len(train_set), folds):
            item = train_set[i]
            probs = segment(item.mesh, fold_model, config, groups[i]).probabilities
            examples.append((face_features(groups[i], config.local_scale), anchor_features(item.mesh, probs), item.labels,
                             item.mesh.face_areas))
    return fit_refiner(examples, len(label_names), seed=train.seed)


class _TrainingState:
    """What a checkpoint holds, so that a resumed run continues exactly as the uninterrupted one would.

    Besides the weights, the optimiser and torch's random state: the
    generator that orders the meshes, and the weights the current hierarchy
    was built with (it is rebuilt only every ``recollapse_every`` epochs),
    and the running sum of the weights being averaged (``average_last``);
    and the wall and CPU seconds spent on the run so far.
    """

    def __init__(self, network, optimizer, order: np.random.Generator, started: tuple[float, float]):
        self.network, self.optimizer, self.order = network, optimizer, order
        self.rebuilt_with = None  # state dict of the last rebuild; None: the current weights
        self.weight_sum, self.summed = None, 0  # the averaged epochs' weights (float64), and how many
        self.started, self.spent_before = started, (0.0, 0.0)  # this session's start; earlier sessions' seconds

    def seconds_spent(self) -> tuple[float, float]:
        """Wall and CPU seconds of the run, earlier sessions included."""
        now = time.time(), time.process_time()
        return tuple(before + n - s for before, n, s in zip(self.spent_before, now, self.started))

    def add_to_average(self) -> None:
        current = {k: v.detach().double() for k, v in self.network.state_dict().items()}
        self.weight_sum = current if self.weight_sum is None else {k: self.weight_sum[k] + v for k, v in current.items()}
        self.summed += 1

    def averaged(self) -> dict:
        reference = self.network.state_dict()
        return {k: (v / self.summed).to(reference[k].dtype) for k, v in self.weight_sum.items()}

    @contextmanager
    def weights_of_last_rebuild(self, rebuilding_now: bool):
        if rebuilding_now or self.rebuilt_with is None:
            self.rebuilt_with = {k: v.detach().clone() for k, v in self.network.state_dict().items()}
            yield
            return
        current = {k: v.detach().clone() for k, v in self.network.state_dict().items()}
        self.network.load_state_dict(self.rebuilt_with)
        try:
            yield
        finally:
            self.network.load_state_dict(current)

    def save(self, path, settings: dict, epoch: int) -> None:
        payload = {"settings": json.dumps(settings, sort_keys=True), "network": self.network.state_dict(),
                   "optimizer": self.optimizer.state_dict(), "epoch": epoch, "torch_rng": torch.get_rng_state(),
                   "order_rng": json.dumps(self.order.bit_generator.state), "rebuilt_with": self.rebuilt_with,
                   "weight_sum": self.weight_sum, "summed": self.summed, "seconds_spent": list(self.seconds_spent())}
        atomic_write(path, lambda tmp: torch.save(payload, tmp))

    def resume(self, path, settings: dict) -> int:
        """The epoch to start from: that of a checkpoint with the same settings, else 0."""
        path = Path(path)
        if not path.is_file():
            return 0
        payload = torch.load(path, map_location="cpu", weights_only=True)
        if payload.get("settings") != json.dumps(settings, sort_keys=True) or "order_rng" not in payload:
            return 0
        self.network.load_state_dict(payload["network"])
        self.optimizer.load_state_dict(payload["optimizer"])
        torch.set_rng_state(payload["torch_rng"])
        self.order.bit_generator.state = json.loads(payload["order_rng"])
        self.rebuilt_with = payload["rebuilt_with"]
        self.weight_sum, self.summed = payload.get("weight_sum"), payload.get("summed", 0)
        self.spent_before = tuple(payload.get("seconds_spent", (0.0, 0.0)))
        return int(payload["epoch"])


def evaluate(model: Segmenter, test_set, config: SegmentConfig | None = None, progress: bool = True,
             ensemble: tuple[Segmenter, ...] = ()) -> dict:
    """Segment the test meshes and score them (Eq. 5; smoothed and unsmoothed).

    ``ensemble``: more models whose probabilities are averaged with ``model``'s (:func:`~anseg.pipeline.segment`).
    """
    from anseg.progress import progress as progress_bar

    config = config or model.config
    device = next(model.network.parameters()).device
    # with canonical, segment computes the features on the canonical meshes: the input meshes' are not read
    groups = [None] * len(test_set) if config.canonical else level_zero_features(test_set, config, progress=False)
    smoothed, raw, per_mesh = [], [], []
    for item, g in progress_bar(list(zip(test_set, groups)), desc="evaluate", show=progress):
        result = segment(item.mesh, model, config, g, device, ensemble=ensemble)
        smoothed.append(result.labels)
        raw.append(result.unsmoothed_labels)
        per_mesh.append({"name": item.name, "faces": item.mesh.n_faces,
                         "accuracy": accuracy(result.labels, item.labels, item.mesh.face_areas)})
    truth = [m.labels for m in test_set]
    areas = [m.mesh.face_areas for m in test_set]
    return {
        "smoothed": pooled_accuracy(smoothed, truth, areas),
        "unsmoothed": pooled_accuracy(raw, truth, areas),
        "per_mesh": per_mesh,
        "predictions": smoothed,
    }
