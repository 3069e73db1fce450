"""Supersampling resolve and hole filling (numba kernels of :mod:`renderer`)."""

from __future__ import annotations

import numba
import numpy as np
from numba import prange


@numba.njit(cache=True, parallel=True)
def resolve(color, mask, depth, factor):  # pragma: no cover - jit
    """Average the covered samples of each ``factor x factor`` block.

    Returns ``color (H, W, 3)`` (mean of the covered samples, 0 where none),
    ``coverage (H, W)`` (fraction of covered samples) and ``depth (H, W)`` (nearest
    covered sample, inf where none).
    """
    h, w = mask.shape[0] // factor, mask.shape[1] // factor
    out = np.zeros((h, w, 3), np.float32)
    cov = np.zeros((h, w), np.float32)
    dep = np.full((h, w), np.inf, np.float32)
    inv = 1.0 / (factor * factor)
    for y in prange(h):
        for x in range(w):
            n = 0
            r = 0.0
            g = 0.0
            b = 0.0
            d = np.inf
            for dy in range(factor):
                for dx in range(factor):
                    yy, xx = y * factor + dy, x * factor + dx
                    if mask[yy, xx]:
                        n += 1
                        r += color[yy, xx, 0]
                        g += color[yy, xx, 1]
                        b += color[yy, xx, 2]
                        d = min(d, depth[yy, xx])
            if n > 0:
                out[y, x, 0] = r / n
                out[y, x, 1] = g / n
                out[y, x, 2] = b / n
                cov[y, x] = n * inv
                dep[y, x] = d
    return out, cov, dep


@numba.njit(cache=True)
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
