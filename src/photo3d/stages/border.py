"""Border extrapolation: extend the input layer beyond the image frame.

When the camera moves, the renderer looks past the photo's edges. The input layer
is extended by ``border`` pixels on every side by replicating the outermost pixels
along the outward direction (corners replicate the corner pixel). Links are
replicated too: two border pixels are linked when their source pixels are the same
or linked, so depth edges that reach the frame continue into the border instead of
being stretched. Border pixels get label 5 (the authors' label for extrapolation).

Their colours are then filled by :func:`fill_border` (the pipeline passes the fill,
by default the ``structured`` inpainter, which carries the photo's lines and texture
outward as the authors' inpainting of the frame does); their disparity stays the
replicated one, so the links above hold.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from photo3d.structures.ldi import LABEL_BORDER, LDI


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
        alpha=np.concatenate([ldi.alpha, np.ones(n_new, np.float32)]),
        border=b,
    )


BorderFill = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``fill(color, disparity, context, synthesis) -> color``: every array on the padded
lattice ``(H + 2b, W + 2b)``; ``color`` ``(.., 3) float32`` and ``disparity`` are zero
outside ``context``; returns the ``(.., 3) float32`` colours (read under ``synthesis``)."""


def fill_border(ldi: LDI, fill: BorderFill, *, context: int) -> LDI:
    """Replace the colours of the border pixels of :func:`extend_border` by ``fill``'s.

    Args:
        ldi: the LDI :func:`extend_border` returned (nothing added since).
        fill: see :data:`BorderFill`; it sees the photo's outer band only.
        context: width of that band in pixels (at least 1).

    Returns:
        A new LDI whose border pixels have the filled colours (positions, disparity,
        links and labels unchanged).

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> img = np.zeros((4, 4, 3), np.float32); img[:, 2:] = 1.0
        >>> ext = extend_border(from_image(img, np.ones((4, 4), np.float32)), 2)
        >>> grey = lambda color, disparity, ctx, syn: np.full(color.shape, 0.5, np.float32)
        >>> out = fill_border(ext, grey, context=1)
        >>> float(out.color[16:].mean()), bool((out.color[:16] == ext.color[:16]).all())
        (0.5, True)
    """
    b = ldi.border
    if b == 0:
        return ldi
    h, w = ldi.height, ldi.width
    hp, wp = h + 2 * b, w + 2 * b
    n_in = h * w
    ring = np.ones((hp, wp), bool)
    ring[b:b + h, b:b + w] = False
    if ldi.size != n_in + int(ring.sum()):
        raise ValueError("fill_border needs the LDI extend_border returned")
    band = np.zeros((hp, wp), bool)
    band[b:b + h, b:b + w] = True
    c = max(1, int(context))
    band[b + c:b + h - c, b + c:b + w - c] = False
    color = np.zeros((hp, wp, 3), np.float32)
    disparity = np.zeros((hp, wp), np.float32)
    color[b:b + h, b:b + w] = ldi.color[:n_in].reshape(h, w, 3)
    disparity[b:b + h, b:b + w] = ldi.disparity[:n_in].reshape(h, w)
    color[~band] = 0.0
    disparity[~band] = 0.0
    filled = np.asarray(fill(color, disparity, band, ring), np.float32)
    new_color = ldi.color.copy()
    new_color[n_in:] = np.clip(filled[ring], 0.0, 1.0)
    return replace(ldi, color=new_color)
