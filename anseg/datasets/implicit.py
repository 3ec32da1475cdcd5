"""The implicit parts the synthetic shapes are made of (:mod:`anseg.datasets.synthetic`).

Each part gives a distance-like function (negative inside), its bounding box
and the label of a point on it: tapered tubes, ellipsoids, profiles turned
about the vertical axis, and tubes along a path (handles). A :class:`Shape`
blends its parts in order with a smooth minimum, so that parts meet in a
fillet as on real models, and names the junctions where the tessellation is
refined.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass
class Tube:
    """A tapered capsule from ``a`` (radius ``ra``) to ``b`` (radius ``rb``)."""

    a: np.ndarray
    b: np.ndarray
    ra: float
    rb: float
    label: int

    def distance(self, p: np.ndarray) -> np.ndarray:
        ab = self.b - self.a
        t = np.clip(((p - self.a) @ ab) / (ab @ ab), 0.0, 1.0)
        return np.linalg.norm(p - (self.a + t[:, None] * ab), axis=1) - (self.ra + t * (self.rb - self.ra))

    def labels(self, p: np.ndarray) -> np.ndarray:
        return np.full(len(p), self.label)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        r = max(self.ra, self.rb)
        return np.minimum(self.a, self.b) - r, np.maximum(self.a, self.b) + r

    def skeleton(self) -> tuple[np.ndarray, np.ndarray]:
        """Sample points on the axis and the radius there; the root end (in the junction with the parent) is left out."""
        t = np.linspace(0.3, 1.0, 8)
        return self.a + t[:, None] * (self.b - self.a), self.ra + t * (self.rb - self.ra)


@dataclass
class Ellipsoid:
    """An ellipsoid with semi-axes ``radii`` along the columns of ``frame``."""

    centre: np.ndarray
    radii: np.ndarray
    label: int
    frame: np.ndarray = field(default_factory=lambda: np.eye(3))

    def distance(self, p: np.ndarray) -> np.ndarray:
        # a close bound on the Euclidean distance, exact on the surface
        q = (p - self.centre) @ self.frame
        k0 = np.linalg.norm(q / self.radii, axis=1)
        k1 = np.linalg.norm(q / self.radii**2, axis=1)
        return k0 * (k0 - 1.0) / np.maximum(k1, 1e-12)

    def labels(self, p: np.ndarray) -> np.ndarray:
        return np.full(len(p), self.label)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.centre - self.radii.max(), self.centre + self.radii.max()

    def skeleton(self) -> tuple[np.ndarray, np.ndarray]:
        return self.centre[None], np.array([self.radii.min()])


@dataclass
class Revolved:
    """The solid swept by a (rho, z) profile polyline turning about the z axis.

    The polyline runs counter-clockwise round the solid's half-section from a
    point on the axis to another point on the axis (the axis closes it but is
    no surface). ``segment_labels`` labels each segment; a point takes the
    label of the nearest one.
    """

    profile: np.ndarray
    segment_labels: np.ndarray

    def __post_init__(self):
        from scipy.spatial import cKDTree

        tangent = np.diff(self.profile, axis=0)
        self._segment_normals = unit(np.stack([tangent[:, 1], -tangent[:, 0]], axis=1))
        # pseudo-normals at the vertices give the right inside/outside sign when the nearest point is a vertex
        padded = np.concatenate([self._segment_normals[:1], self._segment_normals, self._segment_normals[-1:]])
        self._vertex_normals = unit(padded[:-1] + padded[1:])
        self._tree = cKDTree(self.profile)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        r = self.profile[:, 0].max()
        return np.array([-r, -r, self.profile[:, 1].min()]), np.array([r, r, self.profile[:, 1].max()])

    def _nearest(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance in the half-section, and the nearest segment, of each point."""
        q = np.stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]], axis=1)
        # the two segments at the nearest vertex hold a locally nearest point, where the sign test is right;
        # on the finely resampled profile its distance is the true one near the surface
        _, vertex = self._tree.query(q)
        candidates = np.clip(np.stack([vertex - 1, vertex], axis=1), 0, len(self.profile) - 2)
        a = self.profile[candidates]
        ab = self.profile[candidates + 1] - a
        rel = q[:, None, :] - a
        t = np.clip((rel * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
        offset = rel - t[..., None] * ab
        dist = np.linalg.norm(offset, axis=-1)
        rows = np.arange(len(q))
        pick = dist.argmin(axis=1)
        segment, t, offset = candidates[rows, pick], t[rows, pick], offset[rows, pick]
        normal = np.where(
            (t <= 0.0)[:, None], self._vertex_normals[segment],
            np.where((t >= 1.0)[:, None], self._vertex_normals[segment + 1], self._segment_normals[segment]),
        )
        sign = np.where((offset * normal).sum(axis=1) < 0, -1.0, 1.0)
        return sign * dist[rows, pick], segment

    def distance(self, p: np.ndarray) -> np.ndarray:
        return self._nearest(p)[0]

    def labels(self, p: np.ndarray) -> np.ndarray:
        return self.segment_labels[self._nearest(p)[1]]


@dataclass
class TubePath:
    """A tube of radius ``radius`` along the polyline ``path`` (P, 3), with round ends."""

    path: np.ndarray
    radius: float
    label: int

    def distance(self, p: np.ndarray) -> np.ndarray:
        a, ab = self.path[:-1], np.diff(self.path, axis=0)
        rel = p[:, None, :] - a[None]
        t = np.clip((rel * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
        return np.linalg.norm(rel - t[..., None] * ab, axis=-1).min(axis=1) - self.radius

    def labels(self, p: np.ndarray) -> np.ndarray:
        return np.full(len(p), self.label)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.path.min(axis=0) - self.radius, self.path.max(axis=0) + self.radius


def smooth_min(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum: a fillet of size about ``k``; equals min(a, b) where they differ by more than k."""
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.minimum(a, b) - 0.25 * k * h * h


@dataclass
class Junction:
    """Where the tessellation is refined (where parts meet): a point, or a horizontal ring about the z axis.

    ``reach`` is the distance over which the refinement fades; ``ring_radius`` > 0 makes a ring.
    """

    centre: np.ndarray
    reach: float
    ring_radius: float = 0.0

    def nearest(self, p: np.ndarray) -> np.ndarray:
        if self.ring_radius == 0.0:
            return np.broadcast_to(self.centre, p.shape)
        scale = self.ring_radius / np.maximum(np.hypot(p[:, 0], p[:, 1]), 1e-9)
        return np.stack([p[:, 0] * scale, p[:, 1] * scale, np.full(len(p), self.centre[2])], axis=1)


@dataclass
class Shape:
    """A shape before meshing: parts in blend order, the fillet size of each later part, junctions, genus."""

    parts: list
    blends: list[float]
    junctions: list[Junction]
    genus: int

    def field(self, p: np.ndarray) -> np.ndarray:
        """The implicit function: negative inside, roughly the distance to the surface."""
        value = self.parts[0].distance(p)
        for part, k in zip(self.parts[1:], self.blends):
            lower, upper = part.bounds()
            box_gap = np.linalg.norm(np.maximum(np.maximum(lower - p, p - upper), 0.0), axis=1)
            # a part farther than value + k leaves the smooth minimum as it is: skip those points
            near = np.flatnonzero(box_gap < value + k)
            value[near] = smooth_min(value[near], part.distance(p[near]), k)
        return value

    def labels(self, p: np.ndarray) -> np.ndarray:
        """The label of the part nearest to each point."""
        nearest = np.stack([part.distance(p) for part in self.parts]).argmin(axis=0)
        out = np.empty(len(p), dtype=np.int64)
        for i, part in enumerate(self.parts):
            chosen = nearest == i
            if chosen.any():
                out[chosen] = part.labels(p[chosen])
        return out

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lows, highs = zip(*(part.bounds() for part in self.parts))
        return np.min(lows, axis=0), np.max(highs, axis=0)
