"""The collapse engine: numba loops over flat arrays that do the collapses of :func:`anseg.collapse.downsample` and undo them.

Faces (F, 3) keep their row for life (dead rows are flagged, not removed);
each vertex holds a singly linked list of its face corners (corner ``3 * f +
k`` is ``faces[f, k]``), spliced onto the kept vertex's list when two
vertices merge. :func:`downsample_core` runs the passes (the rules are
:mod:`anseg.collapse`'s); :func:`undo_connectivity`,
:func:`resolve_fine_to_coarse` and :func:`vote_reappearing` read a record
backwards. Everything here is compiled and cached by numba; the Python side
(checks, the record, the public API) is :mod:`anseg.collapse`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def build_incidence(faces, n_vertices):
    """Per-vertex linked lists of face corners: head[v] -> corner -> next[corner] ... -> -1."""
    head = np.full(n_vertices, -1, np.int64)
    nxt = np.full(3 * faces.shape[0], -1, np.int64)
    for corner in range(3 * faces.shape[0]):
        v = faces[corner // 3, corner % 3]
        nxt[corner] = head[v]
        head[v] = corner
    return head, nxt


@njit(cache=True)
def first_overshared_edge_face(faces, head, nxt):
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
def downsample_core(vertices, faces, scores, shortest_edge_first, target, cos_max, min_quality, once_per_pass=False):
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
    head, nxt = build_incidence(faces, n_vertices)
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
def undo_connectivity(faces, vertices, kept, removed, removed_faces, removed_face_vertices, old_positions, ptr, corners):
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
def resolve_fine_to_coarse(face_map, removed_faces, neighbors):
    """Give each removed face the map of a face across one of its outer edges, latest collapse first."""
    for t in range(removed_faces.shape[0] - 1, -1, -1):
        for j in range(2):
            across = neighbors[t, j, 0] if neighbors[t, j, 0] >= 0 else neighbors[t, j, 1]
            face_map[removed_faces[t, j]] = face_map[across]


@njit(cache=True)
def vote_reappearing(probs, removed_faces, neighbors):
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
