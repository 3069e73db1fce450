"""Hole filling and 8-bit output (numba kernels of :mod:`renderer`); the supersampling
resolve is fused into the rasterizer (:func:`photo3d.render._kernels.resolve`)."""

from __future__ import annotations

import heapq

import numba
import numpy as np
from numba import prange


@numba.njit(cache=True, nogil=True)
def grow_fill(color, coverage, iterations):  # pragma: no cover - jit
    """Fill pixels with coverage < 1 from fully known 8-neighbours, ring by ring.

    A partly covered pixel keeps its own colour in proportion to its coverage.
    Returns the number of pixels still without any known neighbour after
    ``iterations`` rings (0 when every hole was filled).
    """
    h, w = coverage.shape
    known = coverage >= 0.999
    todo_y = np.empty(h * w, np.int64)
    todo_x = np.empty(h * w, np.int64)
    m = 0
    for y in range(h):
        for x in range(w):
            if not known[y, x]:
                todo_y[m] = y
                todo_x[m] = x
                m += 1
    newly = np.zeros(m, np.bool_)
    fill = np.zeros((m, 3), np.float32)
    for _ in range(iterations):
        if m == 0:
            break
        for i in range(m):
            y, x = todo_y[i], todo_x[i]
            n = 0
            acc0 = 0.0
            acc1 = 0.0
            acc2 = 0.0
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < h and 0 <= xx < w and known[yy, xx]:
                        n += 1
                        acc0 += color[yy, xx, 0]
                        acc1 += color[yy, xx, 1]
                        acc2 += color[yy, xx, 2]
            newly[i] = n > 0
            if n > 0:
                fill[i, 0] = acc0 / n
                fill[i, 1] = acc1 / n
                fill[i, 2] = acc2 / n
        k = 0
        for i in range(m):
            y, x = todo_y[i], todo_x[i]
            if newly[i]:
                c = coverage[y, x]
                for ch in range(3):
                    color[y, x, ch] = c * color[y, x, ch] + (1.0 - c) * fill[i, ch]
                known[y, x] = True
            else:
                todo_y[k] = y
                todo_x[k] = x
                k += 1
        m = k
    return m


@numba.njit(cache=True, nogil=True)
def _depth_at(depth, filled, ring, y, x):  # pragma: no cover - jit
    """Depth of a known pixel: its own (ring 0) or the source depth it was filled with."""
    return filled[y, x] if ring[y, x] > 0 else depth[y, x]


@numba.njit(cache=True, nogil=True)
def _far_mean(color, known, ring, depth, filled, y, x, r, src, tolerance, out):  # pragma: no cover
    """Mean colour of ``(y, x)``'s 8-neighbours filled before ring ``r`` whose depth
    is within ``tolerance`` of ``src`` or farther; returns how many there were."""
    h, w = known.shape
    n = 0
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    for dy in range(-1, 2):
        for dx in range(-1, 2):
            yy, xx = y + dy, x + dx
            if (0 <= yy < h and 0 <= xx < w and known[yy, xx] and ring[yy, xx] < r
                    and _depth_at(depth, filled, ring, yy, xx) >= src * (1.0 - tolerance)):
                n += 1
                for ch in range(3):
                    out[ch] += color[yy, xx, ch]
    return n


@numba.njit(cache=True, nogil=True)
def _farthest(known, ring, depth, filled, y, x, before):  # pragma: no cover - jit
    """Depth and ring of ``(y, x)``'s farthest 8-neighbour filled before ring
    ``before`` (-1 if none)."""
    h, w = known.shape
    far = -1.0
    r = 0
    for dy in range(-1, 2):
        for dx in range(-1, 2):
            yy, xx = y + dy, x + dx
            if 0 <= yy < h and 0 <= xx < w and known[yy, xx] and ring[yy, xx] < before:
                z = _depth_at(depth, filled, ring, yy, xx)
                if z > far:
                    far = z
                    r = ring[yy, xx]
    return far, r


@numba.njit(cache=True, nogil=True)
def grow_fill_far(color, coverage, depth, iterations, tolerance):  # pragma: no cover - jit
    """Fill pixels with coverage < 1 from their neighbours, the farthest surface first.

    What a moving camera uncovers lies behind what it sees, so a hole takes the
    colour of the farther side around it. Partly covered pixels next to a fully
    covered one are filled first, from those neighbours; the rest by a priority flood
    (farthest source depth first, then the nearest ring): a pixel takes the mean of
    its 8-neighbours filled in an earlier ring whose depth is within ``tolerance``
    (relative) of that source's, and passes the source depth on. Pixels more than
    ``iterations`` rings from any covered pixel stay unfilled. A partly covered pixel
    keeps its own colour in proportion to its coverage. Returns the number of
    pixels left unfilled.

    One pass over the frame finds the pixels to fill; the rest of the work visits
    only them and their neighbours (the per-pixel arrays are allocated, not written:
    a video frame has few holes).
    """
    h, w = coverage.shape
    known = np.empty((h, w), np.bool_)
    todo_y = np.empty(h * w, np.int64)
    todo_x = np.empty(h * w, np.int64)
    m = 0
    for y in range(h):
        for x in range(w):
            k = coverage[y, x] >= 0.999
            known[y, x] = k
            if not k:
                todo_y[m] = y
                todo_x[m] = x
                m += 1
    if m == 0:
        return 0
    filled = np.empty((h, w), np.float32)  # source depth of the filled pixels
    ring = np.zeros((h, w), np.int32)  # 0: known from the start (zeroed lazily by the OS)
    mean = np.zeros(3)
    # Ring 1: partly covered pixels from their fully covered neighbours (in place: a
    # pixel written here has ring 1, which no other ring-1 pixel reads).
    for i in range(m):
        y, x = todo_y[i], todo_x[i]
        if coverage[y, x] > 0.0:
            far, _ = _farthest(known, ring, depth, filled, y, x, 1)
            if far > 0.0:
                n = _far_mean(color, known, ring, depth, filled, y, x, 1, far, tolerance, mean)
                c = coverage[y, x]
                for ch in range(3):
                    color[y, x, ch] = c * color[y, x, ch] + (1.0 - c) * mean[ch] / n
                known[y, x] = True
                filled[y, x] = far
                ring[y, x] = 1
    # The rest: priority flood from everything filled so far.
    queued = np.zeros((h, w), np.float32)  # best key queued (keys are < 0; 0: none)
    heap = [(0.0, 0, 0, 0)]
    heap.pop()
    left = 0
    for i in range(m):
        y, x = todo_y[i], todo_x[i]
        if known[y, x]:
            continue
        left += 1
        far, r = _farthest(known, ring, depth, filled, y, x, 2)
        if far > 0.0:
            queued[y, x] = -far
            heapq.heappush(heap, (-far, r + 1, y, x))
    while len(heap) > 0:
        key, r, y, x = heapq.heappop(heap)
        if known[y, x]:
            continue
        n = _far_mean(color, known, ring, depth, filled, y, x, r, -key, tolerance, mean)
        if n == 0:
            continue
        c = coverage[y, x]
        for ch in range(3):
            color[y, x, ch] = c * color[y, x, ch] + (1.0 - c) * mean[ch] / n
        known[y, x] = True
        filled[y, x] = -key
        ring[y, x] = r
        left -= 1
        if r >= iterations:
            continue
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                yy, xx = y + dy, x + dx
                if 0 <= yy < h and 0 <= xx < w and not known[yy, xx] and key < queued[yy, xx]:
                    queued[yy, xx] = key
                    heapq.heappush(heap, (key, r + 1, yy, xx))
    return left


@numba.njit(cache=True, inline="always")
def _u8(v):  # pragma: no cover - jit
    """A colour in [0, 1] (clipped) -> ``uint8``, rounded half up."""
    return np.uint8(min(max(v, 0.0), 1.0) * 255.0 + 0.5)


@numba.njit(cache=True, parallel=True, nogil=True)
def to_rgb8(color):  # pragma: no cover - jit
    """``(H, W, 3)`` float in [0, 1] -> ``uint8`` (clipped, rounded half up)."""
    h, w = color.shape[0], color.shape[1]
    out = np.empty((h, w, 3), np.uint8)
    for y in prange(h):
        for x in range(w):
            for ch in range(3):
                out[y, x, ch] = _u8(color[y, x, ch])
    return out


@numba.njit(cache=True, nogil=True)
def holes_to_rgb8(color, coverage, rgb):  # pragma: no cover - jit
    """Write the pixels with ``coverage < 1`` of ``(H, W, 3)`` float ``color`` into the
    ``(H, W, 3) uint8`` ``rgb`` as :func:`to_rgb8` would (the other pixels are left:
    a frame whose covered pixels were converted with the rasterizer's pass, whose
    holes were filled since)."""
    h, w = coverage.shape
    for y in range(h):
        for x in range(w):
            if coverage[y, x] < 1.0:
                for ch in range(3):
                    rgb[y, x, ch] = _u8(color[y, x, ch])
    return rgb


@numba.njit(cache=True, nogil=True)
def blend_fringe(color, depth, fringe, f_coverage, f_depth, rgb):  # pragma: no cover - jit
    """Blend the soft silhouettes' fringe over ``(H, W, 3)`` float ``color`` in place:
    where the fringe covers a pixel (``f_coverage > 0``) at or in front of ``depth``
    (``(H, W)``, its nearest surface, within 0.1 %), ``a = alpha * min(2 f_coverage,
    1)`` of the fringe's colour over ``color`` (the fringe's mesh ends at its outer
    pixels' centres: it covers about half of them, while their alpha already is their
    coverage); ``depth`` takes the fringe's where it is nearer. ``fringe``: ``(H, W,
    4)`` float, the fringe's colours and (fourth channel) its alpha, the nearest
    corner's (:func:`photo3d.render._kernels._nearest`). ``rgb``: ``(H, W, 3) uint8``
    whose blended pixels are written again as :func:`to_rgb8` would (a frame
    converted before the blend), or ``(0, 0, 3)``."""
    h, w = depth.shape
    rgb8 = rgb.shape[0] > 0
    for y in range(h):
        for x in range(w):
            c = f_coverage[y, x]
            if c <= 0.0 or f_depth[y, x] > depth[y, x] * 1.001:
                continue
            a = fringe[y, x, 3] * min(2.0 * c, 1.0)
            if a <= 0.0:
                continue
            for ch in range(3):
                color[y, x, ch] = a * fringe[y, x, ch] + (1.0 - a) * color[y, x, ch]
                if rgb8:
                    rgb[y, x, ch] = _u8(color[y, x, ch])
            depth[y, x] = min(depth[y, x], f_depth[y, x])
