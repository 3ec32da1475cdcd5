"""The second stage: every face relabelled from where it sits relative to the parts the first stage found.

The first stage's tokens carry no relative position, yet which finger is
which, or which leg, is a matter of where a part sits beside the others.
From the first stage's class probabilities on the input faces,
:func:`anchor_features` gives each face, per class, the probabilities
diffused over the surface at a few times (heat diffusion through the mesh's
cached eigenbasis) and the geodesic distance to the nearest face the first
stage labelled with that class (the heat method). :class:`Refiner`, a small
per-face network, reads them beside the face's own features and the first
stage's log-probabilities. :func:`anseg.train.fit` trains it on first-stage
predictions of training meshes that the first stage did not see
(cross-fitting), so that it learns to trust them as much as they deserve on
a new mesh; :func:`anseg.pipeline.segment` applies it before the graph cut.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from anseg.geometry import spectral
from anseg.mesh import Mesh

DIFFUSION_TIMES = (0.003, 0.03)  # on the unit-area mesh: a few faces' width, and about a limb's
FAR = 2.0  # the distance given to a class no face was labelled with, and the cap (a unit-area shape spans about 1)


def anchor_features(mesh: Mesh, probabilities: np.ndarray) -> np.ndarray:
    """(F, C x (2 + len(DIFFUSION_TIMES))) float32: log-probabilities, their diffusions, and distances to each class.

    The distance to class c is the heat-method geodesic distance on the
    unit-area mesh from the faces whose most likely class is c (the mean of
    a face's corners; 0 on those faces), capped at :data:`FAR`; a class no
    face took, and the parts of the surface its faces cannot reach, read
    :data:`FAR`.
    """
    import potpourri3d as pp3d

    probabilities = np.asarray(probabilities, dtype=np.float64)
    spectrum = spectral.face_spectrum(mesh)
    mass = mesh.face_areas / mesh.face_areas.sum()
    coefficients = spectrum.basis.T.astype(np.float64) @ (mass[:, None] * probabilities)
    diffused = [spectrum.basis @ (np.exp(-spectrum.values * t)[:, None] * coefficients) for t in DIFFUSION_TIMES]
    unit = mesh.unit_area()
    solver = pp3d.MeshHeatMethodDistanceSolver(unit.vertices, unit.faces)
    labels = probabilities.argmax(axis=1)
    distances = np.full(probabilities.shape, FAR)
    for c in range(probabilities.shape[1]):
        if (labels == c).any():
            per_vertex = solver.compute_distance_multisource(np.unique(unit.faces[labels == c]).tolist())
            distances[:, c] = np.nan_to_num(per_vertex[unit.faces].mean(axis=1), nan=FAR, posinf=FAR).clip(0.0, FAR)
            distances[labels == c, c] = 0.0  # the heat method smooths inside a large source set
    return np.concatenate([np.log(probabilities + 1e-6), *diffused, distances], axis=1).astype(np.float32)


class Refiner(nn.Module):
    """Class logits (F, C) of each face from its own features and its :func:`anchor_features`, standardised."""

    def __init__(self, in_features: int, n_classes: int, width: int = 64, mean=None, std=None):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(in_features, width), nn.GELU(), nn.Linear(width, width), nn.GELU(),
                                 nn.Linear(width, n_classes))
        self.register_buffer("mean", torch.zeros(in_features) if mean is None else torch.as_tensor(mean, dtype=torch.float32))
        self.register_buffer("std", torch.ones(in_features) if std is None else torch.as_tensor(std, dtype=torch.float32))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net((x - self.mean) / self.std)

    def refine(self, mesh: Mesh, face_features: np.ndarray, probabilities: np.ndarray) -> np.ndarray:
        """(F, C) float64 class probabilities of one mesh from the first stage's ``probabilities`` on it."""
        return self.probabilities(face_features, anchor_features(mesh, probabilities))

    def probabilities(self, face_features: np.ndarray, anchors: np.ndarray) -> np.ndarray:
        """(F, C) float64 class probabilities of one mesh from its own features and its :func:`anchor_features`."""
        self.eval()
        with torch.no_grad():
            x = torch.as_tensor(np.concatenate([face_features, anchors], axis=1), dtype=torch.float32)
            return torch.softmax(self(x), dim=1).double().numpy()

    def to_payload(self) -> dict:
        return {"in_features": self.net[0].in_features, "n_classes": self.net[-1].out_features,
                "width": self.net[0].out_features, "state_dict": self.state_dict()}

    @classmethod
    def from_payload(cls, payload: dict) -> "Refiner":
        refiner = cls(payload["in_features"], payload["n_classes"], payload["width"])
        refiner.load_state_dict(payload["state_dict"])
        return refiner.eval()


def fit_refiner(examples: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]], n_classes: int, steps: int = 300,
                lr: float = 3e-3, seed: int = 0) -> Refiner:
    """A :class:`Refiner` trained on (face features, anchor features, labels, face areas) of each training mesh.

    Full-batch Adam on the area-weighted cross-entropy, every mesh weighing
    the same (Eq. 5 weighs faces by their share of their mesh's area).
    """
    torch.manual_seed(seed)
    x = torch.as_tensor(np.concatenate([np.concatenate([f, a], axis=1) for f, a, _, _ in examples]), dtype=torch.float32)
    target = torch.as_tensor(np.concatenate([labels for *_, labels, _ in examples]), dtype=torch.long)
    weight = torch.as_tensor(np.concatenate([area / area.sum() / len(examples) for *_, area in examples]),
                             dtype=torch.float32)
    refiner = Refiner(x.shape[1], n_classes, mean=x.mean(dim=0), std=x.std(dim=0).clamp_min(1e-6))
    optimizer = torch.optim.Adam(refiner.parameters(), lr=lr)
    refiner.train()
    for _ in range(steps):
        loss = (F.cross_entropy(refiner(x), target, reduction="none") * weight).sum()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return refiner.eval()
