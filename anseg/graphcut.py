"""Graph-cut smoothing of per-face class probabilities (Algorithm 1, line 8).

The labelling minimises, by alpha-expansion (``gco-wrapper``), the energy

    E(l) = sum_f a_f * -log(p[f, l_f] + eps)
         + weight * sum_{f~g, l_f != l_g} len_e * exp(-concave_discount * max(0, -theta_e))

over the edge-sharing face adjacency, where ``a_f`` is the face area divided
by the mean face area, ``len_e`` the shared edge length divided by the mean
edge length and ``theta_e`` the signed dihedral angle of the shared edge
(negative = concave, :attr:`Mesh.dihedral_angles`). Both normalisations make
``weight`` mean the same on any mesh, whatever its units or resolution.

Why this pairwise form: part boundaries run along concave creases (the minima
rule), so a cut there should be cheap, while a cut across a flat or convex
region should pay its full length. The exponential keeps convex and flat edges
at full cost and makes a right-angled concave crease cost exp(-pi/2 * discount)
of it (1 % at the default discount 3); ``concave_discount=0`` gives plain
length-weighted Potts. The classic ``-log(theta/pi)`` form is unbounded at flat
edges and would need clipping. Boundary edges carry no pairwise term;
disconnected components are smoothed independently by the same cut.
"""

from __future__ import annotations

import numpy as np

from anseg.mesh import Mesh

DEFAULT_WEIGHT = 1.0
DEFAULT_CONCAVE_DISCOUNT = 3.0

# GCO works in int32 and refuses terms above 1e7 (GCO_MAX_ENERGYTERM); its
# max-flow sums a face's unary with up to three pairwise terms, so the
# largest term is scaled to 1e6, keeping six significant digits.
_LARGEST_INTEGER_TERM = 1_000_000


def smooth(
    mesh: Mesh,
    probs,
    weight: float = DEFAULT_WEIGHT,
    concave_discount: float = DEFAULT_CONCAVE_DISCOUNT,
    eps: float = 1e-8,
    n_iter: int = -1,
) -> np.ndarray:
    """Smoothed per-face labels (F,) int64 from class probabilities ``probs`` (F, C).

    ``probs`` must be finite and non-negative; rows need not sum to one
    (vote fractions work). ``weight`` scales the pairwise term: 0 returns the
    argmax. ``n_iter`` caps the expansion cycles (-1: until convergence).
    The expansion starts from the argmax labelling, so its energy (in the
    integer-scaled costs GCO optimises) is never higher than the argmax's.
    """
    unary, pairs, pair_weights = _costs(mesh, probs, weight, concave_discount, eps)
    start = np.argmin(unary, axis=1)  # the argmax of p, ties to the lowest class
    if unary.shape[1] == 1 or len(pairs) == 0 or weight == 0:
        return start.astype(np.int64)
    # the GCO class rather than gco.cut_general_graph: that one rescales integer costs
    # itself (truncating them) and initialises every site through a Python call
    from gco import GCO

    # a per-face constant does not change the minimiser; removing it keeps the integers small
    unary = unary - unary.min(axis=1, keepdims=True)
    scale = _LARGEST_INTEGER_TERM / max(unary.max(), pair_weights.max(), 1e-300)
    pairs = np.sort(pairs, axis=1)  # GCO ignores pairs whose first site is the larger
    n_faces, n_classes = unary.shape
    graph = GCO()
    graph.create_general_graph(n_faces, n_classes, energy_is_float=False)
    try:
        graph.set_data_cost(np.rint(unary * scale).astype(np.int32))
        graph.set_all_neighbors(pairs[:, 0], pairs[:, 1], np.rint(pair_weights * scale).astype(np.int32))
        graph.set_smooth_cost((1 - np.eye(n_classes)).astype(np.int32))
        # GCO starts every site at label 0 and has no bulk initialiser: set only the others
        for face in np.flatnonzero(start).tolist():
            graph.init_label_at_site(face, int(start[face]))
        graph.expansion(n_iter)
        return graph.get_labels().astype(np.int64)
    finally:
        graph.destroy_graph()


def energy(
    mesh: Mesh,
    probs,
    labels,
    weight: float = DEFAULT_WEIGHT,
    concave_discount: float = DEFAULT_CONCAVE_DISCOUNT,
    eps: float = 1e-8,
) -> float:
    """The energy :func:`smooth` minimises (module docstring), in float64, for ``labels`` (F,)."""
    unary, pairs, pair_weights = _costs(mesh, probs, weight, concave_discount, eps)
    labels = np.asarray(labels)
    if labels.shape != (len(unary),) or not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"labels must be an integer array of shape ({len(unary)},), got {labels.dtype} {labels.shape}")
    if len(labels) and (labels.min() < 0 or labels.max() >= unary.shape[1]):
        raise ValueError(f"labels must lie in [0, {unary.shape[1]}), got [{labels.min()}, {labels.max()}]")
    data = unary[np.arange(len(labels)), labels].sum()
    cut = labels[pairs[:, 0]] != labels[pairs[:, 1]]
    return float(data + pair_weights[cut].sum())


def _costs(mesh: Mesh, probs, weight, concave_discount, eps) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unary costs (F, C), adjacent face pairs (P, 2) and their pairwise weights (P,), weight included."""
    probs = np.asarray(probs, dtype=np.float64)
    if probs.ndim != 2 or probs.shape[0] != mesh.n_faces or probs.shape[1] < 1:
        raise ValueError(f"probs must have shape (F={mesh.n_faces}, C>=1), got {probs.shape}")
    if not np.isfinite(probs).all():
        raise ValueError(f"probs has {int((~np.isfinite(probs)).sum())} NaN or infinite entries")
    if probs.min() < 0:
        raise ValueError(f"probs must be non-negative, got a minimum of {probs.min()}")
    for name, value in (("weight", weight), ("concave_discount", concave_discount)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {value}")
    if not (np.isfinite(eps) and eps > 0):
        raise ValueError(f"eps must be finite and > 0, got {eps}")

    areas = mesh.face_areas
    if not areas.mean() > 0:
        raise ValueError("mesh has zero total area; cannot weight the unary term by face area")
    unary = (areas / areas.mean())[:, None] * -np.log(probs + eps)

    pairs = mesh.face_adjacency
    lengths = mesh.edge_lengths[mesh.interior_edges] / mesh.edge_lengths.mean()
    concavity = np.maximum(0.0, -mesh.dihedral_angles)
    return unary, pairs, weight * lengths * np.exp(-concave_discount * concavity)
