"""Regions of one pass -> image-like inpainting patches (and back)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from photo3d.stages.regions import Regions
from photo3d.structures.ldi import LDI
from photo3d.structures.patch import Patch


@dataclass(frozen=True)
class PatchJob:
    """One patch plus where its synthesis values go in the LDI.

    Attributes:
        patch: the inpainter input.
        new_y, new_x: ``(S,) int32`` lattice positions of new pixels.
        band: ``(B,) int64`` existing LDI pixels re-synthesised in place (dilation).
        edge: the index of the edge whose regions these are (-1: not given).
    """

    patch: Patch
    new_y: np.ndarray
    new_x: np.ndarray
    band: np.ndarray
    edge: int = -1


def extract_patches(ldi: LDI, regions: Regions, edge_pixels: np.ndarray, *,
                    margin: int, scale: float = 1.0) -> list[PatchJob]:
    """Rasterise each edge's regions into a :class:`Patch` (its bounding box + margin):
    the list of :func:`iter_patches`.

    Args:
        ldi: the LDI the regions were grown on.
        regions: context and synthesis regions of the pass.
        edge_pixels: ``(K,) int64`` all silhouette pixels of the pass (the patch's
            ``edges`` channel marks those that lie in its context).
        margin: extra pixels around the bounding box.
        scale: lattice pixels per pixel of the input photo (:attr:`Patch.scale`).

    Returns:
        One :class:`PatchJob` per edge that has anything to synthesise.

    Example:
        >>> from photo3d.stages.ldi import from_image, cut
        >>> from photo3d.stages.regions import RegionSizes, find_regions
        >>> d = np.zeros((8, 8), np.float32); d[:, 4:] = 1.0
        >>> cuts = np.zeros((8, 8), np.uint8); cuts[:, 3] = 2
        >>> ldi = cut(from_image(np.ones((8, 8, 3), np.float32), d), cuts)
        >>> sil = np.arange(8) * 8 + 3
        >>> sizes = RegionSizes(synthesis_iterations=2, context_iterations=3, dilation=1,
        ...                     threshold=0.04, thin_context=0.0, context_around=False,
        ...                     thin_context_iterations=1)
        >>> r = find_regions(ldi, np.array([0, 8]), sil, sizes)
        >>> job = extract_patches(ldi, r, sil, margin=1)[0]
        >>> job.patch.shape, int(job.patch.context.sum()), int(job.patch.synthesis.sum())
        ((10, 7), 16, 24)
    """
    return list(iter_patches(ldi, regions, edge_pixels, margin=margin, scale=scale))


def iter_patches(ldi: LDI, regions: Regions, edge_pixels: np.ndarray, *,
                 margin: int, scale: float = 1.0,
                 edges: Iterable[int] | None = None) -> Iterator[PatchJob]:
    """:func:`extract_patches` one job at a time, in edge order, so that a pass need
    not hold all of its patches at once (same arguments; ``edges``: only these edges'
    jobs, in this order; None: every edge).

    Example:
        >>> from photo3d.stages.regions import Regions
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.zeros((2, 2, 3), np.float32), np.zeros((2, 2), np.float32))
        >>> none = Regions(np.zeros(1, np.int64), np.zeros(0, np.int64),
        ...                np.zeros(0, np.int32), np.zeros(1, np.int64),
        ...                np.zeros(0, np.int32), np.zeros(0, np.int32), 0)
        >>> list(iter_patches(ldi, none, np.zeros(0, np.int64), margin=1))
        []
    """
    is_edge = np.zeros(ldi.size, bool)
    is_edge[edge_pixels] = True
    for e in range(regions.count) if edges is None else edges:
        c0, c1 = regions.context_ptr[e], regions.context_ptr[e + 1]
        s0, s1 = regions.synthesis_ptr[e], regions.synthesis_ptr[e + 1]
        ctx, steps = regions.context[c0:c1], regions.context_step[c0:c1]
        band_sel = steps < regions.dilation
        if band_sel.all():  # keep some context: skip the dilation for tiny regions
            band_sel[:] = False
        band, ctx = ctx[band_sel], ctx[~band_sel]
        sy, sx = regions.synthesis_y[s0:s1], regions.synthesis_x[s0:s1]
        if sy.size == 0 and band.size == 0:
            continue
        all_y = np.concatenate([ldi.y[ctx], ldi.y[band], sy])
        all_x = np.concatenate([ldi.x[ctx], ldi.x[band], sx])
        y0, x0 = int(all_y.min()) - margin, int(all_x.min()) - margin
        h, w = int(all_y.max()) - y0 + 1 + margin, int(all_x.max()) - x0 + 1 + margin
        cy, cx = ldi.y[ctx] - y0, ldi.x[ctx] - x0
        color = np.zeros((h, w, 3), np.float32)
        disparity = np.zeros((h, w), np.float32)
        edges = np.zeros((h, w), np.float32)
        context = np.zeros((h, w), bool)
        synthesis = np.zeros((h, w), bool)
        color[cy, cx] = ldi.color[ctx]
        disparity[cy, cx] = ldi.disparity[ctx]
        edges[cy, cx] = is_edge[ctx]
        context[cy, cx] = True
        synthesis[sy - y0, sx - x0] = True
        synthesis[ldi.y[band] - y0, ldi.x[band] - x0] = True
        patch = Patch(color, disparity, edges, context, synthesis, (y0, x0), scale)
        yield PatchJob(patch=patch, new_y=sy, new_x=sx, band=band, edge=int(e))
