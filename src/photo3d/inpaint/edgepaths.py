"""Clean-up of an edge net's output: one-pixel paths that continue context edges.

The paper's edge stage predicts where the context's depth edges continue into the
synthesis region; the authors' inference then keeps, for each context edge that
reaches the region, one path through the predicted pixels and drops the rest. An
edge net that is poorly trained or random fires in blobs instead of thin lines, and
a blob is not an edge: fed to the depth net it yields depth steps all around it, and
every step becomes a new occlusion edge of the next pass (docs/fills.md). Here the
predicted pixels are thinned to their one-pixel skeleton (Zhang-Suen thinning, in
numba: scikit-image has one but is only an optional extra of photo3d) and only the
skeleton pieces that touch a context edge are kept.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import ndimage

from photo3d.structures.patch import Patch

_EIGHT = np.ones((3, 3), bool)


@numba.njit(cache=True)
def _thin(img):  # pragma: no cover - jit
    """Zhang-Suen thinning of a ``(H, W) uint8`` 0/1 image, in place."""
    h, w = img.shape
    changed = True
    marks = np.zeros((h * w, 2), np.int64)
    while changed:
        changed = False
        for sub in range(2):
            n = 0
            for y in range(1, h - 1):
                for x in range(1, w - 1):
                    if img[y, x] == 0:
                        continue
                    p2, p3, p4 = img[y - 1, x], img[y - 1, x + 1], img[y, x + 1]
                    p5, p6, p7 = img[y + 1, x + 1], img[y + 1, x], img[y + 1, x - 1]
                    p8, p9 = img[y, x - 1], img[y - 1, x - 1]
                    b = p2 + p3 + p4 + p5 + p6 + p7 + p8 + p9
                    if b < 2 or b > 6:
                        continue
                    a = ((p2 == 0 and p3 == 1) + (p3 == 0 and p4 == 1) + (p4 == 0 and p5 == 1)
                         + (p5 == 0 and p6 == 1) + (p6 == 0 and p7 == 1)
                         + (p7 == 0 and p8 == 1) + (p8 == 0 and p9 == 1)
                         + (p9 == 0 and p2 == 1))
                    if a != 1:
                        continue
                    if sub == 0 and (p2 * p4 * p6 != 0 or p4 * p6 * p8 != 0):
                        continue
                    if sub == 1 and (p2 * p4 * p8 != 0 or p2 * p6 * p8 != 0):
                        continue
                    marks[n, 0] = y
                    marks[n, 1] = x
                    n += 1
            for i in range(n):
                img[marks[i, 0], marks[i, 1]] = 0
            if n:
                changed = True
    return img


def thin(mask: np.ndarray) -> np.ndarray:
    """One-pixel-wide skeleton of ``mask`` (``(H, W) bool``; Zhang-Suen thinning).

    Example:
        >>> m = np.zeros((9, 12), bool); m[2:7, 1:11] = True   # a 5 px thick bar
        >>> int(thin(m).sum(axis=0).max())                      # one pixel per column
        1
    """
    img = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8)
    img[1:-1, 1:-1] = mask
    return _thin(img)[1:-1, 1:-1].astype(bool)


def edge_paths(new: np.ndarray, context_edges: np.ndarray) -> np.ndarray:
    """The predicted edge pixels ``new`` as one-pixel paths that continue a context edge.

    Args:
        new: ``(H, W) bool`` edge-net output above its threshold inside the synthesis
            region.
        context_edges: ``(H, W) bool`` depth-edge pixels of the context.

    Returns:
        ``(H, W) bool``: the skeleton of the 8-connected pieces of ``new`` that touch
        (8-neighbourhood) a context edge pixel.

    Example:
        >>> ctx = np.zeros((8, 12), bool); ctx[3, :3] = True     # a context edge
        >>> new = np.zeros((8, 12), bool); new[2:5, 3:8] = True  # its blob continuation
        >>> new[6, 10] = True                                    # an isolated speck
        >>> paths = edge_paths(new, ctx)
        >>> bool(paths[6, 10]), int(paths[:, 3:8].sum(axis=0).max())
        (False, 1)
    """
    if not new.any():
        return np.zeros(new.shape, bool)
    labels, count = ndimage.label(new, structure=_EIGHT)
    near = ndimage.binary_dilation(context_edges, structure=_EIGHT)
    touching = np.unique(labels[near & new])
    keep = np.zeros(count + 1, bool)
    keep[touching[touching > 0]] = True
    return thin(keep[labels])


def reported_edges(edges: np.ndarray, p: Patch) -> np.ndarray:
    """``(h, w) float32`` edges of a result for patch ``p``: ``edges`` (a backend's
    edge map, > 0 = edge) in the context, :func:`edge_paths` of them in the
    synthesis region.

    Example:
        >>> ctx = np.zeros((8, 12), bool); ctx[:, :4] = True
        >>> e = np.zeros((8, 12), np.float32); e[:, 3] = 1; e[2:5, 4:9] = 1
        >>> p = Patch(np.zeros((8, 12, 3), np.float32), np.zeros((8, 12), np.float32),
        ...           e * ctx, ctx, ~ctx, (0, 0))
        >>> out = reported_edges(e, p)
        >>> int(out[:, 3].sum()), int(out[:, 4:].sum()) < int(e[:, 4:].sum())
        (8, True)
    """
    ctx = p.context.astype(bool)
    syn = p.synthesis.astype(bool) & ~ctx
    new = edge_paths((edges > 0) & syn, (p.edges > 0) & ctx)
    return np.where(syn, new, edges).astype(np.float32)
