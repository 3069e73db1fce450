"""Context and synthesis regions per depth edge (paper, Sec. 3.2).

For every depth edge (a set of background silhouette pixels, links already cut):

* the *context region* grows from the silhouette pixels along LDI links (so it stops
  at silhouettes) for ``context_iterations`` steps;
* the *synthesis region* is a set of lattice positions for new pixels. It starts one
  step from each silhouette pixel in every direction where the pixel lost its link
  to a nearer pixel and grows over lattice 4-neighbours for
  ``synthesis_iterations`` steps. A position is admissible only if every existing
  pixel there is nearer than the silhouette pixel the growth started from (by half
  the discontinuity threshold): new pixels are always hidden behind existing ones in
  the input view, and synthesis never steps back across the silhouette nor into a
  layer that already exists at that depth;
* both grow alternately, one ring each, and a lattice position belongs to at most
  one of them (per edge);
* context pixels closer than ``dilation`` steps to the silhouette move to the
  synthesis region (the paper's 5 px dilation for misaligned depth edges): their
  colour and depth are re-synthesised in place;
* optionally (photo3d's, not the paper's; :func:`_surround`) the context also takes
  what bounds the synthesis region at its depth (``context_around``), and, when it is
  thin (``thin_context``), what lies behind it.
"""

from __future__ import annotations

import queue
from collections import deque
from dataclasses import dataclass

import numba
import numpy as np

from photo3d.parallel import thread_pool, width
from photo3d.stages._lattice import step
from photo3d.structures.ldi import LDI

_MOST_THREADS = 4
"""Groups of edges grown at once, at most: each holds two lattice-sized int64 scratch
arrays (about 14 MB at 1024 px), and a pass has at most 16 groups."""


@dataclass(frozen=True)
class Regions:
    """Regions of every edge of one pass, in CSR layout (edge ``e`` owns
    ``ptr[e]:ptr[e + 1]`` of each pair of arrays).

    Attributes:
        context_ptr: ``(E + 1,) int64``.
        context: ``(K,) int64`` LDI pixel indices of context regions.
        context_step: ``(K,) int32`` flood-fill step at which the pixel joined (0 = silhouette).
        synthesis_ptr: ``(E + 1,) int64``.
        synthesis_y, synthesis_x: ``(S,) int32`` lattice positions of new pixels.
        dilation: context pixels with ``context_step < dilation`` are re-synthesised.
    """

    context_ptr: np.ndarray
    context: np.ndarray
    context_step: np.ndarray
    synthesis_ptr: np.ndarray
    synthesis_y: np.ndarray
    synthesis_x: np.ndarray
    dilation: int

    @property
    def count(self) -> int:
        return int(self.context_ptr.shape[0] - 1)

    def areas(self, ldi: LDI) -> np.ndarray:
        """``(E,) int64`` bounding-box pixels of each edge's context and synthesis (its
        patch without the margin); ``ldi``: the LDI the regions were grown on."""
        cols = ldi.lattice_shape[1]
        syn = (self.synthesis_y.astype(np.int64) + ldi.border) * cols + (
            self.synthesis_x + ldi.border)
        return _box_areas(self.context_ptr, ldi.positions()[self.context],
                          self.synthesis_ptr, syn, cols)

    def head(self, n: int) -> Regions:
        """The regions of the first ``n`` edges."""
        c, s = int(self.context_ptr[n]), int(self.synthesis_ptr[n])
        return Regions(self.context_ptr[:n + 1], self.context[:c], self.context_step[:c],
                       self.synthesis_ptr[:n + 1], self.synthesis_y[:s],
                       self.synthesis_x[:s], self.dilation)


@numba.njit(cache=True)
def _reserve(arr, n):  # pragma: no cover - jit
    """``arr``, or a copy with room for at least ``n`` items: called once per ring, so
    that the ring's appends need no check (a call per append cost a third of the
    regions' time)."""
    if n <= arr.shape[0]:
        return arr
    out = np.empty(max(2 * arr.shape[0], n, 16), arr.dtype)
    for i in range(arr.shape[0]):
        out[i] = arr[i]
    return out


@numba.njit(cache=True)
def _admissible(b, seed, disp, starts, order, margin):  # pragma: no cover - jit
    if starts[b + 1] == starts[b]:
        return False
    for k in range(starts[b], starts[b + 1]):
        if disp[order[k]] <= seed + margin:
            return False
    return True


@numba.njit(cache=True)
def _link_ring(e, lo, hi, links, pos, stamp, ctx, ctx_step, nc, value):  # pragma: no cover
    """Grow context ``ctx[lo:hi]`` of edge ``e`` one step along the LDI links: every
    linked pixel whose position is not yet stamped ``e`` joins with step ``value``.
    Returns ``(ctx, ctx_step, nc)``."""
    ctx = _reserve(ctx, nc + 4 * (hi - lo))
    ctx_step = _reserve(ctx_step, nc + 4 * (hi - lo))
    for k in range(lo, hi):
        p = ctx[k]
        for d in range(4):
            q = links[p, d]
            if q >= 0 and stamp[pos[q]] != e:
                stamp[pos[q]] = e
                ctx[nc] = q
                ctx_step[nc] = value
                nc += 1
    return ctx, ctx_step, nc


@numba.njit(cache=True)
def _surround(e, thin, s0, ns, pos, disp, links, starts, order, rows, cols, stamp, seen,
              ctx, ctx_step, nc, syn, syn_seed, n_syn, n_ctx, margin,
              n_ext):  # pragma: no cover - jit
    """Edge ``e``'s context also takes what bounds its synthesis region ``syn[s0:ns]``:
    around every edge, a bounding position's pixel at the synthesis depth (within the
    threshold, ``2 margin``); for a ``thin`` context (the edge's background is a sliver
    between two edges, or a gap) also one behind it, searched for through positions
    that only hold nearer pixels for up to ``n_syn`` rings. Each position gives its
    nearest such pixel, and those then grow ``n_ext`` steps along their own links.
    Returns the grown ``(ctx, ctx_step, nc, syn, syn_seed)``."""
    e0 = nc
    q_lo = s0  # the search starts from the region; positions it passes go to syn's
    nq = ns    # tail beyond ns (with their seeds), which the next edge overwrites
    for _ring in range(n_syn if thin else 1):
        q_hi = nq
        ctx = _reserve(ctx, nc + 4 * (q_hi - q_lo))
        ctx_step = _reserve(ctx_step, nc + 4 * (q_hi - q_lo))
        syn = _reserve(syn, nq + 4 * (q_hi - q_lo))
        syn_seed = _reserve(syn_seed, nq + 4 * (q_hi - q_lo))
        for k in range(q_lo, q_hi):
            a = syn[k]
            seed = syn_seed[k]
            for d in range(4):
                b = step(a, d, rows, cols)
                if b < 0 or stamp[b] == e or seen[b] == e:
                    continue
                seen[b] = e
                best = -1
                for j in range(starts[b], starts[b + 1]):
                    q = order[j]
                    if (disp[q] <= seed + margin and (thin or disp[q] >= seed - 2 * margin)
                            and (best < 0 or disp[q] > disp[best])):
                        best = q
                if best >= 0:
                    stamp[b] = e
                    ctx[nc] = best
                    ctx_step[nc] = n_ctx
                    nc += 1
                else:
                    syn[nq] = b
                    syn_seed[nq] = seed
                    nq += 1
        q_lo = q_hi
        if q_lo == nq:
            break
    c_lo, c_hi = e0, nc
    for _it in range(n_ext - 1):
        ctx, ctx_step, nc = _link_ring(e, c_lo, c_hi, links, pos, stamp, ctx, ctx_step, nc,
                                       n_ctx)
        c_lo, c_hi = c_hi, nc
    return ctx, ctx_step, nc, syn, syn_seed


@numba.njit(cache=True, nogil=True)
def _regions(pos, disp, links, starts, order, rows, cols, edge_ptr, edge_pix,
             n_syn, n_ctx, margin, extend, around, n_ext, stamp, seen,
             base):  # pragma: no cover - jit
    # stamp, seen: (rows * cols,) int64 scratch, never holding a value >= base (edge
    # e is marked base + e), so one pair serves every group of a pass
    n_edges = edge_ptr.shape[0] - 1
    ctx = np.empty(1024, np.int64)
    ctx_step = np.empty(1024, np.int32)
    syn = np.empty(1024, np.int64)
    syn_seed = np.empty(1024, np.float32)
    ctx_ptr = np.zeros(n_edges + 1, np.int64)
    syn_ptr = np.zeros(n_edges + 1, np.int64)
    # int64 from the start: a literal 0 would compile the helpers it is passed to
    # once more for the type Literal[int](0)
    nc = np.int64(0)
    ns = np.int64(0)
    for e_local in range(n_edges):
        e = base + e_local
        c0 = nc
        n_pix = edge_ptr[e_local + 1] - edge_ptr[e_local]
        ctx = _reserve(ctx, nc + n_pix)
        ctx_step = _reserve(ctx_step, nc + n_pix)
        syn = _reserve(syn, ns + 4 * n_pix)
        syn_seed = _reserve(syn_seed, ns + 4 * n_pix)
        for k in range(edge_ptr[e_local], edge_ptr[e_local + 1]):
            p = edge_pix[k]
            if stamp[pos[p]] == e:
                continue
            stamp[pos[p]] = e
            ctx[nc] = p
            ctx_step[nc] = 0
            nc += 1
        s0 = ns
        for k in range(edge_ptr[e_local], edge_ptr[e_local + 1]):
            p = edge_pix[k]
            for d in range(4):
                if links[p, d] >= 0:
                    continue
                b = step(pos[p], d, rows, cols)
                if b < 0 or stamp[b] == e:
                    continue
                if _admissible(b, disp[p], disp, starts, order, margin):
                    stamp[b] = e
                    syn[ns] = b
                    syn_seed[ns] = disp[p]
                    ns += 1
        c_lo, c_hi = c0, nc
        s_lo, s_hi = s0, ns
        for it in range(max(n_ctx, n_syn) - 1):
            if it < n_ctx - 1:
                ctx, ctx_step, nc = _link_ring(e, c_lo, c_hi, links, pos, stamp, ctx,
                                               ctx_step, nc, it + 1)
                c_lo, c_hi = c_hi, nc
            if it < n_syn - 1:
                syn = _reserve(syn, ns + 4 * (s_hi - s_lo))
                syn_seed = _reserve(syn_seed, ns + 4 * (s_hi - s_lo))
                for k in range(s_lo, s_hi):
                    a = syn[k]
                    seed = syn_seed[k]
                    for d in range(4):
                        b = step(a, d, rows, cols)
                        if b < 0 or stamp[b] == e:
                            continue
                        if _admissible(b, seed, disp, starts, order, margin):
                            stamp[b] = e
                            syn[ns] = b
                            syn_seed[ns] = seed
                            ns += 1
                s_lo, s_hi = s_hi, ns
        thin = extend > 0 and nc - c0 < extend * (ns - s0)
        if thin or around:
            ctx, ctx_step, nc, syn, syn_seed = _surround(
                e, thin, s0, ns, pos, disp, links, starts, order, rows, cols, stamp, seen,
                ctx, ctx_step, nc, syn, syn_seed, n_syn, n_ctx, margin, n_ext)
        ctx_ptr[e_local + 1] = nc
        syn_ptr[e_local + 1] = ns
    return ctx_ptr, ctx[:nc].copy(), ctx_step[:nc].copy(), syn_ptr, syn[:ns].copy()


KERNELS = ((_regions, "(int64[::1], float32[::1], int32[:, ::1], int64[::1], int64[::1], int64, "
                      "int64, int64[::1], int64[::1], int64, int64, float32, float32, boolean, "
                      "int64, int64[::1], int64[::1], int64)"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


@dataclass(frozen=True)
class RegionSizes:
    """The sizes and rules of one pass's regions, in working pixels (made from a
    :class:`~photo3d.config.Config` by :func:`photo3d.stages.passes.region_sizes`, the
    one place that scales them; no defaults here, so none can drift from the config's).

    Attributes:
        synthesis_iterations, context_iterations: flood-fill steps of each region.
        dilation: context pixels closer than this to the silhouette are re-synthesised.
        threshold: the discontinuity threshold (normalised disparity).
        thin_context: a context with fewer pixels than this fraction of its synthesis
            region also takes the pixels behind the region that bound it (searched
            for through nearer positions); 0: never.
        context_around: every context also takes the pixels at the synthesis
            region's depth (within ``threshold``) that bound the region.
        thin_context_iterations: steps those extra pixels grow along their links.
    """

    synthesis_iterations: int
    context_iterations: int
    dilation: int
    threshold: float
    thin_context: float
    context_around: bool
    thin_context_iterations: int


@dataclass(frozen=True)
class RegionLimit:
    """The most one pass's regions may hold, summed over its edges (see
    :func:`photo3d.stages.passes.pass_limit`, which sets them).

    Attributes:
        context: context pixels.
        synthesis: synthesis positions (the new pixels' candidates).
        area: bounding-box pixels of each edge's context and synthesis (the patches).
    """

    context: int
    synthesis: int
    area: int


def find_regions(
    ldi: LDI,
    edge_ptr: np.ndarray,
    edge_pixels: np.ndarray,
    sizes: RegionSizes,
    *,
    limit: RegionLimit | None = None,
    index: tuple[np.ndarray, np.ndarray] | None = None,
) -> Regions:
    """Grow context and synthesis regions for a batch of depth edges.

    Args:
        ldi: the LDI with links already cut along the edges.
        edge_ptr: ``(E + 1,) int64`` CSR offsets into ``edge_pixels``.
        edge_pixels: ``(K,) int64`` background silhouette pixels of each edge.
        sizes: the pass's :class:`RegionSizes` (already scaled to the working size).
        limit: grow the edges in groups (1/16 of them each, in order) and stop after
            the group that takes a total over this: the result then holds the first
            ``count < E`` edges only. None: every edge.
        index: ``ldi.position_index()`` if the caller has it.

    Returns:
        :class:`Regions`.

    Example:
        >>> from photo3d.stages.ldi import from_image, cut
        >>> d = np.zeros((8, 8), np.float32); d[:, 4:] = 1.0
        >>> cuts = np.zeros((8, 8), np.uint8); cuts[:, 3] = 2  # cut towards the right
        >>> ldi = cut(from_image(np.zeros((8, 8, 3), np.float32), d), cuts)
        >>> sil = np.arange(8) * 8 + 3
        >>> sizes = RegionSizes(synthesis_iterations=2, context_iterations=3, dilation=0,
        ...                     threshold=0.04, thin_context=0.0, context_around=False,
        ...                     thin_context_iterations=1)
        >>> r = find_regions(ldi, np.array([0, 8]), sil, sizes)
        >>> sorted(set(r.synthesis_x.tolist())), sorted(set(ldi.x[r.context].tolist()))
        ([4, 5], [1, 2, 3])
        >>> find_regions(ldi, np.array([0, 4, 8]), sil, sizes,
        ...              limit=RegionLimit(context=100, synthesis=4, area=100)).count
        1
    """
    starts, order = index if index is not None else ldi.position_index()
    rows, cols = ldi.lattice_shape
    pos = ldi.positions()
    edge_ptr = np.asarray(edge_ptr, np.int64)
    edge_pixels = np.asarray(edge_pixels, np.int64)
    n_edges = edge_ptr.size - 1
    group = n_edges if limit is None else max(1, -(-n_edges // 16))
    starts_of = range(0, max(n_edges, 1), max(group, 1))
    extra = sizes.thin_context > 0 or sizes.context_around
    threads = width(min(_MOST_THREADS, len(starts_of)))  # 1: grown in this thread
    scratch: queue.SimpleQueue = queue.SimpleQueue()  # one pair per thread at a time
    for _ in range(threads):
        scratch.put((np.full(rows * cols, -1, np.int64),
                     np.full(rows * cols if extra else 1, -1, np.int64)))

    def grow(a: int) -> tuple:
        b = min(n_edges, a + group)
        stamp, seen = scratch.get()
        try:
            return _regions(
                pos, ldi.disparity, ldi.links, starts, order, rows, cols,
                edge_ptr[a:b + 1] - edge_ptr[a], edge_pixels[edge_ptr[a]:edge_ptr[b]],
                max(1, sizes.synthesis_iterations), max(1, sizes.context_iterations),
                np.float32(sizes.threshold / 2), np.float32(sizes.thin_context),
                bool(sizes.context_around), max(1, sizes.thin_context_iterations),
                stamp, seen, a)
        finally:
            scratch.put((stamp, seen))

    parts = []
    used = np.zeros(3, np.int64)  # context, synthesis, area
    # groups grown by the budget's threads (the kernel runs without the GIL), taken in
    # order; the result does not depend on the threads
    with thread_pool(threads, name="regions") as pool:
        ahead = deque(pool.submit(grow, a) for a in starts_of[:threads])
        following = iter(starts_of[threads:])
        while ahead:
            part = ahead.popleft().result()
            parts.append(part)
            if limit is not None:
                ctx_ptr, ctx, _, syn_ptr, syn = part
                used += (ctx.size, syn.size,
                         _box_areas(ctx_ptr, pos[ctx], syn_ptr, syn, cols).sum())
                if (used > (limit.context, limit.synthesis, limit.area)).any():
                    for job in ahead:
                        job.cancel()
                    break
            a = next(following, None)
            if a is not None:
                ahead.append(pool.submit(grow, a))
    ctx_ptr, syn_ptr = _join_ptr([p[0] for p in parts]), _join_ptr([p[3] for p in parts])
    syn = np.concatenate([p[4] for p in parts])
    return Regions(
        context_ptr=ctx_ptr,
        context=np.concatenate([p[1] for p in parts]),
        context_step=np.concatenate([p[2] for p in parts]),
        synthesis_ptr=syn_ptr,
        synthesis_y=(syn // cols - ldi.border).astype(np.int32),
        synthesis_x=(syn % cols - ldi.border).astype(np.int32),
        dilation=int(sizes.dilation),
    )


def _join_ptr(ptrs: list[np.ndarray]) -> np.ndarray:
    """CSR offsets of consecutive groups joined into one."""
    out, base = [np.zeros(1, np.int64)], 0
    for ptr in ptrs:
        out.append(ptr[1:] + base)
        base += int(ptr[-1])
    return np.concatenate(out)


def _box_areas(ctx_ptr: np.ndarray, ctx_pos: np.ndarray, syn_ptr: np.ndarray,
               syn_pos: np.ndarray, cols: int) -> np.ndarray:
    """``(E,) int64`` bounding-box area of each edge's context and synthesis (flat
    lattice positions in CSR groups)."""
    n = ctx_ptr.size - 1
    lo = np.full((2, n), np.iinfo(np.int64).max)
    hi = np.full((2, n), -1)
    for ptr, flat in ((ctx_ptr, ctx_pos), (syn_ptr, syn_pos)):
        some = np.diff(ptr) > 0
        if not some.any():
            continue
        at = ptr[:-1][some]
        for k, v in enumerate((flat // cols, flat % cols)):
            lo[k, some] = np.minimum(lo[k, some], np.minimum.reduceat(v, at))
            hi[k, some] = np.maximum(hi[k, some], np.maximum.reduceat(v, at))
    size = np.maximum(hi - lo + 1, 0)
    return size[0] * size[1]
