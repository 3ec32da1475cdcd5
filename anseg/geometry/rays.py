"""First hits of rays on a triangle mesh: our bounding-volume tree (float64), and embree's for large meshes.

libigl's embree SDF averages a whole hemisphere of random rays (rand(), so not reproducible) and
hides the per-ray distances a cone and outlier rejection need; igl.AABB returns them but casts
on one thread at about 3 us a ray. This bounding-volume tree casts in parallel, 2-4x faster a core,
in float64; embree's first hits (:func:`embree_caster`) are faster still but float32, so large meshes only.

Both report, for each ray, the first face it hits from either side and the
distance along the (unit) direction.
"""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import njit, prange

from anseg.mesh import Mesh

BVH_LEAF = 4  # triangles per leaf of the tree


def build_bvh(vertices: np.ndarray, faces: np.ndarray) -> tuple:
    """A balanced bounding-volume tree over the triangles, stored level by level.

    Node j of level k holds leaves j 2^k .. (j+1) 2^k - 1; leaf j holds the
    sorted triangles 4j .. 4j+3. The order comes from median splits, top
    down, along the longest side of each node's centroid box.
    """
    triangles = vertices[faces]
    centre = triangles.mean(axis=1)
    n = len(faces)
    n_leaves = -(-n // BVH_LEAF)
    order = np.arange(n)
    for level in range(int(np.ceil(np.log2(n_leaves))) if n_leaves > 1 else 0, 0, -1):
        starts = np.arange(0, n, BVH_LEAF << level)
        node = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, n]))
        c = centre[order]
        low, high = np.minimum.reduceat(c, starts, axis=0), np.maximum.reduceat(c, starts, axis=0)
        axis = np.argmax(high - low, axis=1)
        # one sort for all nodes: node index plus the position along its axis scaled into [0, 0.5]
        position = (c[np.arange(n), axis[node]] - low[node, axis[node]]) / np.maximum((high - low)[node, axis[node]], 1e-300)
        order = order[np.argsort(node + 0.5 * position, kind="stable")]
    triangles = triangles[order]
    padded = np.r_[np.arange(n), np.full(n_leaves * BVH_LEAF - n, n - 1)]
    corners = triangles[padded].reshape(n_leaves, 3 * BVH_LEAF, 3)
    lows, highs = [corners.min(axis=1)], [corners.max(axis=1)]
    while len(lows[-1]) > 1:
        low, high = lows[-1], highs[-1]
        if len(low) % 2:
            low, high = np.vstack([low, low[-1:]]), np.vstack([high, high[-1:]])
        lows.append(np.minimum(low[0::2], low[1::2]))
        highs.append(np.maximum(high[0::2], high[1::2]))
    sizes = np.array([len(level) for level in lows], dtype=np.int64)
    offsets = np.r_[0, np.cumsum(sizes)[:-1]].astype(np.int64)
    corner = np.ascontiguousarray(triangles[:, 0])
    return (
        corner,
        np.ascontiguousarray(triangles[:, 1] - corner),
        np.ascontiguousarray(triangles[:, 2] - corner),
        order.astype(np.int64),
        np.vstack(lows),
        np.vstack(highs),
        offsets,
        sizes,
    )


def embree_caster(mesh: Mesh, threads: int = 1):
    """First hits through embree (embreex): 3x faster than our tree at 330K faces, in float32.

    Used above :data:`anseg.geometry.proxy.LARGE_MESH_FACES` only: on a 330K-face mesh it finds the
    same face for 99.998 % of the SDF rays, at distances within a relative
    5e-8, but those float32 distances would move the last bits of every
    stored feature of the benchmark meshes, and with them the stored runs.
    With ``threads`` above 1 the rays are split between them: embree's
    queries on a built scene are thread-safe and embreex lets go of the GIL
    (two threads cast 1M rays in 0.40-0.44 s against 0.79-0.86 s), and each
    ray's hit is its own, so the result does not depend on the split.
    """
    from embreex import mesh_construction, rtcore_scene

    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, mesh.vertices[mesh.faces].astype(np.float32))

    def cast(origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        origins, directions = origins.astype(np.float32), directions.astype(np.float32)
        bounds = np.linspace(0, len(origins), threads + 1).astype(int)
        with ThreadPoolExecutor(len(bounds) - 1) as pool:
            parts = list(pool.map(lambda a, b: scene.run(origins[a:b], directions[a:b], output=1), bounds[:-1], bounds[1:]))
        geometry, face, t = (np.concatenate([part[key] for part in parts]) for key in ("geomID", "primID", "tfar"))
        hit_face = np.where(geometry >= 0, face, -1).astype(np.int64)
        return hit_face, np.where(hit_face >= 0, t.astype(np.float64), np.inf)

    return cast


def first_hits(bvh: tuple, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face index (-1 for a miss) and distance (inf for a miss) of each ray's first hit, either side of a face."""
    hit_face = np.empty(len(origins), dtype=np.int64)
    hit_t = np.empty(len(origins))
    numba_threads()  # the kernel would start numba's threads otherwise, and change torch's count
    _cast_rays(np.ascontiguousarray(origins, dtype=np.float64),
               np.ascontiguousarray(directions, dtype=np.float64), *bvh, hit_face, hit_t)
    return hit_face, hit_t


def numba_threads() -> int:
    """numba's thread count; starts numba's threading layer with torch's thread count kept.

    numba's OpenMP layer, when it starts (the first parallel kernel or
    thread query of the process), sets the process's OpenMP thread count to
    numba's own (every core unless ``NUMBA_NUM_THREADS`` says otherwise,
    whatever ``OMP_NUM_THREADS`` says), and torch's matrix products read that
    count: without this, computing the SDF (a cold feature cache) would
    change how the network rounds later in the same process, and with it a
    hierarchy. Later kernels leave the count alone.
    """
    torch = sys.modules.get("torch")
    threads = torch.get_num_threads() if torch is not None else None
    count = numba.get_num_threads()
    if torch is not None and torch.get_num_threads() != threads:
        torch.set_num_threads(threads)
    return count


@njit(cache=True, inline="always")
def _box_entry(low, high, node, ox, oy, oz, ix, iy, iz, best):
    """Distance at which the ray enters the node's box, or inf when it misses it or enters beyond ``best``."""
    t1, t2 = (low[node, 0] - ox) * ix, (high[node, 0] - ox) * ix
    near, far = min(t1, t2), max(t1, t2)
    t1, t2 = (low[node, 1] - oy) * iy, (high[node, 1] - oy) * iy
    near, far = max(near, min(t1, t2)), min(far, max(t1, t2))
    t1, t2 = (low[node, 2] - oz) * iz, (high[node, 2] - oz) * iz
    near, far = max(near, min(t1, t2)), min(far, max(t1, t2))
    if near > far or far < 0.0 or near > best:
        return np.inf
    return near


@njit(cache=True, parallel=True, nogil=True)  # nogil: the AGD may run beside it (the features' sdf_with_agd_beside)
def _cast_rays(origins, directions, corner, edge1, edge2, order, low, high, offsets, sizes, hit_face, hit_t):
    n_rays, n_triangles = len(origins), len(corner)
    top = len(sizes) - 1
    block = 256
    for b in prange((n_rays + block - 1) // block):
        stack_level = np.empty(2 * top + 2, np.int64)
        stack_index = np.empty(2 * top + 2, np.int64)
        stack_near = np.empty(2 * top + 2)
        for r in range(b * block, min((b + 1) * block, n_rays)):
            ox, oy, oz = origins[r, 0], origins[r, 1], origins[r, 2]
            dx, dy, dz = directions[r, 0], directions[r, 1], directions[r, 2]
            ix = 1.0 / dx if dx != 0.0 else 1e300
            iy = 1.0 / dy if dy != 0.0 else 1e300
            iz = 1.0 / dz if dz != 0.0 else 1e300
            best, best_face = np.inf, -1
            stack_level[0], stack_index[0], stack_near[0] = top, 0, 0.0
            depth = 1
            while depth > 0:
                depth -= 1
                level, j = stack_level[depth], stack_index[depth]
                if stack_near[depth] > best:
                    continue
                if level == 0:  # Moller-Trumbore against the leaf's triangles
                    for k in range(j * 4, min(j * 4 + 4, n_triangles)):
                        px = dy * edge2[k, 2] - dz * edge2[k, 1]
                        py = dz * edge2[k, 0] - dx * edge2[k, 2]
                        pz = dx * edge2[k, 1] - dy * edge2[k, 0]
                        det = edge1[k, 0] * px + edge1[k, 1] * py + edge1[k, 2] * pz
                        if det == 0.0:
                            continue
                        inv = 1.0 / det
                        sx, sy, sz = ox - corner[k, 0], oy - corner[k, 1], oz - corner[k, 2]
                        u = (sx * px + sy * py + sz * pz) * inv
                        if u < 0.0 or u > 1.0:
                            continue
                        qx = sy * edge1[k, 2] - sz * edge1[k, 1]
                        qy = sz * edge1[k, 0] - sx * edge1[k, 2]
                        qz = sx * edge1[k, 1] - sy * edge1[k, 0]
                        v = (dx * qx + dy * qy + dz * qz) * inv
                        if v < 0.0 or u + v > 1.0:
                            continue
                        t = (edge2[k, 0] * qx + edge2[k, 1] * qy + edge2[k, 2] * qz) * inv
                        if 0.0 < t < best:
                            best, best_face = t, order[k]
                    continue
                child = 2 * j
                first = offsets[level - 1] + child
                near0 = _box_entry(low, high, first, ox, oy, oz, ix, iy, iz, best)
                near1 = np.inf
                if child + 1 < sizes[level - 1]:
                    near1 = _box_entry(low, high, first + 1, ox, oy, oz, ix, iy, iz, best)
                # push the farther child first so that the nearer one is searched first
                for q in (0, 1) if near0 >= near1 else (1, 0):
                    near = near0 if q == 0 else near1
                    if near < np.inf:
                        stack_level[depth], stack_index[depth], stack_near[depth] = level - 1, child + q, near
                        depth += 1
            hit_face[r], hit_t[r] = best_face, best
