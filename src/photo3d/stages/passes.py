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
* :func:`fill_pass` - what ``make`` runs: the same regions, their patches filled and
  merged (:func:`~photo3d.stages.merge.merge_fills`).

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

from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TypeVar

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics
from photo3d.config import Config
from photo3d.progress import CountProgress
from photo3d.stages.border import extend_border
from photo3d.stages.edges import edges_csr
from photo3d.stages.ldi import cut, from_image
from photo3d.stages.merge import Merged, merge_fills, take
from photo3d.stages.patches import PatchJob, extract_patches, iter_patches
from photo3d.stages.preprocess import Preprocessed
from photo3d.stages.regions import RegionLimit, Regions, RegionSizes, find_regions
from photo3d.stages.silhouettes import silhouettes_of
from photo3d.structures.ldi import LABEL_BORDER, LDI
from photo3d.structures.patch import InpaintResult, Patch

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

T = TypeVar("T")

PassFill = Callable[[Sequence[Patch], CountProgress | None], list[InpaintResult]]
"""``fill(patches, progress) -> results``: a pass's inpainting (one result per patch,
in order; ``progress(done, total)`` after each patch, may be None)."""


@dataclass(frozen=True)
class PassInput:
    """An LDI and the depth edges a pass grows regions from.

    Attributes:
        ldi: the LDI, links cut along the edges.
        edge_ptr: ``(E + 1,) int64`` CSR offsets into ``edge_pixels``.
        edge_pixels: ``(K,) int64`` background silhouette pixels of each edge.
        index: ``ldi.position_index()`` if known (a merge's), else None.
        behind: the soft silhouettes' background estimates (``(pixels, colors)``,
            :meth:`~photo3d.stages.silhouettes.Silhouettes.behind`) for
            :func:`~photo3d.stages.silhouettes.paint_behind` once the passes are
            done; None if there is no fringe.
    """

    ldi: LDI
    edge_ptr: np.ndarray
    edge_pixels: np.ndarray
    index: tuple[np.ndarray, np.ndarray] | None = None
    behind: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def edges(self) -> int:
        """Number of edges."""
        return int(self.edge_ptr.size - 1)


def start(pre: Preprocessed, *, config: Config, border: bool = True,
          intrinsics: Intrinsics | None = None,
          mapping: DepthMapping | None = None) -> PassInput:
    """The first pass's input: ``pre``'s one-layer LDI cut along its depth edges (its
    silhouettes soft unless ``config.edges`` is ``exact``:
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


def _border_readers(ldi: LDI, regions: Regions, split: bool) -> tuple[list[int], list[int]]:
    """The edges of ``regions`` whose context holds no border pixel (label
    :data:`~photo3d.structures.ldi.LABEL_BORDER`), and those whose context does, in
    order; without ``split``, every edge and none."""
    every = list(range(regions.count))
    if not split or not regions.count:
        return every, []
    border = ldi.label[regions.context] == LABEL_BORDER
    ptr = regions.context_ptr
    seen = np.concatenate([[0], np.cumsum(border)])
    reads = seen[ptr[1:]] > seen[ptr[:-1]]
    return ([e for e in every if not reads[e]], [e for e in every if reads[e]])


def _ahead(items: Iterator[T]) -> Iterator[T]:
    """``items``, each next one made in another thread while the caller works on the
    one before (the same items in the same order; an exception is raised where
    ``items`` raised it)."""
    end = object()
    with ThreadPoolExecutor(max_workers=1) as pool:
        coming = pool.submit(next, items, end)
        while (item := coming.result()) is not end:
            coming = pool.submit(next, items, end)
            yield item


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


def fill_pass(state: PassInput, fill: PassFill, *, config: Config, working_size: int,
              margin: int, scale: float = 1.0, pass_index: int = 0,
              later_context: float = 1.0, paper_context: bool = False,
              batch_area: int | None = None,
              progress: CountProgress | None = None,
              final: Callable[[], LDI] | None = None) -> Merged:
    """One inpainting pass of ``make``: :func:`pass_patches`' patches filled by ``fill``
    and merged into the LDI with the next pass's edges
    (:func:`~photo3d.stages.merge.merge_fills`; at most as many as this pass's, the
    longest). Only the new pixels' values are kept of each result.

    Args:
        state: the LDI and its edges (:func:`start`, or the previous pass's result).
        fill: the inpainting (:data:`PassFill`).
        config, working_size, margin, scale, pass_index, later_context, paper_context:
            see :func:`pass_patches`.
        batch_area: hold about this many patch pixels at a time (for a backend that
            fills each patch on its own): ``fill`` gets the patches in batches of half
            of it (the first an eighth of that), each next batch extracted in another
            thread while ``fill`` fills the one before; None: all at once.
        progress: ``progress(done, total)`` over the pass's patches.
        final: when ``state.ldi``'s border colours are not final yet (the frame is
            still being filled, in another thread): ``final()`` waits for and returns
            the LDI with them (the same pixels and links). The patches whose context
            reads no border pixel are filled first, meanwhile; the others are
            extracted from ``final()``, which the pass is merged into. The result is
            the same as without (each patch is filled on its own; the fills are merged
            in edge order). Regions never read colours.

    Returns:
        :class:`~photo3d.stages.merge.Merged`: the LDI with the new pixels (label 2 in
        the first pass, 3 later) and the next pass's edges.

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> from photo3d.structures.patch import InpaintResult
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[16:48, 16:48] = 3.0
        >>> pre = preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg)
        >>> grey = lambda patches, progress: [InpaintResult(
        ...     np.full(p.shape + (3,), 0.5, np.float32), p.disparity,
        ...     np.zeros(p.shape, np.float32)) for p in patches]
        >>> merged = fill_pass(start(pre, config=cfg), grey, config=cfg, working_size=64,
        ...                    margin=1)
        >>> merged.added > 0, float(merged.ldi.color[-1, 0])
        (True, 0.5)
    """
    sizes = region_sizes(config, working_size, pass_index=pass_index,
                         later_context=later_context, paper_context=paper_context)
    index = state.index if state.index is not None else state.ldi.position_index()
    regions = pass_regions(state, sizes, index=index)
    total, done = regions.count, 0
    fills = []
    first, later = _border_readers(state.ldi, regions, final is not None)

    def batches() -> Iterator[list[PatchJob]]:
        # two batches are held at once (one filled, the next extracted): each is half
        # of batch_area, the first an eighth of that, so that the fill starts sooner
        # (nothing is filled while the first is extracted)
        ldi, batch, area = state.ldi, [], 0
        half = None if batch_area is None else max(1, batch_area // 2)
        limit = None if half is None else max(1, half // 8)
        for group in (first, later):
            if group is later and final is not None:
                ldi = final()
            for job in iter_patches(ldi, regions, state.edge_pixels, margin=margin,
                                    scale=scale, edges=group):
                batch.append(job)
                area += job.patch.shape[0] * job.patch.shape[1]
                if limit is not None and area >= limit:
                    yield batch
                    batch, area, limit = [], 0, half
            if batch:
                yield batch
                batch, area, limit = [], 0, half

    def report(i: int, n: int) -> None:
        if progress is not None:
            progress(min(done + i, total), total)

    # the next batch is extracted (Python and numpy work) while this one is filled
    for batch in _ahead(batches()) if batch_area is not None else batches():
        results = fill([job.patch for job in batch], report)
        # take reads the LDI's positions only, the same in final()'s
        fills.extend((job.edge, take(state.ldi, job, res))
                     for job, res in zip(batch, results, strict=True))
        done += len(batch)
        del results  # not held while the next batch is filled (a batch's whole patches)
    ldi = final() if final is not None else state.ldi
    fills.sort(key=lambda pair: pair[0])  # edge order, as one group gives them
    pre = config.preprocess
    return merge_fills(ldi, [f for _, f in fills], label=min(pass_index + 2, 3),
                       threshold=pre.discontinuity,
                       min_edge_length=config.spatial(pre.min_edge_length, working_size),
                       overwrite_band=config.regions.overwrite_dilation,
                       max_edges=state.edges, room=ldi_room(state.ldi), index=index)
