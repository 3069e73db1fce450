"""One inpainting pass's regions and patches, from a :class:`~photo3d.config.Config` and
the working size: the only place that sizes and grows regions.

:func:`photo3d.make`, the training pairs (:mod:`photo3d.train.pairs`) and the held-out
benchmark's shapes (:mod:`photo3d.eval.heldout_data`) all call these two functions, so
what training learns from and what the benchmark measures are the shapes users get:

* :func:`start` - the LDI a first pass starts from: the preprocessed photo's one layer,
  its links cut along the depth edges, the extrapolated frame
  (:func:`~photo3d.stages.border.extend_border`), and the edges' silhouette pixels;
* :func:`pass_patches` - one pass: :func:`region_sizes` (the config's sizes at the
  working size, the pass's context rule) -> :func:`pass_regions` (the regions, within
  :func:`pass_limit`) -> :func:`~photo3d.stages.patches.extract_patches`;
* what ``make`` runs (:func:`photo3d.pipeline.fill_pass` schedules it): the pass's
  :class:`PassPlan` (:func:`plan_pass`), the same regions, their patches in batches
  (:func:`patch_batches`; those that read the frame apart, :func:`border_readers`),
  the fills merged (:func:`merge_pass`).

A pass is bounded whatever the depth holds (:func:`pass_limit`): a depth map of noise
or a fine checkerboard has a depth edge at every few pixels, and the regions of
thousands of edges, each grown as far as the config says, overlap many times over
(uniform noise at 1024 px: contexts 33 and patches 79 times the lattice, 6 GB).
Past the limit the pass grows every edge's regions less far (:func:`pass_regions`);
photos stay well inside it (the sample: at most 2.1, 0.9 and 6.2 times the lattice
of context, synthesis and patch pixels per pass). The LDI stays under
:data:`LDI_LIMIT` times the lattice (:func:`ldi_room`), and a pass hands at most as
many edges to the next one as it had itself.

The context rule is a parameter: ``paper_context=True`` gives the paper's contexts (the
side a hidden area was seen from; the learned nets were trained on them, and training
and the held-out shapes keep them), ``False`` adds photo3d's
:attr:`~photo3d.config.RegionConfig.context_around` and
:attr:`~photo3d.config.RegionConfig.thin_context`.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics
from photo3d.config import Config
from photo3d.stages.border import extend_border
from photo3d.stages.edges import edges_csr
from photo3d.stages.ldi import cut, from_image
from photo3d.stages.merge import Fill, Merged, merge_fills
from photo3d.stages.patches import PatchJob, extract_patches, iter_patches
from photo3d.stages.preprocess import Preprocessed
from photo3d.stages.regions import RegionLimit, Regions, RegionSizes, find_regions
from photo3d.stages.silhouettes import Behind, silhouettes_of
from photo3d.structures.ldi import LABEL_BORDER, LDI

CONTEXT_LIMIT = 6.0
"""Context pixels one pass may grow, summed over its edges, per lattice position (the
sample at 1024 px: 2.1 in its first pass; the motorcycle's raw disparity with unknown
= 0: 3.9 in its second)."""
SYNTHESIS_LIMIT = 2.0
"""Synthesis positions one pass may grow, summed over its edges, per lattice position
(the raw disparity's first pass: 1.5)."""
AREA_LIMIT = 16.0
"""Patch pixels (each edge's bounding box) one pass may fill, summed over its edges,
per lattice position (the raw disparity: 8.7)."""
LDI_LIMIT = 2.0
"""LDI pixels per lattice position after any pass (the sample: 1.6): a pass that would
add more keeps, in each of its jobs, the same share of new pixels, those nearest the
edge, and hands on no edges. Saving takes up to about 700 bytes per LDI pixel (the
light mesh of a fragmented LDI); bounding the LDI keeps ``make`` and its files within
:func:`photo3d.resources.memory_estimate` (3x3 blocks of noise at 1024 px: an LDI of
2.3M pixels, 1.94 GB, before this limit)."""

@dataclass(frozen=True)
class PassInput:
    """An LDI and the depth edges a pass grows regions from.

    Attributes:
        ldi: the LDI, links cut along the edges.
        edge_ptr: ``(E + 1,) int64`` CSR offsets into ``edge_pixels``.
        edge_pixels: ``(K,) int64`` background silhouette pixels of each edge.
        index: ``ldi.position_index()`` if known (a merge's), else None.
        behind: the soft silhouettes' fringe
            (:meth:`~photo3d.stages.silhouettes.Silhouettes.behind`) for
            :func:`~photo3d.stages.silhouettes.paint_behind` once the passes are
            done; None if there is no fringe.
    """

    ldi: LDI
    edge_ptr: np.ndarray
    edge_pixels: np.ndarray
    index: tuple[np.ndarray, np.ndarray] | None = None
    behind: Behind | None = None

    @property
    def edges(self) -> int:
        """Number of edges."""
        return int(self.edge_ptr.size - 1)


def start(pre: Preprocessed, *, config: Config, border: bool = True,
          intrinsics: Intrinsics | None = None,
          mapping: DepthMapping | None = None) -> PassInput:
    """The first pass's input: ``pre``'s one-layer LDI cut along its depth edges (its
    silhouettes soft if ``config.edges`` is ``soft``:
    :func:`~photo3d.stages.silhouettes.silhouettes_of`), with the extrapolated frame
    (``config.regions.border`` px at 1024) unless ``border`` is off.

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
    sil = silhouettes_of(pre.image, pre.disparity, pre.edges.cuts, config=config,
                         working_size=pre.working_size)
    ldi = cut(from_image(sil.color, pre.disparity, intrinsics=intrinsics, mapping=mapping),
              pre.edges.cuts)
    if sil.fringe:
        ldi = replace(ldi, alpha=sil.alpha.reshape(-1))
    if border:
        ldi = extend_border(ldi, config.spatial(config.regions.border, pre.working_size))
    edge_ptr, edge_pixels = edges_csr(pre.edges.labels, pre.edges.count)
    return PassInput(ldi, edge_ptr, edge_pixels, behind=sil.behind() if sil.fringe else None)


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
        >>> [region_sizes(Config(edges=e), 64).synthesis_iterations for e in ("align", "soft")]
        [2, 3]
        >>> later = region_sizes(Config(), 512, pass_index=1, later_context=0.5,
        ...                      paper_context=True)
        >>> later.context_iterations, later.dilation, later.context_around
        (25, 0, False)
    """
    reg = config.regions

    def px(value: int) -> int:
        return config.spatial(value, working_size)

    thin = 1.0 if pass_index == 0 else later_context
    # soft silhouettes: the fringe on the near side is partly see-through, so a camera
    # move shows what lies behind it too: the region reaches as far again beyond it (a
    # small photo's region is only 2-3 pixels deep, and a transparent fringe pixel used
    # one of them; at 1024 px it is 40 deep, the fringe 3)
    fringe = px(config.silhouettes.band) if config.edges == "soft" else 0
    return RegionSizes(
        synthesis_iterations=max(px(reg.synthesis_iterations), 2 * fringe + 1),
        context_iterations=max(1, round(px(reg.context_iterations) * thin)),
        dilation=px(reg.edge_dilation) if pass_index == 0 else 0,
        threshold=config.preprocess.discontinuity,
        thin_context=0.0 if paper_context else reg.thin_context,
        context_around=reg.context_around and not paper_context,
        thin_context_iterations=px(reg.thin_context_iterations),
    )


def pass_limit(ldi: LDI) -> RegionLimit:
    """How much one pass from ``ldi`` may grow: :data:`CONTEXT_LIMIT`,
    :data:`SYNTHESIS_LIMIT` and :data:`AREA_LIMIT` times the lattice.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> pass_limit(from_image(np.zeros((10, 10, 3), np.float32),
        ...                       np.zeros((10, 10), np.float32)))
        RegionLimit(context=600, synthesis=200, area=1600)
    """
    rows, cols = ldi.lattice_shape
    lattice = rows * cols
    return RegionLimit(context=int(CONTEXT_LIMIT * lattice),
                       synthesis=int(SYNTHESIS_LIMIT * lattice),
                       area=int(AREA_LIMIT * lattice))


def ldi_room(ldi: LDI) -> int:
    """How many pixels a pass may still add to ``ldi`` (:data:`LDI_LIMIT`).

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> ldi_room(from_image(np.zeros((10, 10, 3), np.float32),
        ...                     np.zeros((10, 10), np.float32)))
        100
    """
    rows, cols = ldi.lattice_shape
    return max(0, int(LDI_LIMIT * rows * cols) - ldi.size)


def pass_regions(state: PassInput, sizes: RegionSizes, *,
                 index: tuple[np.ndarray, np.ndarray] | None = None) -> Regions:
    """The regions of ``state``'s edges at ``sizes``, or, past :func:`pass_limit`, at
    smaller sizes: every flood fill is shortened (by the factor the part grown so far
    says is needed) and the regions grown again, until they fit; if they do not fit
    even one step deep, the edges that do (in order) are kept and the rest dropped.

    Args:
        state: the LDI and its edges.
        sizes: the pass's sizes (:func:`region_sizes`).
        index: ``state.ldi.position_index()`` if the caller has it.

    Returns:
        :class:`~photo3d.stages.regions.Regions` (``count`` below ``state.edges`` only in
        that last case).

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> cfg = Config(size=None)
        >>> rng = np.random.default_rng(0)
        >>> noise = rng.random((64, 64)).astype(np.float32)  # an edge every few pixels
        >>> first = start(preprocess(np.zeros((64, 64, 3), np.float32), noise, config=cfg),
        ...               config=cfg, border=False)
        >>> sizes = region_sizes(cfg, 64)
        >>> fits = pass_regions(first, sizes)
        >>> limit = pass_limit(first.ldi)
        >>> fits.context.size <= limit.context, fits.synthesis_y.size <= limit.synthesis
        (True, True)
    """
    limit = pass_limit(state.ldi)
    silhouettes = max(int(state.edge_ptr[-1]), 1)
    index = index if index is not None else state.ldi.position_index()
    while True:
        regions = find_regions(state.ldi, state.edge_ptr, state.edge_pixels, sizes,
                               limit=limit, index=index)
        if regions.count >= state.edges:
            return regions
        # what all edges would need, from the share of silhouette pixels grown so far
        done = max(int(state.edge_ptr[regions.count]), 1) / silhouettes
        need = max(regions.context.size / max(limit.context, 1),
                   regions.synthesis_y.size / max(limit.synthesis, 1),
                   int(regions.areas(state.ldi).sum()) / max(limit.area, 1)) / done
        smaller = _shrunk(sizes, min(0.9, max(0.25, 0.9 / np.sqrt(max(need, 1.0)))))
        if smaller == sizes:  # one step deep and still too much: the edges that fit
            fit = ((np.diff(regions.context_ptr).cumsum() <= limit.context)
                   & (np.diff(regions.synthesis_ptr).cumsum() <= limit.synthesis)
                   & (regions.areas(state.ldi).cumsum() <= limit.area))
            return regions.head(int(np.argmin(fit)) if not fit.all() else regions.count)
        sizes = smaller


def _shrunk(sizes: RegionSizes, factor: float) -> RegionSizes:
    """``sizes`` with every flood fill ``factor`` as deep, and at least one step less
    (but never below one step)."""

    def less(steps: int) -> int:
        return max(1, min(steps - 1, int(steps * factor)))

    return replace(sizes, synthesis_iterations=less(sizes.synthesis_iterations),
                   context_iterations=less(sizes.context_iterations),
                   thin_context_iterations=less(sizes.thin_context_iterations),
                   dilation=min(sizes.dilation, less(sizes.context_iterations)))


def pass_patches(state: PassInput, *, config: Config, working_size: int, margin: int,
                 scale: float = 1.0, pass_index: int = 0, later_context: float = 1.0,
                 paper_context: bool = False) -> list[PatchJob]:
    """One pass's regions (:func:`region_sizes`, then :func:`pass_regions`) as the
    inpainter's patches.

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
    regions = pass_regions(state, sizes)
    return extract_patches(state.ldi, regions, state.edge_pixels, margin=margin, scale=scale)


@dataclass(frozen=True)
class PassPlan:
    """Everything one inpainting pass needs besides its LDI (:func:`plan_pass`).

    Attributes:
        sizes: the regions' sizes and rules (:func:`region_sizes`).
        margin: the backend's context-free margin around each patch, px.
        scale: lattice pixels per pixel of the input photo (:attr:`Patch.scale`).
        label: the new pixels' label (2 in the first pass, 3 later).
        threshold: the disparity step that is an edge (normalised disparity).
        min_edge_length: the next pass's edges shorter than this are dropped, px.
        overwrite_band: :attr:`~photo3d.config.RegionConfig.overwrite_dilation`.
    """

    sizes: RegionSizes
    margin: int
    scale: float
    label: int
    threshold: float
    min_edge_length: int
    overwrite_band: int


def plan_pass(config: Config, working_size: int, *, margin: int, scale: float = 1.0,
              pass_index: int = 0, later_context: float = 1.0,
              paper_context: bool = False) -> PassPlan:
    """Pass ``pass_index``'s :class:`PassPlan` from the config at ``working_size``.

    Args:
        config, working_size, pass_index, later_context, paper_context: see
            :func:`region_sizes`.
        margin: the backend's context-free margin around each patch, px.
        scale: lattice pixels per pixel of the input photo.

    Example:
        >>> plan = plan_pass(Config(), 512, margin=1, pass_index=1)
        >>> plan.label, plan.sizes.dilation, plan.min_edge_length
        (3, 0, 5)
    """
    pre = config.preprocess
    return PassPlan(
        sizes=region_sizes(config, working_size, pass_index=pass_index,
                           later_context=later_context, paper_context=paper_context),
        margin=margin, scale=scale, label=min(pass_index + 2, 3),
        threshold=pre.discontinuity,
        min_edge_length=config.spatial(pre.min_edge_length, working_size),
        overwrite_band=config.regions.overwrite_dilation)


def border_readers(ldi: LDI, regions: Regions) -> tuple[list[int], list[int]]:
    """The edges of ``regions`` whose context holds no border pixel (label
    :data:`~photo3d.structures.ldi.LABEL_BORDER`: they may be filled before the
    frame's colours are), and those whose context does, each in edge order.

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[16:48, 16:48] = 3.0
        >>> first = start(preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg),
        ...               config=cfg)
        >>> border_readers(first.ldi, pass_regions(first, region_sizes(cfg, 64)))
        ([0], [])
    """
    every = list(range(regions.count))
    if not regions.count:
        return every, []
    border = ldi.label[regions.context] == LABEL_BORDER
    ptr = regions.context_ptr
    seen = np.concatenate([[0], np.cumsum(border)])
    reads = seen[ptr[1:]] > seen[ptr[:-1]]
    return ([e for e in every if not reads[e]], [e for e in every if reads[e]])


def patch_batches(ldi: LDI, regions: Regions, edge_pixels: np.ndarray, plan: PassPlan, *,
                  edges: Sequence[int] | None = None, area: int | None = None,
                  first_area: int | None = None) -> Iterator[list[PatchJob]]:
    """The patches of ``edges`` (None: every edge) in edge order, in lists of about
    ``area`` patch pixels each (the first of ``first_area``, default ``area // 8``, so
    that a fill can start sooner), so that a pass need not hold all of its patches at
    once; ``area`` None: one list.

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[8:24, 8:24] = d[40:56, 40:56] = 3.0
        >>> first = start(preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg),
        ...               config=cfg, border=False)
        >>> plan = plan_pass(cfg, 64, margin=1)
        >>> regions = pass_regions(first, plan.sizes)
        >>> [len(b) for b in patch_batches(first.ldi, regions, first.edge_pixels, plan,
        ...                                area=1)]
        [1, 1]
    """
    limit = None if area is None else max(1, first_area or area // 8)
    batch, held = [], 0
    for job in iter_patches(ldi, regions, edge_pixels, margin=plan.margin, scale=plan.scale,
                            edges=edges):
        batch.append(job)
        held += job.patch.shape[0] * job.patch.shape[1]
        if limit is not None and held >= limit:
            yield batch
            batch, held, limit = [], 0, max(1, area)
    if batch:
        yield batch


def merge_pass(state: PassInput, plan: PassPlan, fills: Sequence[tuple[int, Fill]], *,
               ldi: LDI | None = None,
               index: tuple[np.ndarray, np.ndarray] | None = None) -> Merged:
    """A pass's fills merged into the LDI, with the next pass's edges
    (:func:`~photo3d.stages.merge.merge_fills`: at most as many as this pass's, the
    longest; the LDI within :func:`ldi_room`).

    Args:
        state: the pass's input.
        plan: the pass's plan.
        fills: ``(edge, fill)`` pairs in any order (merged in edge order, so the
            result does not depend on the order the patches were filled in).
        ldi: the LDI to merge into if not ``state.ldi`` (the same pixels and links,
            its frame's colours filled meanwhile).
        index: ``state.ldi.position_index()`` if the caller has it.

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> from photo3d.stages.merge import take
        >>> from photo3d.structures.patch import InpaintResult
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[16:48, 16:48] = 3.0
        >>> first = start(preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg),
        ...               config=cfg)
        >>> plan = plan_pass(cfg, 64, margin=1)
        >>> job = pass_patches(first, config=cfg, working_size=64, margin=1)[0]
        >>> grey = InpaintResult(np.full(job.patch.shape + (3,), 0.5, np.float32),
        ...                      job.patch.disparity, np.zeros(job.patch.shape, np.float32))
        >>> merged = merge_pass(first, plan, [(job.edge, take(first.ldi, job, grey))])
        >>> merged.added > 0, float(merged.ldi.color[-1, 0])
        (True, 0.5)
    """
    target = state.ldi if ldi is None else ldi
    ordered = [fill for _, fill in sorted(fills, key=lambda pair: pair[0])]
    return merge_fills(target, ordered, label=plan.label, threshold=plan.threshold,
                       min_edge_length=plan.min_edge_length,
                       overwrite_band=plan.overwrite_band, max_edges=state.edges,
                       room=ldi_room(state.ldi), index=index)
