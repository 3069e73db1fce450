"""Push-pull filling of unknown pixels, shared by the renderer (pixels no triangle
covers) and the light mesh (texels no chart covers)."""

from __future__ import annotations

import numpy as np


def fill_holes(color: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Push-pull fill: unknown pixels get a smooth average of nearby known ones.

    Args:
        color: ``(H, W, C) float32``.
        known: ``(H, W)`` weights in [0, 1] (1 = fully known).

    Example:
        >>> c = np.zeros((4, 4, 1), np.float32); c[0, 0] = 1.0
        >>> k = np.zeros((4, 4)); k[0, 0] = 1
        >>> float(fill_holes(c, k)[3, 3, 0])
        1.0
    """
    w = np.clip(known, 0.0, 1.0).astype(np.float32)
    if w.min() >= 1.0 or w.max() <= 0.0:
        return color
    levels = [(color * w[..., None], w)]
    while min(levels[-1][1].shape) > 1:
        c, k = levels[-1]
        h2, w2 = (c.shape[0] + 1) // 2, (c.shape[1] + 1) // 2
        pc = np.zeros((h2 * 2, w2 * 2, c.shape[2]), np.float32)
        pk = np.zeros((h2 * 2, w2 * 2), np.float32)
        pc[: c.shape[0], : c.shape[1]], pk[: k.shape[0], : k.shape[1]] = c, k
        c2 = pc.reshape(h2, 2, w2, 2, -1).sum((1, 3))
        k2 = pk.reshape(h2, 2, w2, 2).sum((1, 3))
        norm = np.maximum(k2, 1e-12)[..., None]
        levels.append((c2 / norm * np.minimum(k2, 1.0)[..., None], np.minimum(k2, 1.0)))
    filled = levels[-1][0] / np.maximum(levels[-1][1], 1e-12)[..., None]
    for c, k in reversed(levels[:-1]):
        up = np.repeat(np.repeat(filled, 2, 0), 2, 1)[: c.shape[0], : c.shape[1]]
        filled = c + (1.0 - k)[..., None] * up
    return filled.astype(np.float32)
