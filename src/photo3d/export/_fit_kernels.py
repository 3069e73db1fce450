"""The numba kernels of :mod:`photo3d.export.splat_fit`: products with Spark's weights
kept as :func:`~photo3d.export.spark_model.visible_weights` gives them (one column of
pixels and weights per splat), without transposing them."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def render(indptr, rows, vals, colors, image):
    """``image = W @ colors``: ``(pixels, 3) float32``, overwritten."""
    image[:] = 0
    for j in range(len(indptr) - 1):
        c0, c1, c2 = colors[j, 0], colors[j, 1], colors[j, 2]
        for k in range(indptr[j], indptr[j + 1]):
            r, w = rows[k], vals[k]
            image[r, 0] += w * c0
            image[r, 1] += w * c1
            image[r, 2] += w * c2


@njit(cache=True, nogil=True)
def gather(indptr, rows, vals, mask, image, out):
    """``out = W^T M image``: ``(M, 3) float32``, overwritten (``mask``: ``(pixels,)
    float32``, 1 where a pixel counts, else 0)."""
    for j in range(len(indptr) - 1):
        s0 = s1 = s2 = np.float32(0)
        for k in range(indptr[j], indptr[j + 1]):
            r = rows[k]
            w = vals[k] * mask[r]
            s0 += w * image[r, 0]
            s1 += w * image[r, 1]
            s2 += w * image[r, 2]
        out[j, 0], out[j, 1], out[j, 2] = s0, s1, s2


@njit(cache=True, nogil=True)
def diagonal(indptr, rows, vals, mask):
    """``diag(W^T M W)``: ``(M,) float32``."""
    out = np.zeros(len(indptr) - 1, np.float32)
    for j in range(len(indptr) - 1):
        for k in range(indptr[j], indptr[j + 1]):
            out[j] += vals[k] * vals[k] * mask[rows[k]]
    return out


def normal(indptr: np.ndarray, rows: np.ndarray, vals: np.ndarray, mask: np.ndarray,
           x: np.ndarray, lam: np.float32, image: np.ndarray) -> np.ndarray:
    """``(W^T M W + lam) x``: ``(M, 3) float32`` (``image``: ``(pixels, 3) float32``
    scratch)."""
    out = np.empty_like(x)
    render(indptr, rows, vals, x, image)
    gather(indptr, rows, vals, mask, image, out)
    out += lam * x
    return out
