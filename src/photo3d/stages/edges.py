"""Depth discontinuities and linked depth edges (paper, Sec. 3.1).

Directions are numbered ``0 = left, 1 = right, 2 = up, 3 = down`` everywhere in
photo3d (``d ^ 1`` is the opposite direction); a *cut mask* is a ``uint8`` bit set
``1 << d`` per pixel.

A discontinuity between two 4-neighbours is a normalised disparity difference above
the threshold. It is recorded on the *background* (smaller disparity) pixel, whose
link towards the nearer pixel will be cut: these pixels form the background
silhouette. They are linked into depth edges by 8-connected components in which two
silhouette pixels only join when they are connected in the LDI (directly, or through
a common 4-neighbour, without crossing a discontinuity). That splits edges at
junctions where different depth layers meet. Edges shorter than ``min_length`` are
dropped (their links stay, so nothing tears there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy import ndimage

from photo3d.stages._lattice import find_root, union


@dataclass(frozen=True)
class DepthEdges:
    """Linked depth edges of one image.

    Attributes:
        labels: ``(H, W) int32`` edge id per background silhouette pixel, 0 = none.
        cuts: ``(H, W) uint8`` bit set of directions to cut at kept edge pixels.
        count: number of edges (ids ``1..count``).
    """

    labels: np.ndarray
    cuts: np.ndarray
    count: int


def find_discontinuities(disparity: np.ndarray, threshold: float) -> np.ndarray:
    """Cut mask of raw discontinuities, set on the background pixel.

    Args:
        disparity: ``(H, W) float32`` normalised disparity.
        threshold: minimum neighbour difference.

    Returns:
        ``(H, W) uint8`` bit set of directions towards a nearer neighbour.

    Example:
        >>> d = np.array([[0.0, 0.0, 1.0]], np.float32)
        >>> find_discontinuities(d, 0.04).tolist()  # pixel 1 sees a nearer right neighbour
        [[0, 2, 0]]
    """
    cuts = np.zeros(disparity.shape, np.uint8)
    dx = disparity[:, 1:] - disparity[:, :-1]
    cuts[:, :-1] |= np.where(dx > threshold, 1 << 1, 0).astype(np.uint8)
    cuts[:, 1:] |= np.where(-dx > threshold, 1 << 0, 0).astype(np.uint8)
    dy = disparity[1:, :] - disparity[:-1, :]
    cuts[:-1, :] |= np.where(dy > threshold, 1 << 3, 0).astype(np.uint8)
    cuts[1:, :] |= np.where(-dy > threshold, 1 << 2, 0).astype(np.uint8)
    return cuts


@numba.njit(cache=True)
def _link(disc, candidates):  # pragma: no cover - jit
    """Union-find over silhouette pixels; ``disc`` is the 'link is broken' bit set."""
    h, w = disc.shape
    n = h * w
    parent = np.arange(n)
    for y in range(h):
        for x in range(w):
            if not candidates[y, x]:
                continue
            p = y * w + x
            # forward neighbours: right, down-left, down, down-right
            for k in range(4):
                if k == 0:
                    ny, nx = y, x + 1
                elif k == 1:
                    ny, nx = y + 1, x - 1
                elif k == 2:
                    ny, nx = y + 1, x
                else:
                    ny, nx = y + 1, x + 1
                if ny >= h or nx < 0 or nx >= w or not candidates[ny, nx]:
                    continue
                if ny == y:  # horizontal 4-neighbour
                    ok = (disc[y, x] >> 1) & 1 == 0
                elif nx == x:  # vertical 4-neighbour
                    ok = (disc[y, x] >> 3) & 1 == 0
                else:
                    # diagonal: through (y, nx) or through (ny, x), no broken link on the way
                    sx = 1 if nx > x else 0  # direction bit from (y, x) towards nx
                    via_a = ((disc[y, x] >> sx) & 1) == 0 and ((disc[y, nx] >> 3) & 1) == 0
                    via_b = ((disc[y, x] >> 3) & 1) == 0 and ((disc[ny, x] >> sx) & 1) == 0
                    ok = via_a or via_b
                if ok:
                    union(parent, p, ny * w + nx)
    labels = np.zeros((h, w), np.int64)
    for y in range(h):
        for x in range(w):
            if candidates[y, x]:
                labels[y, x] = find_root(parent, y * w + x) + 1
    return labels


KERNELS = ((_link, "(uint8[:, ::1], boolean[:, ::1])"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def link_edges(disparity: np.ndarray, *, threshold: float, min_length: int,
               attach_short: bool = True) -> DepthEdges:
    """Detect, link and clean depth edges.

    Args:
        disparity: ``(H, W) float32`` normalised (filtered) disparity.
        threshold: discontinuity threshold.
        min_length: edges with fewer pixels are dropped.
        attach_short: a short segment that touches (8-adjacency) a long edge joins
            it instead of being dropped. Dropping keeps the segment's links, which
            the mesh then stretches across the depth step: thin streaks in novel
            views. The paper drops them; isolated short segments are dropped either way.

    Returns:
        :class:`DepthEdges` (ids ordered by first pixel in raster order).

    Example:
        >>> d = np.zeros((20, 20), np.float32); d[:, 10:] = 1.0
        >>> e = link_edges(d, threshold=0.04, min_length=10)
        >>> e.count, int((e.labels > 0).sum()), sorted(set(e.labels[:, 9].tolist()))
        (1, 20, [1])
    """
    cuts = find_discontinuities(disparity, threshold)
    # A link is broken if either end records the discontinuity.
    disc = cuts.copy()
    disc[:, 1:] |= np.where(cuts[:, :-1] & 2, 1, 0).astype(np.uint8)
    disc[:, :-1] |= np.where(cuts[:, 1:] & 1, 2, 0).astype(np.uint8)
    disc[1:, :] |= np.where(cuts[:-1, :] & 8, 4, 0).astype(np.uint8)
    disc[:-1, :] |= np.where(cuts[1:, :] & 4, 8, 0).astype(np.uint8)
    roots = _link(disc, cuts > 0).reshape(-1)
    # ids, and each pixel's index into them: 0 (no edge) first, then the roots of
    # the silhouette pixels (a few percent of the map: np.unique of those only)
    pixels = np.flatnonzero(roots)
    found, index, sizes = np.unique(roots[pixels], return_inverse=True, return_counts=True)
    ids = np.concatenate([[0], found])
    counts = np.concatenate([[roots.size - pixels.size], sizes])
    inverse = np.zeros(roots.size, np.intp)
    inverse[pixels] = index + 1
    inverse = inverse.reshape(disparity.shape)
    keep = (ids > 0) & (counts >= max(1, min_length))
    new_id = np.zeros(ids.size, np.int32)
    new_id[keep] = np.arange(1, int(keep.sum()) + 1, dtype=np.int32)
    labels = new_id[inverse]
    short = (ids > 0) & ~keep
    if attach_short and short.any() and keep.any():
        near = ndimage.maximum_filter(labels, size=3)
        is_short = short[inverse]
        # each short segment takes the largest neighbouring long-edge id it touches
        target = np.zeros(ids.size, np.int32)
        np.maximum.at(target, inverse[is_short], near[is_short])
        labels = np.where(is_short, target[inverse], labels).astype(np.int32)
    return DepthEdges(labels=labels, cuts=np.where(labels > 0, cuts, 0).astype(np.uint8),
                      count=int(keep.sum()))


def edges_csr(labels: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of each labelled edge, as CSR arrays (what
    :func:`photo3d.stages.regions.find_regions` takes).

    Args:
        labels: ``(H, W) int`` edge label per pixel, 0 = none, 1..count = edges.
        count: number of edges.

    Returns:
        ``(edge_ptr (count + 1,) int64, pixels (K,) int64)``: edge ``e`` (0-based) owns
        the flat pixel indices ``pixels[edge_ptr[e]:edge_ptr[e + 1]]``.

    Example:
        >>> ptr, pix = edges_csr(np.array([[0, 2], [1, 2]]), 2)
        >>> ptr.tolist(), pix.tolist()
        ([0, 1, 3], [2, 1, 3])
    """
    flat = labels.reshape(-1)
    pix = np.nonzero(flat)[0]
    order = np.argsort(flat[pix], kind="stable")
    counts = np.bincount(flat[pix], minlength=count + 1)[1:]
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64), pix[order].astype(np.int64)
