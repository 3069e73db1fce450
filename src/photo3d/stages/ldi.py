"""Building the layered depth image (:class:`~photo3d.structures.ldi.LDI`): the trivial
one-layer LDI of a photo, and its links cut along the depth edges.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics
from photo3d.structures.ldi import LABEL_ORIGINAL, LDI


def from_image(
    image: np.ndarray,
    disparity: np.ndarray,
    *,
    intrinsics: Intrinsics | None = None,
    mapping: DepthMapping | None = None,
) -> LDI:
    """The trivial LDI: one fully 4-connected layer.

    Args:
        image: ``(H, W, 3) float32`` in [0, 1].
        disparity: ``(H, W) float32`` normalised disparity.
        intrinsics: defaults to :meth:`Intrinsics.default`.
        mapping: defaults to the authors' mapping (:class:`DepthMapping`).

    Example:
        >>> ldi = from_image(np.zeros((2, 3, 3), np.float32), np.zeros((2, 3), np.float32))
        >>> ldi.size, ldi.links[0].tolist()
        (6, [-1, 1, -1, 3])
    """
    h, w = disparity.shape
    idx = np.arange(h * w, dtype=np.int32).reshape(h, w)
    links = np.full((h, w, 4), -1, np.int32)
    links[:, 1:, 0] = idx[:, :-1]
    links[:, :-1, 1] = idx[:, 1:]
    links[1:, :, 2] = idx[:-1, :]
    links[:-1, :, 3] = idx[1:, :]
    yy, xx = np.divmod(np.arange(h * w, dtype=np.int32), np.int32(w))
    return LDI(
        y=yy.astype(np.int32),
        x=xx.astype(np.int32),
        color=np.ascontiguousarray(image.reshape(-1, 3), np.float32),
        disparity=np.ascontiguousarray(disparity.reshape(-1), np.float32),
        links=links.reshape(-1, 4),
        label=np.full(h * w, LABEL_ORIGINAL, np.uint8),
        intrinsics=intrinsics or Intrinsics.default(w, h),
        mapping=mapping or DepthMapping(),
    )


def cut(ldi: LDI, cuts: np.ndarray) -> LDI:
    """Remove the links marked in a cut mask (both directions).

    Args:
        ldi: an LDI whose first ``H * W`` pixels are the input image.
        cuts: ``(H, W) uint8`` direction bit set per input pixel.

    Example:
        >>> ldi = from_image(np.zeros((1, 2, 3), np.float32), np.zeros((1, 2), np.float32))
        >>> cut(ldi, np.array([[2, 0]], np.uint8)).links.tolist()
        [[-1, -1, -1, -1], [-1, -1, -1, -1]]
    """
    links = ldi.links.copy()
    flat = cuts.reshape(-1)
    for d in range(4):
        src = np.nonzero(flat & (1 << d))[0]
        dst = links[src, d]
        ok = dst >= 0
        links[dst[ok], d ^ 1] = -1
        links[src, d] = -1
    return replace(ldi, links=links)
