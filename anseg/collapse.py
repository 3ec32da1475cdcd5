"""Edge-collapse downsampling and its exact record (chains of records, pooling and upsampling: :mod:`anseg.hierarchy`).

The paper's attentive edge collapse (section III-B, Fig. 3): take the alive face with the least
score, collapse the edge it shares with its least-score neighbour to the midpoint (both faces
vanish) and repeat until ``round(ratio * faces in)`` faces are left (or one more). Where the paper is silent:

* **Valid collapses only**, so the coarse mesh stays a sound surface: the link condition (no closed
  component below four faces), no normal turning past ``max_normal_flip_deg``, no face pushed below
  ``MIN_FACE_QUALITY``. Only edges shared by two faces collapse (the paper's rule): boundaries stay.
* **Selection** (``nonuniform``): one walk over the faces by rising score (ties by face index),
  each trying its neighbours by rising score; faces keep their score. Passes repeat while they
  make progress; one without progress stops with a ``CollapseWarning`` and ``reached_target = False``.
* ``uniform``: shortest edge first (a lazily updated heap), which evens out edge lengths: the
  attention-free baseline. ``priority="weighted"``: the same heap keyed by squared length times the
  face's score, so a low-score region thins out to edge lengths of about 1/sqrt(score) instead of
  merging into a few giant faces; the paper's ``"score"`` walk is the default. ``random``: a control.

The :class:`CollapseRecord` stores every collapse, so undoing them in reverse gives back the input
mesh exactly (:meth:`CollapseRecord.replay`), maps every input face to its coarse face
(:attr:`CollapseRecord.fine_to_coarse`) and carries probabilities back (:func:`upsample`: a face
that reappears takes the normalised sum of the faces across its two outer edges, the paper's vote).
The loops run in numba over flat arrays. Why the flip limit defaults to 60 degrees: ``docs/decisions.md``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numba import njit

from anseg.mesh import Mesh, MeshError

# how a collapse picks its edges (the engine's modes; "random" is a control), and the nonuniform mode's orders
COLLAPSE_MODES = ("nonuniform", "uniform", "random")
PRIORITIES = ("score", "weighted")
MIN_FACE_QUALITY = 1e-3
"""A collapse may not push a face's ``2 * area / longest_edge**2`` below this
(equilateral: 0.87), unless the face was already worse before the collapse."""
_NO_BOUNDARY_RINGS = 1e6  # rings assigned when a mesh has a single label


class CollapseWarning(UserWarning):
    """Downsampling stopped above its target because no valid collapse was left."""


# --------------------------------------------------------------------------- numba core
@njit(cache=True)
def _build_incidence(faces, n_vertices):
    """Per-vertex linked lists of face corners: head[v] -> corner -> next[corner] ... -> -1."""
    head = np.full(n_vertices, -1, np.int64)
    nxt = np.full(3 * faces.shape[0], -1, np.int64)
    for corner in range(3 * faces.shape[0]):
        v = faces[corner // 3, corner % 3]
        nxt[corner] = head[v]
        head[v] = corner
    return head, nxt


@njit(cache=True)
def _first_overshared_edge_face(faces, head, nxt):
    """A face with an edge shared by more than two faces, or -1."""
    for f in range(faces.shape[0]):
        for k in range(3):
            u = faces[f, k]
            w = faces[f, (k + 1) % 3]
            count = 0
            corner = head[u]
            while corner != -1:
                h = corner // 3
                if faces[h, 0] == w or faces[h, 1] == w or faces[h, 2] == w:
                    count += 1
                corner = nxt[corner]
            if count > 2:
                return f
    return -1


@njit(cache=True)
def _third_vertex(faces, f, u, w):
    for k in range(3):
        x = faces[f, k]
        if x != u and x != w:
            return x
    return -1


@njit(cache=True)
def _face_across(faces, alive, head, nxt, f, u, w):
    """The alive face other than ``f`` that holds both ``u`` and ``w`` (walks u's corners), or -1."""
    corner = head[u]
    while corner != -1:
        h = corner // 3
        if h != f and alive[h] and (faces[h, 0] == w or faces[h, 1] == w or faces[h, 2] == w):
            return h
        corner = nxt[corner]
    return -1


@njit(cache=True)
def _compact(head, nxt, alive, v):
    """Drop the corners of dead faces from v's list."""
    new_head = -1
    corner = head[v]
    while corner != -1:
        following = nxt[corner]
        if alive[corner // 3]:
            nxt[corner] = new_head
            new_head = corner
        corner = following
    head[v] = new_head


@njit(cache=True)
def _normal_and_quality(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Unnormalised normal (x, y, z), its length (twice the area) and 2 * area / longest_edge**2."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - ax, cy - ay, cz - az
    wx, wy, wz = cx - bx, cy - by, cz - bz
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    longest = max(ux * ux + uy * uy + uz * uz, vx * vx + vy * vy + vz * vz, wx * wx + wy * wy + wz * wz)
    quality = norm / longest if longest > 0.0 else 0.0
    return nx, ny, nz, norm, quality


@njit(cache=True)
def _moved_face_ok(vertices, faces, h, v, tx, ty, tz, cos_max, min_quality):
    """Whether face h stays acceptable when its vertex v moves to (tx, ty, tz)."""
    i0, i1, i2 = faces[h, 0], faces[h, 1], faces[h, 2]
    ax, ay, az = vertices[i0, 0], vertices[i0, 1], vertices[i0, 2]
    bx, by, bz = vertices[i1, 0], vertices[i1, 1], vertices[i1, 2]
    cx, cy, cz = vertices[i2, 0], vertices[i2, 1], vertices[i2, 2]
    ox, oy, oz, old_norm, old_quality = _normal_and_quality(ax, ay, az, bx, by, bz, cx, cy, cz)
    if i0 == v:
        ax, ay, az = tx, ty, tz
    elif i1 == v:
        bx, by, bz = tx, ty, tz
    else:
        cx, cy, cz = tx, ty, tz
    nx, ny, nz, new_norm, new_quality = _normal_and_quality(ax, ay, az, bx, by, bz, cx, cy, cz)
    if new_norm == 0.0:
        return False
    if ox * nx + oy * ny + oz * nz < cos_max * old_norm * new_norm:
        return False
    return not (new_quality < min_quality and new_quality < old_quality)


@njit(cache=True)
def _collapse_allowed(vertices, faces, alive, head, nxt, mark_u, mark_w, stamp, f, g, u, w, c, d, cos_max, min_quality):
    """Check the link condition, boundary, tetrahedron, normal-flip and degeneracy rules.

    Edge ``uw`` between faces ``uwc`` and ``wud`` may collapse only if ``u`` and
    ``w`` have exactly ``c`` and ``d`` as common neighbours, not both lie on the
    boundary, faces ``ucd`` and ``wcd`` do not both exist (a tetrahedron), no
    moved face turns its normal past ``cos_max`` and no moved face's quality
    falls below ``min_quality`` unless it already was lower (never to zero).
    Returns (allowed, faces around u, faces around w).
    """
    deg_u = 0
    nbrs_u = 0
    u_has_cd_face = False
    corner = head[u]
    while corner != -1:
        h = corner // 3
        if alive[h]:
            deg_u += 1
            has_c = False
            has_d = False
            for k in range(3):
                y = faces[h, k]
                if y == c:
                    has_c = True
                elif y == d:
                    has_d = True
                elif y == w and h != f and h != g:
                    return False, 0, 0  # a third face on edge uw
                if y != u and mark_u[y] != stamp:
                    mark_u[y] = stamp
                    nbrs_u += 1
            if has_c and has_d:
                u_has_cd_face = True
        corner = nxt[corner]

    deg_w = 0
    nbrs_w = 0
    w_has_cd_face = False
    corner = head[w]
    while corner != -1:
        h = corner // 3
        if alive[h]:
            deg_w += 1
            has_c = False
            has_d = False
            for k in range(3):
                y = faces[h, k]
                if y == c:
                    has_c = True
                elif y == d:
                    has_d = True
                if y != w and mark_w[y] != stamp:
                    mark_w[y] = stamp
                    nbrs_w += 1
                    if y != u and mark_u[y] == stamp and y != c and y != d:
                        return False, 0, 0  # link condition: a third common neighbour
            if has_c and has_d:
                w_has_cd_face = True
        corner = nxt[corner]

    # in a vertex fan, one more neighbour than faces per open fan: the vertex lies on the boundary
    if nbrs_u > deg_u and nbrs_w > deg_w:
        return False, 0, 0
    if u_has_cd_face and w_has_cd_face:
        return False, 0, 0

    tx = 0.5 * (vertices[u, 0] + vertices[w, 0])
    ty = 0.5 * (vertices[u, 1] + vertices[w, 1])
    tz = 0.5 * (vertices[u, 2] + vertices[w, 2])
    for v in (u, w):
        corner = head[v]
        while corner != -1:
            h = corner // 3
            if alive[h] and h != f and h != g:
                if not _moved_face_ok(vertices, faces, h, v, tx, ty, tz, cos_max, min_quality):
                    return False, 0, 0
            corner = nxt[corner]
    return True, deg_u, deg_w


@njit(cache=True)
def _apply_collapse(vertices, faces, alive, head, nxt, f, g, a, b, c, d, t,
                    kept, removed, removed_faces, removed_face_vertices, old_positions, neighbors, ptr, corners):
    """Merge b into a at the midpoint, kill f and g, and write collapse t into the record arrays."""
    kept[t] = a
    removed[t] = b
    removed_faces[t, 0] = f
    removed_faces[t, 1] = g
    for k in range(3):
        removed_face_vertices[t, 0, k] = faces[f, k]
        removed_face_vertices[t, 1, k] = faces[g, k]
        old_positions[t, 0, k] = vertices[a, k]
        old_positions[t, 1, k] = vertices[b, k]
    # faces across the outer edges: alive after the collapse, they vote for f and g on the way back
    neighbors[t, 0, 0] = _face_across(faces, alive, head, nxt, f, c, b)
    neighbors[t, 0, 1] = _face_across(faces, alive, head, nxt, f, c, a)
    neighbors[t, 1, 0] = _face_across(faces, alive, head, nxt, g, d, b)
    neighbors[t, 1, 1] = _face_across(faces, alive, head, nxt, g, d, a)
    for k in range(3):
        vertices[a, k] = 0.5 * (vertices[a, k] + vertices[b, k])
    alive[f] = False
    alive[g] = False
    _compact(head, nxt, alive, a)
    _compact(head, nxt, alive, c)
    _compact(head, nxt, alive, d)
    n = ptr[t]
    corner = head[b]
    while corner != -1:
        following = nxt[corner]
        if alive[corner // 3]:
            faces[corner // 3, corner % 3] = a
            corners[n] = corner
            n += 1
            nxt[corner] = head[a]
            head[a] = corner
        corner = following
    head[b] = -1
    ptr[t + 1] = n


@njit(cache=True)
def _collapse_if_allowed(vertices, faces, alive, head, nxt, mark_u, mark_w, stamp, f, g, u, w, cos_max, min_quality,
                         t, kept, removed, removed_faces, removed_face_vertices, old_positions, neighbors, ptr, corners):
    """Collapse edge uw shared by f and g when allowed; returns (done, corners buffer, possibly grown)."""
    c = _third_vertex(faces, f, u, w)
    d = _third_vertex(faces, g, u, w)
    if c == -1 or d == -1 or c == d:
        return False, corners
    allowed, deg_u, deg_w = _collapse_allowed(vertices, faces, alive, head, nxt, mark_u, mark_w, stamp,
                                              f, g, u, w, c, d, cos_max, min_quality)
    if not allowed:
        return False, corners
    # remove the endpoint with fewer faces: fewer corners to re-point and record
    a, b = (u, w) if deg_w <= deg_u else (w, u)
    need = ptr[t] + max(deg_u, deg_w)
    if need > corners.shape[0]:
        grown = np.empty(max(2 * corners.shape[0], need), np.int64)
        grown[: ptr[t]] = corners[: ptr[t]]
        corners = grown
    _apply_collapse(vertices, faces, alive, head, nxt, f, g, a, b, c, d, t,
                    kept, removed, removed_faces, removed_face_vertices, old_positions, neighbors, ptr, corners)
    return True, corners


@njit(cache=True)
def _tried_before(scores, x, y):
    """Whether neighbour x comes before y: lower score first, then lower index, missing (-1) last."""
    if x == -1:
        return False
    if y == -1:
        return True
    return scores[x] < scores[y] or (scores[x] == scores[y] and x < y)


@njit(cache=True)
def _heap_push(keys, items, times, size, key, item, time):
    i = size
    while i > 0:
        parent = (i - 1) // 2
        if keys[parent] <= key:
            break
        keys[i] = keys[parent]
        items[i] = items[parent]
        times[i] = times[parent]
        i = parent
    keys[i] = key
    items[i] = item
    times[i] = time
    return size + 1


@njit(cache=True)
def _heap_pop(keys, items, times, size):
    """Remove the smallest entry; returns (item, time, new size)."""
    item = items[0]
    time = times[0]
    size -= 1
    key = keys[size]
    last_item = items[size]
    last_time = times[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and keys[child + 1] < keys[child]:
            child += 1
        if keys[child] >= key:
            break
        keys[i] = keys[child]
        items[i] = items[child]
        times[i] = times[child]
        i = child
    if size > 0:
        keys[i] = key
        items[i] = last_item
        times[i] = last_time
    return item, time, size


@njit(cache=True)
def _corner_edge_length2(vertices, faces, corner):
    u = faces[corner // 3, corner % 3]
    w = faces[corner // 3, (corner % 3 + 1) % 3]
    dx = vertices[u, 0] - vertices[w, 0]
    dy = vertices[u, 1] - vertices[w, 1]
    dz = vertices[u, 2] - vertices[w, 2]
    return dx * dx + dy * dy + dz * dz


@njit(cache=True)
def _downsample_core(vertices, faces, scores, shortest_edge_first, target, cos_max, min_quality, once_per_pass=False):
    """Collapse until ``target`` faces (or one above) are alive or no valid collapse is left.

    ``shortest_edge_first``: edges by squared length times their face's
    score (all ones: plain shortest edge first); otherwise faces in score order.

    ``once_per_pass`` (score order only): a face changed by a collapse (one
    around the kept vertex) takes part in no other collapse of the same pass.

    ``vertices`` and ``faces`` are modified in place; returns the alive flags,
    the record arrays truncated to the collapses made and the count of refused attempts.
    """
    n_faces = faces.shape[0]
    n_vertices = vertices.shape[0]
    head, nxt = _build_incidence(faces, n_vertices)
    alive = np.ones(n_faces, np.bool_)
    mark_u = np.full(n_vertices, -1, np.int64)
    mark_w = np.full(n_vertices, -1, np.int64)
    max_collapses = n_faces // 2 + 1
    kept = np.empty(max_collapses, np.int64)
    removed = np.empty(max_collapses, np.int64)
    removed_faces = np.empty((max_collapses, 2), np.int64)
    removed_face_vertices = np.empty((max_collapses, 2, 3), np.int64)
    old_positions = np.empty((max_collapses, 2, 3), np.float64)
    neighbors = np.empty((max_collapses, 2, 2), np.int64)
    ptr = np.zeros(max_collapses + 1, np.int64)
    corners = np.empty(3 * n_faces, np.int64)
    n_alive = n_faces
    t = 0
    stamp = 0
    refused = 0

    if not shortest_edge_first:
        order = np.argsort(scores, kind="mergesort")
        touched_in = np.full(n_faces, -1, np.int64)  # the pass in which a collapse last changed the face
        n_pass = 0
        while n_alive - target >= 2:
            collapses_before_pass = t
            n_pass += 1
            for i in range(n_faces):
                if n_alive - target < 2:
                    break
                f = order[i]
                if not alive[f] or touched_in[f] == n_pass:
                    continue
                g0 = _face_across(faces, alive, head, nxt, f, faces[f, 0], faces[f, 1])
                g1 = _face_across(faces, alive, head, nxt, f, faces[f, 1], faces[f, 2])
                g2 = _face_across(faces, alive, head, nxt, f, faces[f, 2], faces[f, 0])
                e0, e1, e2 = 0, 1, 2
                # three-element sort of the neighbours by (score, index)
                if _tried_before(scores, g1, g0):
                    g0, g1, e0, e1 = g1, g0, e1, e0
                if _tried_before(scores, g2, g1):
                    g1, g2, e1, e2 = g2, g1, e2, e1
                if _tried_before(scores, g1, g0):
                    g0, g1, e0, e1 = g1, g0, e1, e0
                for g, e in ((g0, e0), (g1, e1), (g2, e2)):
                    if g == -1:
                        break
                    if touched_in[g] == n_pass:
                        continue
                    stamp += 1
                    done, corners = _collapse_if_allowed(
                        vertices, faces, alive, head, nxt, mark_u, mark_w, stamp, f, g, faces[f, e], faces[f, (e + 1) % 3],
                        cos_max, min_quality, t, kept, removed, removed_faces, removed_face_vertices, old_positions,
                        neighbors, ptr, corners)
                    if done:
                        if once_per_pass:
                            corner = head[kept[t]]
                            while corner != -1:
                                touched_in[corner // 3] = n_pass
                                corner = nxt[corner]
                        t += 1
                        n_alive -= 2
                        break
                    refused += 1
            if t == collapses_before_pass:
                break
    else:
        capacity = 3 * n_faces + 16
        keys = np.empty(capacity, np.float64)
        items = np.empty(capacity, np.int64)
        times = np.empty(capacity, np.int64)
        moved_at = np.full(n_vertices, -1, np.int64)  # collapse index at which a vertex last moved
        size = 0
        collapses_at_fill = -1
        while n_alive - target >= 2:
            if size == 0:
                if t == collapses_at_fill:
                    break  # a full sweep since the last fill found nothing to collapse
                collapses_at_fill = t
                for corner in range(3 * n_faces):
                    if alive[corner // 3]:
                        size = _heap_push(keys, items, times, size,
                                          scores[corner // 3] * _corner_edge_length2(vertices, faces, corner), corner, t - 1)
            corner, time, size = _heap_pop(keys, items, times, size)
            f = corner // 3
            if not alive[f]:
                continue
            u = faces[f, corner % 3]
            w = faces[f, (corner % 3 + 1) % 3]
            if moved_at[u] > time or moved_at[w] > time:
                continue  # stale: an endpoint moved after this entry was pushed
            g = _face_across(faces, alive, head, nxt, f, u, w)
            if g == -1:
                continue
            stamp += 1
            done, corners = _collapse_if_allowed(
                vertices, faces, alive, head, nxt, mark_u, mark_w, stamp, f, g, u, w, cos_max, min_quality,
                t, kept, removed, removed_faces, removed_face_vertices, old_positions, neighbors, ptr, corners)
            if not done:
                refused += 1
                continue
            a = kept[t]
            moved_at[a] = t
            n_alive -= 2
            # re-push the edges around the moved vertex with their new lengths
            degree = 0
            corner = head[a]
            while corner != -1:
                degree += 1
                corner = nxt[corner]
            if size + 2 * degree > keys.shape[0]:
                new_capacity = 2 * keys.shape[0] + 2 * degree
                keys_grown = np.empty(new_capacity, np.float64)
                items_grown = np.empty(new_capacity, np.int64)
                times_grown = np.empty(new_capacity, np.int64)
                keys_grown[:size] = keys[:size]
                items_grown[:size] = items[:size]
                times_grown[:size] = times[:size]
                keys, items, times = keys_grown, items_grown, times_grown
            corner = head[a]
            while corner != -1:
                h = corner // 3
                before = 3 * h + (corner % 3 + 2) % 3  # the face's edge that ends at a
                size = _heap_push(keys, items, times, size, scores[h] * _corner_edge_length2(vertices, faces, corner), corner, t)
                size = _heap_push(keys, items, times, size, scores[h] * _corner_edge_length2(vertices, faces, before), before, t)
                corner = nxt[corner]
            t += 1

    return (alive, kept[:t].copy(), removed[:t].copy(), removed_faces[:t].copy(), removed_face_vertices[:t].copy(),
            old_positions[:t].copy(), neighbors[:t].copy(), ptr[: t + 1].copy(), corners[: ptr[t]].copy(), refused)


@njit(cache=True)
def _undo_connectivity(faces, vertices, kept, removed, removed_faces, removed_face_vertices, old_positions, ptr, corners):
    """Undo the collapses in reverse (vertex splits) in place; returns the first inconsistent step or -1."""
    for t in range(kept.shape[0] - 1, -1, -1):
        a = kept[t]
        b = removed[t]
        for i in range(ptr[t], ptr[t + 1]):
            f = corners[i] // 3
            k = corners[i] % 3
            if faces[f, k] != a:
                return t
            faces[f, k] = b
        for j in range(2):
            f = removed_faces[t, j]
            if faces[f, 0] != -1:
                return t
            for k in range(3):
                faces[f, k] = removed_face_vertices[t, j, k]
        for k in range(3):
            vertices[a, k] = old_positions[t, 0, k]
            vertices[b, k] = old_positions[t, 1, k]
    return -1


@njit(cache=True)
def _resolve_fine_to_coarse(face_map, removed_faces, neighbors):
    """Give each removed face the map of a face across one of its outer edges, latest collapse first."""
    for t in range(removed_faces.shape[0] - 1, -1, -1):
        for j in range(2):
            across = neighbors[t, j, 0] if neighbors[t, j, 0] >= 0 else neighbors[t, j, 1]
            face_map[removed_faces[t, j]] = face_map[across]


@njit(cache=True)
def _vote_reappearing(probs, removed_faces, neighbors):
    """Each reappearing face takes the normalised sum of its outer-edge neighbours' probabilities."""
    n_classes = probs.shape[1]
    for t in range(removed_faces.shape[0] - 1, -1, -1):
        for j in range(2):
            f = removed_faces[t, j]
            total = 0.0
            for c in range(n_classes):
                value = 0.0
                for i in range(2):
                    h = neighbors[t, j, i]
                    if h >= 0:
                        value += probs[h, c]
                probs[f, c] = value
                total += value
            if total > 0.0:
                for c in range(n_classes):
                    probs[f, c] /= total


# --------------------------------------------------------------------------- the record
@dataclass(eq=False, repr=False)
class CollapseRecord:
    """Every collapse of one :func:`downsample` call, enough to undo them exactly.

    Collapse ``t`` merged ``removed_vertex[t]`` into ``kept_vertex[t]`` (which
    moved to the midpoint), removed the faces ``removed_faces[t]`` whose
    vertices were ``removed_face_vertices[t]``, and re-pointed the corners
    ``repointed_corners[repointed_ptr[t]:repointed_ptr[t+1]]`` (corner
    ``3 * f + k`` is fine face f's k-th vertex). ``outer_neighbors[t, j]`` are
    the faces across the two other edges of ``removed_faces[t, j]`` (-1 on
    the boundary). All indices are fine (input) face and vertex indices:
    faces keep their identity, and coarse face i *is* fine face
    ``coarse_face_ids[i]`` (coarse vertex i likewise ``coarse_vertex_ids[i]``).
    """

    coarse: Mesh
    n_fine_faces: int
    n_fine_vertices: int
    target_faces: int
    reached_target: bool
    coarse_face_ids: np.ndarray
    coarse_vertex_ids: np.ndarray
    kept_vertex: np.ndarray
    removed_vertex: np.ndarray
    removed_faces: np.ndarray
    removed_face_vertices: np.ndarray
    old_positions: np.ndarray
    outer_neighbors: np.ndarray
    repointed_ptr: np.ndarray
    repointed_corners: np.ndarray
    unused_vertex_ids: np.ndarray
    unused_vertex_positions: np.ndarray

    def __repr__(self) -> str:
        return (f"CollapseRecord({self.n_fine_faces} -> {self.n_coarse_faces} faces, {self.n_collapses} collapses, "
                f"target {self.target_faces}{'' if self.reached_target else ' not reached'})")

    @property
    def n_collapses(self) -> int:
        return len(self.kept_vertex)

    @property
    def n_coarse_faces(self) -> int:
        return self.coarse.n_faces

    @cached_property
    def fine_to_coarse(self) -> np.ndarray:
        """(F_fine,) the coarse face that stands for each fine face.

        A surviving face maps to itself; a face removed by collapse t maps to
        where a face across one of its outer edges maps (that face is alive
        after step t), resolved from the last collapse back to the first.
        """
        face_map = np.full(self.n_fine_faces, -1, np.int64)
        face_map[self.coarse_face_ids] = np.arange(self.n_coarse_faces)
        _resolve_fine_to_coarse(face_map, self.removed_faces, self.outer_neighbors)
        return face_map

    def replay(self, coarse: Mesh | None = None) -> Mesh:
        """Undo the collapses in reverse, from ``coarse`` (default: the record's own coarse mesh).

        Returns the fine mesh: faces exactly as the input, vertices at their
        input positions. Raises ValueError when ``coarse`` does not match the record.
        """
        coarse = self.coarse if coarse is None else coarse
        if coarse.n_faces != len(self.coarse_face_ids) or coarse.n_vertices != len(self.coarse_vertex_ids):
            raise ValueError(
                f"coarse mesh has {coarse.n_faces} faces and {coarse.n_vertices} vertices; this record ends at "
                f"{len(self.coarse_face_ids)} faces and {len(self.coarse_vertex_ids)} vertices"
            )
        faces = np.full((self.n_fine_faces, 3), -1, np.int64)
        faces[self.coarse_face_ids] = self.coarse_vertex_ids[coarse.faces]
        vertices = np.zeros((self.n_fine_vertices, 3))
        vertices[self.coarse_vertex_ids] = coarse.vertices
        vertices[self.unused_vertex_ids] = self.unused_vertex_positions
        bad_step = _undo_connectivity(faces, vertices, self.kept_vertex, self.removed_vertex, self.removed_faces,
                                      self.removed_face_vertices, self.old_positions, self.repointed_ptr,
                                      self.repointed_corners)
        if bad_step >= 0:
            raise ValueError(f"coarse mesh does not match this record (undoing collapse {bad_step} found other faces)")
        return Mesh(vertices, faces)


# --------------------------------------------------------------------------- downsampling
def downsample(mesh: Mesh, scores=None, ratio: float = 0.5, mode: str = "nonuniform", seed: int = 0,
               max_normal_flip_deg: float = 60.0, once_per_pass: bool = False,
               priority: str = "score") -> tuple[Mesh, CollapseRecord]:
    """Collapse edges until ``round(ratio * mesh.n_faces)`` faces are left (or one more).

    ``mode``: ``"nonuniform"`` (least ``scores`` first, the paper's attentive
    rule; ``scores`` (F,) finite, required), ``"uniform"`` (shortest edge
    first) or ``"random"`` (static random scores from ``seed``). See the
    module docstring (in full: ``_collapse_allowed``) for the validity rules. When no valid collapse is left
    before the target, a :class:`CollapseWarning` is issued and
    ``record.reached_target`` is False. ``once_per_pass`` (score-ordered
    modes): a face that a collapse changed (one around the kept vertex) takes
    part in no further collapse of the same pass, so a region of low scores
    thins out over several passes instead of being merged into a few large
    faces in one. ``priority`` (nonuniform): ``"score"``, faces in order of
    rising score (the paper), or ``"weighted"``, edges by squared length
    times score (scores must then be positive; module docstring). The input mesh must be edge-manifold
    (boundaries and several components are fine); it is not modified.
    Returns the coarse mesh (alive faces in fine-index order, used vertices
    compacted) and the :class:`CollapseRecord`.
    """
    if mode not in COLLAPSE_MODES:
        raise ValueError(f"mode must be one of {COLLAPSE_MODES}, got {mode!r}")
    if priority not in PRIORITIES:
        raise ValueError(f"priority must be one of {PRIORITIES}, got {priority!r}")
    if not 0.0 < ratio <= 1.0:
        raise ValueError(f"ratio must lie in (0, 1], got {ratio}")
    if not 0.0 < max_normal_flip_deg <= 180.0:
        raise ValueError(f"max_normal_flip_deg must lie in (0, 180], got {max_normal_flip_deg}")
    n_faces = mesh.n_faces
    if mode == "nonuniform":
        if scores is None:
            raise ValueError("nonuniform mode needs per-face scores")
        scores = np.asarray(scores, dtype=np.float64)
        if scores.shape != (n_faces,):
            raise ValueError(f"scores must have shape ({n_faces},), one per face, got {scores.shape}")
        if not np.isfinite(scores).all():
            raise ValueError(f"scores must be finite; {int((~np.isfinite(scores)).sum())} are NaN or infinite")
        if priority == "weighted" and (scores <= 0).any():
            raise ValueError(f"weighted priority needs positive scores; {int((scores <= 0).sum())} are not")
    elif scores is not None:
        raise ValueError(f"scores are only used in nonuniform mode, not {mode!r}")
    elif mode == "random":
        scores = np.random.default_rng(seed).random(n_faces)
    else:
        scores = np.ones(n_faces)  # every edge weighs its plain length
    _check_input(mesh)

    vertices = mesh.vertices.copy()
    faces = mesh.faces.copy()
    target = int(round(ratio * n_faces))
    (alive, kept, removed, removed_faces, removed_face_vertices, old_positions, neighbors, ptr, corners,
     refused) = _downsample_core(vertices, faces, scores, mode == "uniform" or priority == "weighted", target,
                                 float(np.cos(np.radians(max_normal_flip_deg))), MIN_FACE_QUALITY, once_per_pass)

    coarse_face_ids = np.flatnonzero(alive)
    used = np.zeros(mesh.n_vertices, dtype=bool)
    used[faces[coarse_face_ids]] = True
    coarse_vertex_ids = np.flatnonzero(used)
    new_index = np.cumsum(used) - 1
    coarse = Mesh(vertices[coarse_vertex_ids], new_index[faces[coarse_face_ids]])
    used_in_input = np.zeros(mesh.n_vertices, dtype=bool)
    used_in_input[mesh.faces] = True
    unused_vertex_ids = np.flatnonzero(~used_in_input)

    reached = coarse.n_faces - target < 2
    if not reached:
        warnings.warn(
            f"downsample ({mode}) stopped at {coarse.n_faces} faces, target {target} (from {n_faces}): "
            f"no valid collapse left after {len(kept)} collapses and {refused} refused attempts",
            CollapseWarning, stacklevel=2,
        )
    record = CollapseRecord(
        coarse=coarse, n_fine_faces=n_faces, n_fine_vertices=mesh.n_vertices, target_faces=target,
        reached_target=reached, coarse_face_ids=coarse_face_ids, coarse_vertex_ids=coarse_vertex_ids,
        kept_vertex=kept, removed_vertex=removed, removed_faces=removed_faces,
        removed_face_vertices=removed_face_vertices, old_positions=old_positions, outer_neighbors=neighbors,
        repointed_ptr=ptr, repointed_corners=corners, unused_vertex_ids=unused_vertex_ids,
        unused_vertex_positions=mesh.vertices[unused_vertex_ids].copy(),
    )
    return coarse, record


def _check_input(mesh: Mesh) -> None:
    if mesh.n_faces == 0:
        raise MeshError("mesh has no faces")
    faces = mesh.faces
    if faces.min() < 0 or faces.max() >= mesh.n_vertices:
        raise MeshError(f"faces index vertices outside [0, {mesh.n_vertices})")
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    if repeated.any():
        raise MeshError(f"{int(repeated.sum())} faces repeat a vertex (first: {int(np.flatnonzero(repeated)[0])})")
    if not np.isfinite(mesh.vertices).all():
        raise MeshError("vertices have NaN or infinite coordinates")
    head, nxt = _build_incidence(faces, mesh.n_vertices)
    bad = _first_overshared_edge_face(faces, head, nxt)
    if bad >= 0:
        raise MeshError(f"face {bad} has an edge shared by more than two faces; downsample needs an edge-manifold mesh")


# --------------------------------------------------------------------------- carrying values back
def upsample(record: CollapseRecord, coarse_probs) -> np.ndarray:
    """Carry per-face class probabilities (F_coarse, C) back to the fine faces by replaying the record.

    A surviving face keeps its coarse face's row; a face that reappears in a
    vertex split takes the normalised sum of the rows of the faces across its
    two outer edges at that moment (ties are left as ties: argmax then
    picks the lowest class). Returns (F_fine, C).
    """
    coarse_probs = np.asarray(coarse_probs, dtype=np.float64)
    if coarse_probs.ndim != 2 or len(coarse_probs) != record.n_coarse_faces:
        raise ValueError(f"coarse_probs must have shape ({record.n_coarse_faces}, C), got {coarse_probs.shape}")
    if not np.isfinite(coarse_probs).all() or (coarse_probs < 0).any():
        raise ValueError("coarse_probs must be finite and non-negative")
    probs = np.zeros((record.n_fine_faces, coarse_probs.shape[1]))
    probs[record.coarse_face_ids] = coarse_probs
    _vote_reappearing(probs, record.removed_faces, record.outer_neighbors)
    return probs


def rings_to_other_label(mesh, labels) -> np.ndarray:
    """(F,) face-graph distance, in rings, from each face to the nearest face with another label (1 = adjacent).

    Faces near label boundaries are where a collapse loses labels: the oracle score
    of the round-trip study and the attention target of training both derive from this.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    pairs = mesh.face_adjacency
    differ = labels[pairs[:, 0]] != labels[pairs[:, 1]]
    sources = np.unique(pairs[differ])
    if len(sources) == 0:
        return np.full(mesh.n_faces, _NO_BOUNDARY_RINGS)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(mesh.n_faces,) * 2)
    # faces touching another label are 1 ring away from it; each further ring adds one
    return 1.0 + dijkstra(graph, directed=False, indices=sources, unweighted=True, min_only=True)
