"""The numba kernel of :mod:`photo3d.export.spark_model`: splats drawn front to back
into a transmittance buffer, each fragment's weight ``alpha * T`` recorded."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _footprint(u, v, a, b, d, width, height, cutoff2):
    """The pixel box of one splat's ellipse ``z2 <= cutoff2`` (clipped)."""
    rx = math.sqrt(cutoff2 * a)
    ry = math.sqrt(cutoff2 * d)
    x0 = max(0, int(math.ceil(u - rx - 0.5)))
    x1 = min(width - 1, int(math.floor(u + rx - 0.5)))
    y0 = max(0, int(math.ceil(v - ry - 0.5)))
    y1 = min(height - 1, int(math.floor(v + ry - 0.5)))
    return x0, x1, y0, y1


@njit(cache=True, nogil=True)
def _count(order, u, v, cov, alpha, width, height, cutoff2):
    total = 0
    for i in order:
        x0, x1, y0, y1 = _footprint(u[i], v[i], cov[i, 0], cov[i, 1], cov[i, 2], width,
                                    height, cutoff2)
        if x1 >= x0 and y1 >= y0:
            total += (x1 - x0 + 1) * (y1 - y0 + 1)
    return total


@njit(cache=True, nogil=True)
def _draw(order, u, v, cov, alpha, width, height, cutoff2, min_alpha, floor, rows, cols,
          vals):
    trans = np.ones(width * height)
    n = 0
    for i in order:
        a, b, d = cov[i, 0], cov[i, 1], cov[i, 2]
        det = a * d - b * b
        x0, x1, y0, y1 = _footprint(u[i], v[i], a, b, d, width, height, cutoff2)
        for y in range(y0, y1 + 1):
            dy = y + 0.5 - v[i]
            for x in range(x0, x1 + 1):
                dx = x + 0.5 - u[i]
                z2 = (d * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det
                if z2 > cutoff2:
                    continue
                al = alpha[i] * math.exp(-0.5 * z2)
                if al < min_alpha:
                    continue
                p = y * width + x
                w = al * trans[p]
                trans[p] *= 1.0 - al
                if w >= floor:
                    rows[n] = p
                    cols[n] = i
                    vals[n] = w
                    n += 1
    return n


def rasterize(order: np.ndarray, u: np.ndarray, v: np.ndarray, cov: np.ndarray,
              alpha: np.ndarray, width: int, height: int, cutoff2: float,
              min_alpha: float, floor: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fragments of the splats ``order`` (front to back) with a weight of at least
    ``floor``: ``(pixel (K,) int32, splat (K,) int32, weight (K,) float32)``."""
    capacity = _count(order, u, v, cov, alpha, width, height, cutoff2)
    rows = np.empty(capacity, np.int32)
    cols = np.empty(capacity, np.int32)
    vals = np.empty(capacity, np.float32)
    n = _draw(order, u, v, cov, alpha, width, height, cutoff2, min_alpha, floor, rows,
              cols, vals)
    return rows[:n], cols[:n], vals[:n]
