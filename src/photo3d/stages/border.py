"""Border extrapolation: extend the input layer beyond the image frame.

When the camera moves, the renderer looks past the photo's edges. The input layer
is extended by ``border`` pixels on every side by replicating the outermost pixels
along the outward direction (corners replicate the corner pixel). Links are
replicated too: two border pixels are linked when their source pixels are the same
or linked, so depth edges that reach the frame continue into the border instead of
being stretched. Border pixels get label 5 (the authors' label for extrapolation).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from photo3d.stages.ldi import LABEL_BORDER, LDI


def extend_border(ldi: LDI, border: int) -> LDI:
    """Add a ``border``-pixel frame of extrapolated pixels around the input layer.

    Args:
        ldi: LDI whose first ``H * W`` pixels are the input image (``ldi.border == 0``).
        border: frame width in pixels (0 returns ``ldi`` unchanged).

    Returns:
        A new LDI with ``(H + 2b) * (W + 2b) - H * W`` extra pixels and ``border = b``.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.zeros((2, 2, 3), np.float32), np.zeros((2, 2), np.float32))
        >>> ext = extend_border(ldi, 1)
        >>> ext.size, ext.lattice_shape, int(ext.x.min()), int(ext.y.max())
        (16, (4, 4), -1, 2)
    """
    if border <= 0:
        return ldi
    if ldi.border != 0:
        raise ValueError("the LDI already has a border")
    h, w, b = ldi.height, ldi.width, border
    hp, wp = h + 2 * b, w + 2 * b
    py, px = np.mgrid[0:hp, 0:wp]
    sy, sx = np.clip(py - b, 0, h - 1), np.clip(px - b, 0, w - 1)
    src = (sy * w + sx).astype(np.int64)
    outside = (py < b) | (py >= b + h) | (px < b) | (px >= b + w)
    n_new = int(outside.sum())
    ids = src.copy()
    ids[outside] = ldi.size + np.arange(n_new)

    links = np.full((ldi.size + n_new, 4), -1, np.int32)
    links[: ldi.size] = ldi.links
    for axis, (fwd, back) in ((1, (1, 0)), (0, (3, 2))):
        if axis == 1:
            a, bb, sa, sb = ids[:, :-1], ids[:, 1:], src[:, :-1], src[:, 1:]
            any_out = outside[:, :-1] | outside[:, 1:]
        else:
            a, bb, sa, sb = ids[:-1, :], ids[1:, :], src[:-1, :], src[1:, :]
            any_out = outside[:-1, :] | outside[1:, :]
        linked = any_out & ((sa == sb) | (ldi.links[sa, fwd] == sb))
        links[a[linked], fwd] = bb[linked]
        links[bb[linked], back] = a[linked]

    new_src = src[outside]
    return replace(
        ldi,
        y=np.concatenate([ldi.y, (py[outside] - b).astype(np.int32)]),
        x=np.concatenate([ldi.x, (px[outside] - b).astype(np.int32)]),
        color=np.concatenate([ldi.color, ldi.color[new_src]]),
        disparity=np.concatenate([ldi.disparity, ldi.disparity[new_src]]),
        links=links,
        label=np.concatenate([ldi.label, np.full(n_new, LABEL_BORDER, np.uint8)]),
        border=b,
    )
