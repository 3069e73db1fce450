"""Numba kernels of :mod:`photo3d.mesh._simplify`: vertex kinds, quadrics, and the
collapse passes (see that module for the method).

Kernels inline their helpers: keep every helper in this file, or numba's on-disk
cache (keyed by the kernel file's timestamp) would not see a helper change.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_MANIFOLD, _BORDER, _SEAM, _LOCKED = 0, 1, 2, 3
# _CAN_COLLAPSE[k0, k1]: a vertex of kind k0 may collapse onto one of kind k1
_CAN_COLLAPSE = np.array([[1, 1, 1, 1], [0, 1, 0, 1], [0, 0, 1, 1], [0, 0, 0, 0]], np.uint8)
# _HAS_OPPOSITE[k0, k1]: an edge between these kinds is in two triangles (as a position
# edge), so it is listed twice
_HAS_OPPOSITE = np.array([[1, 1, 1, 1], [1, 0, 1, 0], [1, 1, 1, 1], [1, 0, 1, 0]], np.uint8)
_BORDER_WEIGHT = 10.0  # border edges keep their place; seams move more freely (1)
_MAX_PASSES = 200


@njit(cache=True, nogil=True)
def collapse_part(points, faces, leader, lock, limit, drift):
    """The faces of one strip simplified: its vertices numbered apart (so the passes
    touch only them), then :func:`_collapse`.

    Args:
        points: ``(N, 3) float32`` every vertex of the mesh.
        faces: ``(F, 3) int64`` the strip's faces.
        leader: ``(N,) int64`` the first vertex at each vertex's place (seams).
        lock: ``(N,) bool`` vertices that must stay.
        limit: the squared error bound.
        drift: the texture-drift bound (0: none).

    Returns:
        ``(F', 3) int64`` the simplified faces, in global vertex numbers.
    """
    mark = np.zeros(len(points), np.bool_)
    for f in range(len(faces)):
        for c in range(3):
            mark[faces[f, c]] = True
    local = np.full(len(points), -1, np.int64)
    used = np.empty(len(points), np.int64)
    n = 0
    for v in range(len(points)):  # the faces' vertices in increasing order
        if mark[v]:
            local[v] = n
            used[n] = v
            n += 1
    used = used[:n]
    tri = np.empty(faces.shape, np.int32)  # int32 inside: half the memory traffic
    for f in range(len(faces)):
        for c in range(3):
            tri[f, c] = local[faces[f, c]]
    # position leader: the first local vertex of each place (local order is global order)
    first = np.full(len(points), -1, np.int64)
    remap = np.empty(n, np.int32)
    for i in range(n):
        g = leader[used[i]]
        if first[g] < 0:
            first[g] = i
        remap[i] = first[g]
    out = _collapse(points[used], tri, remap, lock[used], limit, drift)
    result = np.empty(out.shape, np.int64)
    for f in range(len(out)):
        for c in range(3):
            result[f, c] = used[out[f, c]]
    return result


@njit(cache=True, nogil=True)
def _adjacency(tri, n_tri, remap, offsets, ends):
    """Fill the half-edges of ``tri[:n_tri]`` by start vertex (``remap``-ed):
    ``offsets (n + 1,)`` into ``ends (>= 3 n_tri, 2) int32``, each half-edge's end and
    its triangle's third vertex."""
    offsets[:] = 0
    for t in range(n_tri):
        for k in range(3):
            offsets[remap[tri[t, k]] + 1] += 1
    for v in range(len(offsets) - 1):
        offsets[v + 1] += offsets[v]
    fill = offsets[:-1].copy()
    for t in range(n_tri):
        for k in range(3):
            v = remap[tri[t, k]]
            j = fill[v]
            fill[v] += 1
            ends[j, 0] = remap[tri[t, (k + 1) % 3]]
            ends[j, 1] = remap[tri[t, (k + 2) % 3]]


@njit(cache=True, nogil=True)
def _classify(tri, n, remap, wedge, lock):
    """``(kind (n,) uint8, loop (n,), loopback (n,))``: each vertex's kind and, for
    border and seam vertices, the next and previous vertex along its open loop."""
    offsets = np.empty(n + 1, np.int64)
    ends = np.empty((3 * len(tri), 2), np.int32)
    _adjacency(tri, len(tri), np.arange(n).astype(np.int32), offsets, ends)
    loop = np.full(n, -1, np.int32)  # open out-edge's end; the vertex itself: several
    loopback = np.full(n, -1, np.int32)
    for v in range(n):
        for j in range(offsets[v], offsets[v + 1]):
            t = ends[j, 0]
            if t == v:
                loop[v] = loopback[v] = v
                continue
            closed = False
            for i in range(offsets[t], offsets[t + 1]):
                if ends[i, 0] == v:
                    closed = True
                    break
            if not closed:
                loopback[t] = v if loopback[t] == -1 else t
                loop[v] = t if loop[v] == -1 else v
    kind = np.empty(n, np.uint8)
    for i in range(n):
        if remap[i] != i:
            kind[i] = kind[remap[i]]
            continue
        kind[i] = _LOCKED
        if wedge[i] == i:
            a, b = loopback[i], loop[i]
            if a == -1 and b == -1:
                kind[i] = _MANIFOLD
            elif a != -1 and b != -1 and a != i and b != i:
                kind[i] = _BORDER
        elif wedge[wedge[i]] == i:
            w = wedge[i]
            iv, ov, iw, ow = loopback[i], loop[i], loopback[w], loop[w]
            if (iv != -1 and iv != i and ov != -1 and ov != i
                    and iw != -1 and iw != w and ow != -1 and ow != w
                    and remap[iv] == remap[ow] and remap[ov] == remap[iw]
                    and remap[iv] != remap[ov]):
                kind[i] = _SEAM
    for i in range(n):
        if lock[i]:
            kind[remap[i]] = _LOCKED
    for i in range(n):
        kind[i] = kind[remap[i]]
    return kind, loop, loopback


@njit(cache=True, nogil=True)
def _add_plane(q, v, a, b, c, d, w):
    """Add the plane ``a x + b y + c z + d = 0`` with weight ``w`` to quadric ``q[v]``
    (a00 a11 a22 a10 a20 a21 b0 b1 b2 c w)."""
    q[v, 0] += a * a * w
    q[v, 1] += b * b * w
    q[v, 2] += c * c * w
    q[v, 3] += a * b * w
    q[v, 4] += a * c * w
    q[v, 5] += b * c * w
    q[v, 6] += a * d * w
    q[v, 7] += b * d * w
    q[v, 8] += c * d * w
    q[v, 9] += d * d * w
    q[v, 10] += w


@njit(cache=True, nogil=True)
def _error(q, v, p, i):
    """Quadric ``q[v]`` at point ``p[i]``: weighted mean squared plane distance."""
    x, y, z = p[i, 0], p[i, 1], p[i, 2]
    r = (q[v, 0] * x * x + q[v, 1] * y * y + q[v, 2] * z * z
         + 2.0 * (q[v, 3] * x * y + q[v, 4] * x * z + q[v, 5] * y * z)
         + 2.0 * (q[v, 6] * x + q[v, 7] * y + q[v, 8] * z) + q[v, 9])
    return abs(r) / q[v, 10] if q[v, 10] > 0 else 0.0


@njit(cache=True, nogil=True)
def _cross(p, a, b, c):
    """``(p[b] - p[a]) x (p[c] - p[a])`` as three floats."""
    bx, by, bz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    cx, cy, cz = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1], p[c, 2] - p[a, 2]
    return by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx


@njit(cache=True, nogil=True)
def _quadrics(p, tri, remap, kind, loop, loopback):
    """``(n, 11) float64`` quadric of each place (at its leader): its triangles'
    planes, and the perpendicular planes of its border and seam edges."""
    q = np.zeros((len(p), 11))
    for t in range(len(tri)):
        a = tri[t, 0]
        nx, ny, nz = _cross(p, a, tri[t, 1], tri[t, 2])
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0:
            nx, ny, nz = nx / length, ny / length, nz / length
        d = -(nx * p[a, 0] + ny * p[a, 1] + nz * p[a, 2])
        for k in range(3):
            _add_plane(q, remap[tri[t, k]], nx, ny, nz, d, np.sqrt(length))
    for t in range(len(tri)):
        for e in range(3):
            i0, i1, i2 = tri[t, e], tri[t, (e + 1) % 3], tri[t, (e + 2) % 3]
            k0, k1 = kind[i0], kind[i1]
            open0 = k0 == _BORDER or k0 == _SEAM
            open1 = k1 == _BORDER or k1 == _SEAM
            if not (open0 or open1) or (open0 and loop[i0] != i1):
                continue
            if (open1 and loopback[i1] != i0) or (
                    _HAS_OPPOSITE[k0, k1] and remap[i1] > remap[i0]):
                continue
            ex, ey, ez = p[i1, 0] - p[i0, 0], p[i1, 1] - p[i0, 1], p[i1, 2] - p[i0, 2]
            fx, fy, fz = p[i2, 0] - p[i0, 0], p[i2, 1] - p[i0, 1], p[i2, 2] - p[i0, 2]
            lsq = ex * ex + ey * ey + ez * ez
            dot = fx * ex + fy * ey + fz * ez
            nx, ny, nz = fx * lsq - ex * dot, fy * lsq - ey * dot, fz * lsq - ez * dot
            norm = np.sqrt(nx * nx + ny * ny + nz * nz)
            if norm > 0:
                nx, ny, nz = nx / norm, ny / norm, nz / norm
            d = -(nx * p[i0, 0] + ny * p[i0, 1] + nz * p[i0, 2])
            w = np.sqrt(lsq) * (_BORDER_WEIGHT if k0 == _BORDER or k1 == _BORDER else 1.0)
            _add_plane(q, remap[i0], nx, ny, nz, d, w)
            _add_plane(q, remap[i1], nx, ny, nz, d, w)
    return q


@njit(cache=True, nogil=True)
def _spoils(p, root, offsets, ends, dest, r0, r1, drift):
    """Whether moving place ``r0`` onto ``r1`` turns one of its other triangles by
    more than about 75 degrees, or (``drift > 0``) gives one a new edge along which
    the texture drifts by more than ``drift`` (:func:`_drifts`; ``root``: square
    roots of ``p[:, 2]``; ``dest``: where this pass moved each place)."""
    for j in range(offsets[r0], offsets[r0 + 1]):
        a, b = dest[ends[j, 0]], dest[ends[j, 1]]
        if a == r1 or b == r1 or a == b:
            continue  # removed by this collapse, or by an earlier one
        x0, y0, z0 = _cross(p, a, b, r0)
        x1, y1, z1 = _cross(p, a, b, r1)
        dot = x0 * x1 + y0 * y1 + z0 * z1  # flipped: <= 0.25 |n0| |n1|
        if dot <= 0 or dot * dot <= 0.0625 * ((x0 * x0 + y0 * y0 + z0 * z0)
                                              * (x1 * x1 + y1 * y1 + z1 * z1)):
            return True
        if drift > 0 and (_drifts(p, root, r1, a, drift) or _drifts(p, root, r1, b, drift)):
            return True
    return False


@njit(cache=True, nogil=True)
def _drifts(p, root, a, b, drift):
    """Whether the texture drifts by more than ``drift`` along edge ``a b`` of points
    ``(column, row, v)``, ``v`` proportional to inverse depth (> 0; ``root``: its
    square roots). The renderer interpolates the texture coordinates (the pixel
    positions) linearly in 3D, i.e. weighted by ``v``, the photo's projection
    linearly in the image: at ``t`` they are ``t (1 - t) |d(x, y)| |dv| / ((1 - t)
    v_a + t v_b)`` apart, at most ``|d(x, y)| |dv| / (sqrt(v_a) + sqrt(v_b))^2``."""
    dx, dy, dv = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    r = root[a] + root[b]
    return (dx * dx + dy * dy) * dv * dv > drift * drift * (r * r) * (r * r)


@njit(cache=True, nogil=True)
def _order(err):
    """Indices sorting ``err (M,) float32 >= 0`` by its top 12 bits (counting sort,
    stable, as meshoptimizer's)."""
    bins = 2560
    key = np.empty(len(err), np.int64)
    bits = err.view(np.uint32)
    hist = np.zeros(bins + 1, np.int64)
    for i in range(len(err)):
        key[i] = min((np.int64(bits[i]) & 0x7FFFFFFF) >> 19, bins - 1)
        hist[key[i] + 1] += 1
    for b in range(bins):
        hist[b + 1] += hist[b]
    order = np.empty(len(err), np.int32)
    for i in range(len(err)):
        order[hist[key[i]]] = i
        hist[key[i]] += 1
    return order


@njit(cache=True, nogil=True)
def _pick(p, tri, n_tri, remap, kind, loop, loopback, q, c0, c1, err):
    """The candidate collapses ``c0[:m] -> c1[:m]`` and their errors ``err[:m]``:
    each edge once, in its cheaper allowed direction. Returns ``m``."""
    m = 0
    for t in range(n_tri):
        for e in range(3):
            i0, i1 = tri[t, e], tri[t, (e + 1) % 3]
            if remap[i0] == remap[i1]:
                continue
            k0, k1 = kind[i0], kind[i1]
            can01, can10 = _CAN_COLLAPSE[k0, k1], _CAN_COLLAPSE[k1, k0]
            if not (can01 or can10):
                continue
            if _HAS_OPPOSITE[k0, k1] and remap[i1] > remap[i0]:
                continue  # the other half-edge lists it
            if (k0 == _BORDER or k0 == _SEAM) and k1 != _MANIFOLD and loop[i0] != i1:
                continue  # two loops' vertices, not along a loop
            if (k1 == _BORDER or k1 == _SEAM) and k0 != _MANIFOLD and loopback[i1] != i0:
                continue
            if not can01:
                i0, i1 = i1, i0
            ei = _error(q, remap[i0], p, i1)
            if can01 and can10:
                ej = _error(q, remap[i1], p, i0)
                if ej < ei:
                    i0, i1, ei = i1, i0, ej
            c0[m], c1[m], err[m] = i0, i1, ei
            m += 1
    return m


@njit(cache=True, nogil=True)
def _perform(p, root, c0, c1, err, m, n_tri, remap, wedge, kind, loop, loopback,
             offsets, ends, moved, dest, touched, limit, drift, worst):
    """Carry out the cheapest of the ``m`` candidates, at most one per place, none
    that spoils a triangle (:func:`_spoils`), paced as meshoptimizer's passes:
    ``moved[v]`` is where vertex ``v`` goes, ``dest[r]`` where place ``r`` goes.
    Returns ``(collapses, worst)``, the largest error so far."""
    order = _order(err[:m])
    goal = n_tri // 2  # collapses wanted; the pace is 1.5 x the goal-th error
    removed = done = 0
    for o in range(m):
        c = order[o]
        if err[c] > limit:
            break
        pace = 1.5 * err[order[goal]] if goal < m else np.inf
        if err[c] > pace and err[c] > worst and removed > n_tri // 6:
            break
        i0, i1 = c0[c], c1[c]
        r0, r1 = remap[i0], remap[i1]
        if touched[r0] or touched[r1]:
            continue
        if _spoils(p, root, offsets, ends, dest, r0, r1, drift):
            goal += 1
            continue
        if kind[i0] == _SEAM:  # the partner on the other side moves along
            s0 = wedge[i0]
            s1 = loopback[s0] if loop[i0] == i1 else loop[s0]
            if s1 < 0 or remap[s1] != r1:
                continue
            moved[i0], moved[s0] = i1, s1
        else:
            moved[i0] = i1
        dest[r0] = r1
        touched[r0] = touched[r1] = True
        removed += 1 if kind[i0] == _BORDER else 2
        done += 1
        worst = max(worst, float(err[c]))
    return done, worst


@njit(cache=True, nogil=True)
def _apply(tri, n_tri, moved, remap, q, loop, loopback):
    """Apply a pass's ``moved`` to the quadrics, loops and triangles (dropping those
    that lost a corner). Returns the number of triangles."""
    for i in range(len(moved)):  # the moved places' quadrics join their targets'
        if moved[i] != i and remap[i] == i:
            for k in range(11):
                q[remap[moved[i]], k] += q[i, k]
    for lp in (loop, loopback):
        for i in range(len(moved)):
            if lp[i] >= 0:
                nx = moved[lp[i]]
                if nx == i:  # a seam edge collapsed against its loop's direction
                    lp[i] = moved[lp[lp[i]]] if lp[lp[i]] >= 0 else -1
                else:
                    lp[i] = nx
    w = 0
    for t in range(n_tri):
        a, b, c = moved[tri[t, 0]], moved[tri[t, 1]], moved[tri[t, 2]]
        if a != b and a != c and b != c:
            tri[w, 0], tri[w, 1], tri[w, 2] = a, b, c
            w += 1
    return w


@njit(cache=True, nogil=True)
def _collapse(p, tri, remap, lock, limit, drift):
    """``(F', 3) int32`` ``tri`` simplified (see the module docstring).

    Args:
        p: ``(n, 3) float64`` positions.
        tri: ``(F, 3) int32`` triangles.
        remap: ``(n,) int32`` the lowest vertex at each vertex's place.
        lock: ``(n,) bool`` vertices that must stay.
        limit: the bound on a collapse's quadric error (squared distance).
        drift: the bound on the texture drift along new edges (:func:`_drifts`); 0:
            none.
    """
    n = len(p)
    wedge = np.arange(n).astype(np.int32)  # a cycle through the vertices at each place
    for i in range(n):
        r = remap[i]
        if r != i:
            wedge[i] = wedge[r]
            wedge[r] = i
    kind, loop, loopback = _classify(tri, n, remap, wedge, lock)
    q = _quadrics(p, tri, remap, kind, loop, loopback)
    root = np.sqrt(np.maximum(p[:, 2], 0.0))
    tri = tri.copy()
    n_tri = len(tri)
    moved = np.empty(n, np.int32)
    dest = np.empty(n, np.int32)
    touched = np.empty(n, np.bool_)
    offsets = np.empty(n + 1, np.int64)
    ends = np.empty((3 * n_tri, 2), np.int32)
    c0 = np.empty(3 * n_tri, np.int32)
    c1 = np.empty(3 * n_tri, np.int32)
    err = np.empty(3 * n_tri, np.float32)
    worst = 0.0  # the largest error accepted so far
    for _ in range(_MAX_PASSES):
        m = _pick(p, tri, n_tri, remap, kind, loop, loopback, q, c0, c1, err)
        if m == 0:
            break
        for i in range(n):
            moved[i] = dest[i] = i
            touched[i] = False
        _adjacency(tri, n_tri, remap, offsets, ends)
        done, worst = _perform(p, root, c0, c1, err, m, n_tri, remap, wedge, kind, loop,
                               loopback, offsets, ends, moved, dest, touched, limit, drift,
                               worst)
        if done == 0:
            break
        n_tri = _apply(tri, n_tri, moved, remap, q, loop, loopback)
    # triangles with two corners at one place (a vertex collapsed onto both sides of a
    # seam) go last: removing them earlier would break the loops
    w = 0
    for t in range(n_tri):
        a, b, c = remap[tri[t, 0]], remap[tri[t, 1]], remap[tri[t, 2]]
        if a != b and a != c and b != c:
            tri[w, 0], tri[w, 1], tri[w, 2] = tri[t, 0], tri[t, 1], tri[t, 2]
            w += 1
    return tri[:w].copy()


KERNELS = ((collapse_part, "(float64[:, ::1], int64[:, ::1], int64[::1], boolean[::1], float64, "
                           "float64)"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""
