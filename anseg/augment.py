"""Training copies of a labelled mesh: stretched along random axes and tessellated anew.

For the categories whose network fits its training meshes and still misses
new ones, more kinds of shape and triangulation than the few training
meshes show. A copy is the mesh scaled by a factor per axis of a random
frame (up to :data:`MAX_STRETCH` either way by default, ``stretch`` where given: the strength the
accuracy screens vary, ``train.augment_stretch``; the descriptors are computed on
the unit-area mesh, so only the proportions change), then collapsed at
random to :data:`KEEP` of its faces by the collapse engine itself (every
edge in a random order, so the triangles change everywhere, not only where
a collapse would be cheap); the labels follow the collapse as the coarse
levels' targets do, each new face taking the area majority of the faces it
stands for. A copy's features are computed and cached like any mesh's.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from anseg import collapse
from anseg.hierarchy import pool_labels
from anseg.mesh import Mesh

MAX_STRETCH = 1.25
KEEP = 0.8


def stretched(mesh: Mesh, rng: np.random.Generator, stretch: float = MAX_STRETCH) -> Mesh:
    """``mesh`` scaled by a factor in [1 / stretch, stretch] along each axis of a random frame."""
    from scipy.spatial.transform import Rotation

    axes = Rotation.random(random_state=rng).as_matrix()
    factors = np.exp(rng.uniform(-np.log(stretch), np.log(stretch), size=3))
    return Mesh(((mesh.vertices @ axes) * factors) @ axes.T, mesh.faces)


def augmented(item, copies: int, seed: int = 0, stretch: float = MAX_STRETCH) -> list:
    """``copies`` training copies of a labelled mesh (``.mesh``, ``.labels``, ``.label_names``, ``.name``), each named
    after it with ``+copy<k>``; the same for a given ``seed`` and name."""
    out = []
    for k in range(copies):
        rng = np.random.default_rng([seed, k, *item.name.encode()])
        mesh = stretched(item.mesh, rng, stretch)
        with warnings.catch_warnings():  # a target missed by a few faces changes nothing here
            warnings.simplefilter("ignore", collapse.CollapseWarning)
            coarse, record = collapse.downsample(mesh, None, ratio=KEEP, mode="random", seed=int(rng.integers(2**31)))
        labels = pool_labels(record, item.labels, mesh.face_areas, len(item.label_names))
        out.append(replace(item, mesh=coarse, labels=labels, name=f"{item.name}+copy{k}", soft_labels=None, face_map=None))
    return out
