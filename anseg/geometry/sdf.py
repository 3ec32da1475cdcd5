"""The Shape Diameter Function (Shapira et al. 2008): how thick the shape is under each face.

From each face's centroid, rays spread evenly over a cone around the inward
normal; misses and hits that enter a surface from outside are dropped, the
rays further than one standard deviation from the face's median rejected,
and the rest averaged with cosine weights. The ray pattern is laid out in a
frame built from the face's own edges, so the values turn with the mesh.
Rays go to our BVH caster (:mod:`anseg.geometry.rays`), or to embree on a mesh above
:data:`anseg.geometry.proxy.LARGE_MESH_FACES` faces. :mod:`anseg.features` turns the
values into its ``sdf`` group.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import partial

import numpy as np

from anseg.geometry import proxy, rays
from anseg.mesh import Mesh

RAY_OFFSET = 1e-7  # rays start this far inside the surface, so that they do not hit their own face
RAYS_PER_CALL = 1 << 20  # bounds the memory of the ray arrays on big meshes


def cone_pattern(n_rays: int, cone_degrees: float) -> np.ndarray:
    """(n_rays, 3) directions spread evenly (golden-angle spiral) over a cap around +z."""
    half = np.radians(cone_degrees) / 2.0
    i = np.arange(n_rays) + 0.5
    cos_polar = 1.0 - i / n_rays * (1.0 - np.cos(half))
    sin_polar = np.sqrt(1.0 - cos_polar**2)
    azimuth = i * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([sin_polar * np.cos(azimuth), sin_polar * np.sin(azimuth), cos_polar], axis=1)


def shape_diameter(mesh: Mesh, outward: np.ndarray, tangent: np.ndarray, n_rays: int, cone_degrees: float,
                   threads: int = 1, beside: Callable[[], object] | None = None) -> np.ndarray:
    """(F,) SDF of every face: a cone of ``n_rays`` rays from its centroid around the inward normal.

    ``outward`` are the face normals pointing out of the shape, ``tangent`` an
    in-plane unit axis per face; ``threads`` is what the ray casters may use.
    ``beside`` runs on a second thread during the first cast of rays (our
    caster releases the GIL, so work that holds it can overlap); what it
    raises is raised here.
    """
    pattern = cone_pattern(n_rays, cone_degrees)
    inward = -outward
    frame = np.stack([tangent, np.cross(inward, tangent), inward], axis=1)  # (F, 3 axes, 3)
    cast = (rays.embree_caster(mesh, threads) if mesh.n_faces > proxy.LARGE_MESH_FACES
            else partial(rays.first_hits, rays.build_bvh(mesh.vertices, mesh.faces)))
    n_faces, n_rays = mesh.n_faces, len(pattern)
    lengths = np.full((n_faces, n_rays), np.nan)
    chunk = max(1, RAYS_PER_CALL // n_rays)
    for start in range(0, n_faces, chunk):
        rows = np.arange(start, min(start + chunk, n_faces))
        directions = np.einsum("rk,fkd->frd", pattern, frame[rows]).reshape(-1, 3)
        origins = np.repeat(mesh.face_centroids[rows] + RAY_OFFSET * inward[rows], n_rays, axis=0)
        if beside is None:
            hit_face, t = cast(origins, directions)
        else:
            with ThreadPoolExecutor(1) as pool:
                job = pool.submit(beside)
                hit_face, t = cast(origins, directions)
                job.result()
            beside = None
        hit = (hit_face >= 0) & (hit_face != np.repeat(rows, n_rays))
        # a ray from inside leaves through a surface facing along it; a front-facing hit means it started outside
        leaving = np.zeros_like(hit)
        leaving[hit] = (outward[hit_face[hit]] * directions[hit]).sum(axis=1) > 0
        lengths[rows] = np.where(hit & leaving, t, np.nan).reshape(-1, n_rays)
    return robust_ray_mean(lengths, pattern[:, 2])


def robust_ray_mean(lengths: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Cosine-weighted mean of the rays within one standard deviation of each face's median; misses are NaN."""
    hits = np.isfinite(lengths)
    has_hit = hits.any(axis=1)
    sdf = np.empty(len(lengths))
    valid = lengths[has_hit]
    median = np.nanmedian(valid, axis=1, keepdims=True)
    spread = np.nanstd(valid, axis=1, keepdims=True)
    # at least the middle rays always pass (half the rays lie on either side, so spread >= their gap / 2)
    keep = np.abs(valid - median) <= spread * (1.0 + 1e-9) + 1e-12
    w = np.where(keep, weights[None, :], 0.0)
    sdf[has_hit] = (np.where(keep, valid, 0.0) * w).sum(axis=1) / w.sum(axis=1)
    # every ray escaped (open surface): locally unbounded, so take the thickest value seen, or the unit length of the mesh
    sdf[~has_hit] = sdf[has_hit].max() if has_hit.any() else 1.0
    return sdf
