"""Numba kernels of :mod:`photo3d.mesh.light`: merge planar blocks before simplifying.

The simplifier's cost grows with the triangles it is given (3 million for a 1024 px
photo, most of the save time). Most of them lie in blocks of the lattice whose
surface is a plane to well within the light mesh's error bound; such a block's
``2 b^2`` triangles are replaced by a fan of at most ``4 b`` triangles from its centre pixel
to the pixels on its border that its neighbours also use (corners of blocks,
vertices of kept faces), so the block still meets its neighbours (merged or not) at
the same vertices: no cracks, no T-junctions. Blocks are tried in a quadtree
(``b`` = 32 down to 2) per layer image.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def quad_counts(faces, face_layer, py, px, n_layers, rows, cols):
    """``(L, rows * cols) uint8`` faces of layer image ``l`` in the lattice quad whose
    top-left corner is at each position (2: the quad is whole).

    Example:
        >>> faces = np.array([[0, 2, 1], [1, 2, 3]], np.int32)
        >>> py, px = np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1])
        >>> quad_counts(faces, np.zeros(2, np.int64), py, px, 1, 2, 2).tolist()
        [[2, 0, 0, 0]]
    """
    cnt = np.zeros((n_layers, rows * cols), np.uint8)  # here: an allocation in a kernel
    _quad_counts(faces, face_layer, py, px, cols, cnt)   # compiles on the first run
    return cnt


@njit(cache=True, nogil=True)
def _quad_counts(faces, face_layer, py, px, cols, cnt):
    """:func:`quad_counts` added to ``cnt``."""
    for f in range(len(faces)):
        y0 = min(py[faces[f, 0]], py[faces[f, 1]], py[faces[f, 2]])
        y1 = max(py[faces[f, 0]], py[faces[f, 1]], py[faces[f, 2]])
        x0 = min(px[faces[f, 0]], px[faces[f, 1]], px[faces[f, 2]])
        x1 = max(px[faces[f, 0]], px[faces[f, 1]], px[faces[f, 2]])
        if y1 - y0 == 1 and x1 - x0 == 1:
            cnt[face_layer[f], y0 * cols + x0] += 1


@njit(cache=True, nogil=True)
def _planar(images, k, value, y0, x0, b, cols, eps):
    """Whether ``value`` at the ``(b+1)^2`` pixels of block ``(y0, x0, b)`` of layer
    image ``k`` is a plane in (x, y) to within ``eps`` (least squares)."""
    n = (b + 1) * (b + 1)
    c = b / 2.0
    mean = 0.0
    sx = 0.0
    sy = 0.0
    for y in range(b + 1):
        for x in range(b + 1):
            v = value[images[k, (y0 + y) * cols + x0 + x]]
            mean += v
            sx += (x - c) * v
            sy += (y - c) * v
    s2 = 0.0
    for x in range(b + 1):
        s2 += (x - c) * (x - c)
    s2 *= b + 1
    mean /= n
    gx = sx / s2
    gy = sy / s2
    for y in range(b + 1):
        for x in range(b + 1):
            v = value[images[k, (y0 + y) * cols + x0 + x]]
            if abs(v - mean - gx * (x - c) - gy * (y - c)) > eps:
                return False
    return True


@njit(cache=True, nogil=True)
def _whole(cnt, k, y0, x0, b, cols):
    """Whether every quad of the block has both its triangles in layer image ``k``."""
    for y in range(y0, y0 + b):
        for x in range(x0, x0 + b):
            if cnt[k, y * cols + x] != 2:
                return False
    return True


def planar_blocks(cnt, images, value, rows, cols, eps, big, small):
    """Quadtree of blocks (sides ``big`` .. ``small``, powers of two) whose quads are
    whole and whose ``value`` is planar within ``eps``.

    Returns:
        ``(B, 4) int64`` rows ``(layer image, y0, x0, side)``; ``cnt`` is set to 255
        at every quad of a block.
    """
    # here, not in the kernel: each allocation (and a list) in a kernel compiles
    out = np.empty((int(np.count_nonzero(cnt == 2)) // (small * small) + 1, 4), np.int64)
    stack = np.empty((4 * int(np.log2(max(big // small, 1)) + 1) + 1, 3), np.int64)
    n = _planar_blocks(cnt, images, value, rows, cols, eps, big, small, out, stack)
    return out[:n].copy()


@njit(cache=True, nogil=True)
def _planar_blocks(cnt, images, value, rows, cols, eps, big, small, out, stack):
    """:func:`planar_blocks` into ``out``'s first rows (returns how many); ``stack``:
    scratch (a depth-first walk holds at most 3 rows per level and one)."""
    n = 0
    for k in range(images.shape[0]):
        for by in range(0, rows - 1, big):
            for bx in range(0, cols - 1, big):
                stack[0, 0], stack[0, 1], stack[0, 2] = by, bx, big
                top = 1
                while top:
                    top -= 1
                    y0, x0, b = stack[top, 0], stack[top, 1], stack[top, 2]
                    if y0 + b > rows - 1 or x0 + b > cols - 1 or not _whole(cnt, k, y0, x0,
                                                                            b, cols):
                        ok = False
                    else:
                        ok = _planar(images, k, value, y0, x0, b, cols, eps)
                    if ok:
                        out[n, 0], out[n, 1], out[n, 2], out[n, 3] = k, y0, x0, b
                        n += 1
                        for y in range(y0, y0 + b):
                            for x in range(x0, x0 + b):
                                cnt[k, y * cols + x] = 255
                    elif b > small:
                        h = b // 2
                        for dy in (0, h):
                            for dx in (0, h):
                                if y0 + dy < rows - 1 and x0 + dx < cols - 1:
                                    stack[top, 0] = y0 + dy
                                    stack[top, 1] = x0 + dx
                                    stack[top, 2] = h
                                    top += 1
    return n


def merged_faces(faces, face_layer, py, px, cnt, cols, blocks, images, sign):
    """Faces outside the blocks, then each block's fan; and their layer images
    (:func:`_merged_faces`, with the arrays it fills allocated here: each allocation
    in a kernel compiles on the first run).

    Returns:
        ``(faces (M, 3) int64, layer (M,) int64)``.
    """
    return _merged_faces(faces, face_layer, py, px, cnt, cols, blocks, images, sign,
                         np.zeros(len(faces), np.bool_), np.zeros(len(py), np.bool_),
                         np.empty((len(blocks), 2), np.int64),
                         np.empty(4 * int(blocks[:, 3].sum()), np.int64))


@njit(cache=True, nogil=True)
def _merged_faces(faces, face_layer, py, px, cnt, cols, blocks, images, sign, keep, needed,
                  rings, ring):
    """Faces outside the blocks, then each block's fan; and their layer images
    (``keep (F,)``, ``needed (N,)`` bool zeros, ``rings (B, 2)`` and ``ring (4 sum(b),)``
    int64: scratch).

    A block's fan runs from its centre to the pixels of its border that something
    else needs: its corners, every other block's corners and the vertices of the
    faces kept. Where two blocks meet, the pixels between those are dropped from
    both, so they share one straight edge (no crack, no T-junction) and a plane of
    ``4 b`` border pixels becomes as few as 4 triangles. ``sign`` is the sign of
    ``cross(v1 - v0, v2 - v0)`` in (x, y) of the input faces; the fans are wound the
    same way.
    """
    n_keep = 0
    for f in range(len(faces)):
        y0 = min(py[faces[f, 0]], py[faces[f, 1]], py[faces[f, 2]])
        x0 = min(px[faces[f, 0]], px[faces[f, 1]], px[faces[f, 2]])
        if cnt[face_layer[f], y0 * cols + x0] != 255:
            keep[f] = True
            n_keep += 1
            for c in range(3):
                needed[faces[f, c]] = True
    for i in range(len(blocks)):
        k, y0, x0, b = blocks[i, 0], blocks[i, 1], blocks[i, 2], blocks[i, 3]
        for y, x in ((y0, x0), (y0, x0 + b), (y0 + b, x0 + b), (y0 + b, x0)):
            needed[images[k, y * cols + x]] = True
    n = 0  # rings[i]: start and length of block i's border in `ring`
    for i in range(len(blocks)):
        k, y0, x0, b = blocks[i, 0], blocks[i, 1], blocks[i, 2], blocks[i, 3]
        rings[i, 0] = n
        # the border clockwise on screen (y down): top, right, bottom, left edges
        for t in range(4 * b):
            if t < b:
                q = images[k, y0 * cols + x0 + t]
            elif t < 2 * b:
                q = images[k, (y0 + t - b) * cols + x0 + b]
            elif t < 3 * b:
                q = images[k, (y0 + b) * cols + x0 + 3 * b - t]
            else:
                q = images[k, (y0 + 4 * b - t) * cols + x0]
            if needed[q]:
                ring[n] = q
                n += 1
        rings[i, 1] = n - rings[i, 0]
    out = np.empty((n_keep + n, 3), np.int64)
    layer = np.empty(n_keep + n, np.int64)
    j = 0
    for f in range(len(faces)):
        if keep[f]:
            out[j, 0], out[j, 1], out[j, 2] = faces[f, 0], faces[f, 1], faces[f, 2]
            layer[j] = face_layer[f]
            j += 1
    for i in range(len(blocks)):
        k, y0, x0, b = blocks[i, 0], blocks[i, 1], blocks[i, 2], blocks[i, 3]
        centre = images[k, (y0 + b // 2) * cols + x0 + b // 2]
        s, m = rings[i, 0], rings[i, 1]
        for t in range(m):
            u, v = ring[s + t], ring[s + (t + 1) % m]
            if sign > 0:  # the ring is clockwise on screen: cross > 0 as (c, u, v)
                out[j, 0], out[j, 1], out[j, 2] = centre, u, v
            else:
                out[j, 0], out[j, 1], out[j, 2] = centre, v, u
            layer[j] = k
            j += 1
    return out, layer


KERNELS = (
    (_quad_counts, "(int32[:, ::1], int64[::1], int64[::1], int64[::1], int64, uint8[:, ::1])"),
    (_planar_blocks, "(uint8[:, ::1], int32[:, ::1], float64[::1], int64, int64, float64, "
                     "int64, int64, int64[:, ::1], int64[:, ::1])"),
    (_merged_faces, "(int32[:, ::1], int64[::1], int64[::1], int64[::1], uint8[:, ::1], int64, "
                    "int64[:, ::1], int32[:, ::1], int64, boolean[::1], boolean[::1], "
                    "int64[:, ::1], int64[::1])"),
)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""
