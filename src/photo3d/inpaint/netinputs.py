"""What the learned backend's nets see of a patch (also what training feeds them).

:class:`NetInputs` builds every net input from a :class:`~photo3d.structures.patch.Patch`:
the learned backend at inference and :mod:`photo3d.train.samples` in training use it
both, so the two cannot drift apart. :func:`close_gaps` is the hole channel of the
depth and colour nets (the authors' ``open_small_mask``). :func:`diffusion_rgb` is
the refine colour net's RGB input (:mod:`photo3d.nets.refine`): the context's colours
with the diffusion fill under the hole.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import binary_dilation, maximum_filter, minimum_filter

from photo3d.camera import DepthMapping
from photo3d.inpaint.diffusion import diffuse
from photo3d.structures.patch import Patch


def close_gaps(context: np.ndarray, synthesis: np.ndarray, *, size: int = 41,
               iterations: int = 3) -> np.ndarray:
    """The hole mask the depth and colour nets see (the authors' ``open_small_mask``).

    ``context | synthesis`` is closed ``iterations`` times (dilation then erosion by a
    ``size`` x ``size`` square; outside the patch counts as empty for the dilation and
    as full for the erosion); the pixels this adds outside the context join the hole.

    Args:
        context, synthesis: ``(h, w) bool``.

    Returns:
        ``(h, w) bool``, a superset of ``synthesis`` disjoint from ``context``.

    Example:
        >>> ctx = np.zeros((1, 9), bool); ctx[0, :3] = True
        >>> syn = np.zeros((1, 9), bool); syn[0, 5:] = True
        >>> close_gaps(ctx, syn, size=3).astype(int).tolist()  # the 2-pixel gap closes
        [[0, 0, 0, 1, 1, 1, 1, 1, 1]]
    """
    closed = (context | synthesis).astype(np.uint8)
    for _ in range(iterations):
        closed = maximum_filter(closed, size, mode="constant", cval=0)
        closed = minimum_filter(closed, size, mode="constant", cval=1)
    return synthesis | (closed.astype(bool) & ~context)


def diffusion_rgb(rgb: np.ndarray, context: np.ndarray, synthesis: np.ndarray,
                  hole: np.ndarray | None = None) -> np.ndarray:
    """The refine net's RGB input: ``rgb`` under ``context``; under ``synthesis`` the
    diffusion backend's fill (:func:`photo3d.inpaint.diffusion.diffuse` from the
    context, the backend's iterations and tolerance: exactly what ``--inpainter
    diffusion`` gives those pixels); under the rest of ``hole`` (the gaps
    :func:`close_gaps` adds) a second fill from both; zeros elsewhere.

    Args:
        rgb: ``(3, h, w) float32`` in [0, 1] (only read under ``context``).
        context, synthesis: ``(h, w)`` 0/1 masks (disjoint).
        hole: ``(h, w)`` 0/1, a superset of ``synthesis`` (None: ``synthesis``).

    Returns:
        ``(3, h, w) float32``.

    Example:
        >>> ctx = np.array([[1, 0, 0, 1]], bool)
        >>> rgb = np.zeros((3, 1, 4), np.float32); rgb[:, 0, 3] = 1.0
        >>> [round(float(v), 2) for v in diffusion_rgb(rgb, ctx, ~ctx)[0, 0]]
        [0.0, 0.33, 0.67, 1.0]
    """
    ctx = context.astype(bool)
    syn = synthesis.astype(bool) & ~ctx
    filled = diffuse(np.ascontiguousarray(np.moveaxis(rgb, 0, 2), np.float32), ctx, syn)
    if hole is not None:
        gaps = hole.astype(bool) & ~syn & ~ctx
        if gaps.any():
            filled = diffuse(filled, ctx | syn, gaps)
    return np.ascontiguousarray(np.moveaxis(np.clip(filled, 0.0, 1.0), 2, 0), np.float32)


class NetInputs:
    """Per-patch net inputs, everything zero outside the context (the training data
    builds its inputs with this class too, so they match inference).

    Attributes (all ``(h, w) float32`` unless noted): ``ctx``, ``syn`` masks;
    ``hole`` (:func:`close_gaps`, depth and colour nets); ``rgb`` ``(3, h, w)``;
    ``edges``; ``disp`` (inverse depth / its maximum, edge net); ``log_depth`` (log
    depth minus ``log_mean``, its mean over the context); ``needs_edges`` (bool: a
    context edge touches the synthesis region).

    Example:
        >>> ctx = np.zeros((4, 6), bool); ctx[:, :3] = True
        >>> p = Patch(np.full((4, 6, 3), 0.5, np.float32) * ctx[..., None],
        ...           np.full((4, 6), 0.25, np.float32) * ctx, np.zeros((4, 6), np.float32),
        ...           ctx, ~ctx, (0, 0))
        >>> it = NetInputs(p, DepthMapping())
        >>> it.edge_input(it.edges).shape, float(it.disp.max()), it.needs_edges
        ((7, 4, 6), 1.0, False)
    """

    def __init__(self, p: Patch, mapping: DepthMapping) -> None:
        ctx = p.context.astype(bool)
        self.ctx = ctx.astype(np.float32)
        syn = p.synthesis.astype(bool) & ~ctx
        self.syn = syn.astype(np.float32)
        self.hole = close_gaps(ctx, syn).astype(np.float32)  # depth and colour nets
        self.rgb = np.where(ctx[None], np.moveaxis(p.color, 2, 0), 0).astype(np.float32)
        self.edges = np.where(ctx, p.edges, 0).astype(np.float32)
        depth = mapping.depth(np.where(ctx, p.disparity, 0))
        inv = np.where(ctx, 1.0 / depth, 0).astype(np.float32)
        self.disp = inv / inv.max() if ctx.any() else inv
        log = np.where(ctx, np.log(depth + 1e-8), 0)
        self.log_mean = float(log[ctx].mean()) if ctx.any() else 0.0
        self.log_depth = np.where(ctx, log - self.log_mean, 0).astype(np.float32)
        self.needs_edges = NetInputs.touches(p)

    @staticmethod
    def touches(p: Patch) -> bool:
        """A context edge of ``p`` touches its synthesis region (dilated by one pixel)."""
        ctx = p.context.astype(bool)
        dilated = binary_dilation(p.synthesis.astype(bool) & ~ctx,
                                  structure=np.ones((3, 3), bool))
        return bool((p.edges[dilated & ctx] > 0).any())

    def filled_rgb(self) -> np.ndarray:
        """``(3, h, w)``: :attr:`rgb` with the diffusion fill under :attr:`hole` (the
        refine colour net's RGB input, :func:`diffusion_rgb`)."""
        return diffusion_rgb(self.rgb, self.ctx > 0, self.syn > 0, self.hole > 0)

    def edge_input(self, edges: np.ndarray) -> np.ndarray:
        """``(7, h, w)`` edge-net input: rgb, disparity, ``edges``, context, synthesis."""
        return np.concatenate([self.rgb, np.stack([self.disp, edges, self.ctx, self.syn])])
