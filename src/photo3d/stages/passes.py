"""One inpainting pass's regions and patches, from a :class:`~photo3d.config.Config` and
the working size: the only place that sizes and grows regions.

:func:`photo3d.make`, the training pairs (:mod:`photo3d.train.pairs`) and the held-out
benchmark's shapes (:mod:`photo3d.eval.heldout_data`) all call these two functions, so
what training learns from and what the benchmark measures are the shapes users get:

* :func:`start` - the LDI a first pass starts from: the preprocessed photo's one layer,
  its links cut along the depth edges, the extrapolated frame
  (:func:`~photo3d.stages.border.extend_border`), and the edges' silhouette pixels;
* :func:`pass_patches` - one pass: :func:`region_sizes` (the config's sizes at the
  working size, the pass's context rule) -> :func:`~photo3d.stages.regions.find_regions`
  -> :func:`~photo3d.stages.patches.extract_patches`.

The context rule is a parameter: ``paper_context=True`` gives the paper's contexts (the
side a hidden area was seen from; the learned nets were trained on them, and training
and the held-out shapes keep them), ``False`` adds photo3d's
:attr:`~photo3d.config.RegionConfig.context_around` and
:attr:`~photo3d.config.RegionConfig.thin_context`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics
from photo3d.config import Config
from photo3d.stages.border import extend_border
from photo3d.stages.edges import edges_csr
from photo3d.stages.ldi import cut, from_image
from photo3d.stages.patches import PatchJob, extract_patches
from photo3d.stages.preprocess import Preprocessed
from photo3d.stages.regions import RegionSizes, find_regions
from photo3d.structures.ldi import LDI


@dataclass(frozen=True)
class PassInput:
    """An LDI and the depth edges a pass grows regions from.

    Attributes:
        ldi: the LDI, links cut along the edges.
        edge_ptr: ``(E + 1,) int64`` CSR offsets into ``edge_pixels``.
        edge_pixels: ``(K,) int64`` background silhouette pixels of each edge.
    """

    ldi: LDI
    edge_ptr: np.ndarray
    edge_pixels: np.ndarray

    @property
    def edges(self) -> int:
        """Number of edges."""
        return int(self.edge_ptr.size - 1)


def start(pre: Preprocessed, *, config: Config, border: bool = True,
          intrinsics: Intrinsics | None = None,
          mapping: DepthMapping | None = None) -> PassInput:
    """The first pass's input: ``pre``'s one-layer LDI cut along its depth edges, with
    the extrapolated frame (``config.regions.border`` px at 1024) unless ``border`` is off.

    Args:
        pre: the preprocessed photo (working size, disparity, linked depth edges).
        config: pipeline configuration.
        border: extend the frame, as ``make`` does (training turns it off: it would only
            add shapes that hug the image frame).
        intrinsics, mapping: the LDI's camera and depth mapping (defaults:
            :func:`~photo3d.stages.ldi.from_image`'s).

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[16:48, 16:48] = 3.0  # a near square
        >>> pre = preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg)
        >>> first = start(pre, config=cfg)
        >>> first.edges, first.ldi.border
        (1, 4)
    """
    ldi = cut(from_image(pre.image, pre.disparity, intrinsics=intrinsics, mapping=mapping),
              pre.edges.cuts)
    if border:
        ldi = extend_border(ldi, config.spatial(config.regions.border, pre.working_size))
    edge_ptr, edge_pixels = edges_csr(pre.edges.labels, pre.edges.count)
    return PassInput(ldi, edge_ptr, edge_pixels)


def region_sizes(config: Config, working_size: int, *, pass_index: int = 0,
                 later_context: float = 1.0, paper_context: bool = False) -> RegionSizes:
    """The region sizes and rules of pass ``pass_index`` at ``working_size``.

    Args:
        config: pipeline configuration (sizes in px at 1024, the context rules).
        working_size: the longer side of the working image, px.
        pass_index: 0 = the input's depth edges (with the edge dilation), 1+ = later.
        later_context: context depth after the first pass, as a fraction of the first's.
        paper_context: the paper's contexts only (no ``context_around``/``thin_context``).

    Example:
        >>> s = region_sizes(Config(), 512)
        >>> s.synthesis_iterations, s.context_iterations, s.dilation, s.context_around
        (20, 50, 2, True)
        >>> later = region_sizes(Config(), 512, pass_index=1, later_context=0.5,
        ...                      paper_context=True)
        >>> later.context_iterations, later.dilation, later.context_around
        (25, 0, False)
    """
    reg = config.regions

    def px(value: int) -> int:
        return config.spatial(value, working_size)

    thin = 1.0 if pass_index == 0 else later_context
    return RegionSizes(
        synthesis_iterations=px(reg.synthesis_iterations),
        context_iterations=max(1, round(px(reg.context_iterations) * thin)),
        dilation=px(reg.edge_dilation) if pass_index == 0 else 0,
        threshold=config.preprocess.discontinuity,
        thin_context=0.0 if paper_context else reg.thin_context,
        context_around=reg.context_around and not paper_context,
        thin_context_iterations=px(reg.thin_context_iterations),
    )


def pass_patches(state: PassInput, *, config: Config, working_size: int, margin: int,
                 scale: float = 1.0, pass_index: int = 0, later_context: float = 1.0,
                 paper_context: bool = False) -> list[PatchJob]:
    """One pass's regions (:func:`region_sizes`, then
    :func:`~photo3d.stages.regions.find_regions`) as the inpainter's patches.

    Args:
        state: the LDI and its edges (:func:`start`, or a previous pass's merge).
        config, working_size, pass_index, later_context, paper_context: see
            :func:`region_sizes`.
        margin: the backend's context-free margin around each patch, px.
        scale: lattice pixels per pixel of the input photo (:attr:`Patch.scale`).

    Returns:
        One :class:`~photo3d.stages.patches.PatchJob` per edge with anything to fill.

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[16:48, 16:48] = 3.0
        >>> pre = preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg)
        >>> jobs = pass_patches(start(pre, config=cfg), config=cfg, working_size=64, margin=0)
        >>> len(jobs), bool((jobs[0].patch.context & jobs[0].patch.synthesis).any())
        (1, False)
    """
    sizes = region_sizes(config, working_size, pass_index=pass_index,
                         later_context=later_context, paper_context=paper_context)
    regions = find_regions(state.ldi, state.edge_ptr, state.edge_pixels, sizes)
    return extract_patches(state.ldi, regions, state.edge_pixels, margin=margin, scale=scale)
