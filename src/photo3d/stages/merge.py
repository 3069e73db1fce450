"""Merge inpainted pixels into the LDI and find the depth edges they create.

New pixels (paper, Sec. 3.4) are appended with their colour and disparity. A
candidate is dropped when a pixel of similar depth (within the discontinuity
threshold) already exists at its position, either from an earlier pass or from
another edge of the same pass, or when it would not be hidden behind every
existing pixel there. Each new pixel links to the lattice neighbour of closest
disparity within the threshold whose slot facing it is free, so links stay
symmetric and new layers join the context they grew from. Dilation-band pixels
get their re-synthesised values in place only if ``overwrite_band`` is set.

Multi-layer inpainting (paper, Sec. 3.3) continues where new pixels meet other new
pixels of this pass across a discontinuity: the farther ones form the background
silhouettes of the next pass's depth edges, where the next pass can fill behind the
nearer ones, i.e. where the facing position holds nothing at or behind the farther
pixel's depth (the regions' rule: :mod:`photo3d.stages.regions`). Where two fills of
one layer meet (overlapping regions of neighbouring edges, whose values differ at
the seam by a little more than the threshold), the layer already goes on there: a
silhouette would grow nothing. On the motorcycle's raw disparity (unknown pixels =
0) such seams made the second pass find 994 edges after the first's 354, 61 % of
them with nothing to fill; without them: [354, 315, 96]. A pass hands on at most as
many edges as it had (the longest, ``max_edges``), and adds at most what keeps the LDI
within its limit (``room``; :mod:`photo3d.stages.passes`).

Two rules keep a poor or random net from flooding the later passes with edges
(docs/fills.md): with a compact depth net the 1024 px sample went from 208 edges
in the first pass to 932 in the second, against 177 with diffusion.

* **One fill is one surface unless its edges say otherwise.** Neighbouring new
  pixels of the same job are linked even across a step of more than the threshold,
  unless either lies on an edge the backend reported in the synthesis region (the
  paper's edge stage: structure first, then depth and colour that follow it; the
  authors' code likewise tears a synthesised region only along its predicted edge
  paths). Steps the depth net leaves elsewhere are its errors, not occlusions.
  Where fills of different jobs meet, the threshold decides as before.
* **A fill stays within its context's depth range.** A new pixel's disparity is
  clipped to the range of its job's context: interpolating fills (diffusion,
  structured) never leave it, and a net that does invents depth the context gives no
  evidence for.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numba
import numpy as np

from photo3d.stages._lattice import find_root, step, union
from photo3d.stages.patches import PatchJob
from photo3d.structures.ldi import LDI
from photo3d.structures.patch import InpaintResult


@dataclass(frozen=True)
class Merged:
    """Result of merging one pass.

    Attributes:
        ldi: the LDI with the new pixels.
        added: number of new pixels.
        edge_ptr: ``(E + 1,) int64`` CSR offsets of the next pass's edges.
        edge_pixels: ``(K,) int64`` their background silhouette pixels.
        index: ``ldi.position_index()`` (the merge keeps it up to date; None: not kept).
    """

    ldi: LDI
    added: int
    edge_ptr: np.ndarray
    edge_pixels: np.ndarray
    index: tuple[np.ndarray, np.ndarray] | None = None


@numba.njit(cache=True)
def _select(cand_pos, cand_disp, starts, order, disp, thr):  # pragma: no cover - jit
    n = cand_pos.shape[0]
    keep = np.zeros(n, np.bool_)
    group = 0
    for i in range(n):
        if i == 0 or cand_pos[i] != cand_pos[i - 1]:
            group = i
        b = cand_pos[i]
        ok = True
        for k in range(starts[b], starts[b + 1]):
            e = disp[order[k]]
            if abs(e - cand_disp[i]) < thr or e <= cand_disp[i] + 0.5 * thr:
                ok = False
                break
        if ok:
            for j in range(group, i):
                if keep[j] and abs(cand_disp[j] - cand_disp[i]) < thr:
                    ok = False
                    break
        keep[i] = ok
    return keep


@numba.njit(cache=True)
def _link_new(first, pos, disp, links, starts, order, rows, cols, thr, job, on_edge,
              fills):  # pragma: no cover - jit
    """Link the free slots of new pixels: to the neighbour of closest disparity within
    ``thr`` or, with ``fills``, to the neighbour of the same job when neither is on an
    edge of that job's result."""
    for n in range(first, pos.shape[0]):
        if fills and on_edge[n - first]:
            continue
        for d in range(4):
            if links[n, d] >= 0:
                continue
            b = step(pos[n], d, rows, cols)
            if b < 0:
                continue
            best = -1
            best_diff = thr
            for k in range(starts[b], starts[b + 1]):
                m = order[k]
                if links[m, d ^ 1] >= 0:
                    continue
                if fills:
                    if m >= first and job[m - first] == job[n - first] and not on_edge[m - first]:
                        best = m
                        break
                elif abs(disp[m] - disp[n]) < best_diff:
                    best = m
                    best_diff = abs(disp[m] - disp[n])
            if best >= 0:
                links[n, d] = best
                links[best, d ^ 1] = n


@numba.njit(cache=True)
def _new_edges(first, pos, disp, links, starts, order, rows, cols, thr):  # pragma: no cover
    """Union-find roots of new background silhouettes (-1 = not a silhouette): new
    pixels with a free slot facing a new pixel nearer by more than ``thr`` at a position
    the next pass may fill for them (every pixel there nearer by more than ``thr / 2``,
    the regions' rule)."""
    n_all = pos.shape[0]
    sil = np.zeros(n_all, np.bool_)
    for n in range(first, n_all):
        for d in range(4):
            if links[n, d] >= 0:
                continue
            b = step(pos[n], d, rows, cols)
            if b < 0:
                continue
            nearer = False
            covered = False
            for k in range(starts[b], starts[b + 1]):
                m = order[k]
                if m >= first and disp[m] > disp[n] + thr:
                    nearer = True
                if disp[m] <= disp[n] + 0.5 * thr:
                    covered = True
            if nearer and not covered:
                sil[n] = True
    parent = np.arange(n_all)
    for n in range(first, n_all):
        if not sil[n]:
            continue
        for d in range(4):
            q = links[n, d]
            if q < 0:
                continue
            if sil[q]:
                union(parent, n, q)
            for d2 in range(4):
                if d2 // 2 == d // 2:
                    continue
                m = links[q, d2]
                if m >= 0 and sil[m]:
                    union(parent, n, m)
    roots = np.full(n_all, -1, np.int64)
    for n in range(first, n_all):
        if sil[n]:
            roots[n] = find_root(parent, n)
    return roots


_LDI = "int64, int64[::1], float32[::1], int32[:, ::1], int64[::1], int64[::1], int64, int64"
KERNELS = (
    (_select, "(int64[::1], float32[::1], int64[::1], int64[::1], float32[::1], float32)"),
    (_link_new, f"({_LDI}, float32, int32[::1], boolean[::1], boolean)"),
    (_new_edges, f"({_LDI}, float32)"),
)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


@dataclass(frozen=True)
class Fill:
    """What the merge needs of one job's result: its new pixels' values (a few bytes
    per new pixel, so a pass need not hold every patch and result at once).

    Attributes:
        new_y, new_x: ``(S,) int32`` lattice positions of the new pixels.
        color: ``(S, 3) float32``.
        disparity: ``(S,) float32`` (clipped to the context's range by :func:`take`).
        on_edge: ``(S,) bool`` the backend reported an edge there.
        band: ``(B,) int64`` existing LDI pixels the job re-synthesised in place.
        band_color: ``(B, 3) float32``, band_disparity: ``(B,) float32`` their values.
    """

    new_y: np.ndarray
    new_x: np.ndarray
    color: np.ndarray
    disparity: np.ndarray
    on_edge: np.ndarray
    band: np.ndarray
    band_color: np.ndarray
    band_disparity: np.ndarray


def take(ldi: LDI, job: PatchJob, result: InpaintResult, *, clamp: bool = True) -> Fill:
    """The values of ``result`` that :func:`merge_fills` uses.

    Args:
        ldi: the LDI the job was extracted from.
        job: the patch and where its new pixels go.
        result: the inpainter's output for ``job.patch``.
        clamp: clip new disparities to the range of the job's context.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> from photo3d.structures.patch import Patch
        >>> ldi = from_image(np.zeros((2, 3, 3), np.float32), np.zeros((2, 3), np.float32))
        >>> ctx = np.array([[True, True, False]] * 2); d = np.where(ctx, 0.5, 0).astype(np.float32)
        >>> patch = Patch(np.zeros((2, 3, 3), np.float32), d, np.zeros((2, 3), np.float32),
        ...               ctx, ~ctx, (0, 0))
        >>> job = PatchJob(patch, np.array([0, 1], np.int32), np.array([2, 2], np.int32),
        ...                np.zeros(0, np.int64))
        >>> out = InpaintResult(np.ones((2, 3, 3), np.float32), np.ones((2, 3), np.float32),
        ...                     np.zeros((2, 3), np.float32))
        >>> take(ldi, job, out).disparity.tolist()  # clipped to the context's 0.5
        [0.5, 0.5]
    """
    y0, x0 = job.patch.origin
    ly, lx = job.new_y - y0, job.new_x - x0
    d = result.disparity[ly, lx].astype(np.float32)
    ctx = job.patch.context.astype(bool)
    if clamp and ctx.any() and d.size:
        known = job.patch.disparity[ctx]
        d = np.clip(d, known.min(), known.max())
    by, bx = ldi.y[job.band] - y0, ldi.x[job.band] - x0
    return Fill(job.new_y, job.new_x, result.color[ly, lx].astype(np.float32), d,
                result.edges[ly, lx] > 0.5, job.band,
                result.color[by, bx].astype(np.float32),
                result.disparity[by, bx].astype(np.float32))


def merge(
    ldi: LDI,
    jobs: list[PatchJob],
    results: list[InpaintResult],
    *,
    label: int,
    threshold: float,
    min_edge_length: int,
    overwrite_band: bool = False,
    link_fills: bool = True,
    clamp: bool = True,
) -> Merged:
    """Merge one pass of inpainting results into ``ldi`` (:func:`take` of every job,
    then :func:`merge_fills`).

    Args:
        ldi: the LDI the jobs were extracted from.
        jobs: patches with their target positions.
        results: the inpainter's outputs, one per job.
        label, threshold, min_edge_length, overwrite_band, link_fills: see
            :func:`merge_fills`.
        clamp: clip new disparities to the range of their job's context.

    Returns:
        :class:`Merged`.
    """
    fills = [take(ldi, job, res, clamp=clamp) for job, res in zip(jobs, results, strict=True)]
    return merge_fills(ldi, fills, label=label, threshold=threshold,
                       min_edge_length=min_edge_length, overwrite_band=overwrite_band,
                       link_fills=link_fills)


def merge_fills(
    ldi: LDI,
    fills: list[Fill],
    *,
    label: int,
    threshold: float,
    min_edge_length: int,
    overwrite_band: bool = False,
    link_fills: bool = True,
    max_edges: int | None = None,
    room: int | None = None,
    index: tuple[np.ndarray, np.ndarray] | None = None,
) -> Merged:
    """Merge one pass's fills (:func:`take`, in job order) into ``ldi``.

    Args:
        ldi: the LDI the jobs were extracted from.
        fills: one per job, in the jobs' order (earlier jobs win a position).
        label: label of the new pixels.
        threshold: discontinuity threshold (normalised disparity).
        min_edge_length: new edges with fewer pixels are ignored.
        overwrite_band: replace the dilation band's colour and disparity by the
            inpainted values (else the input view stays exactly the photo).
        link_fills: link neighbouring new pixels of one job across steps unless
            either is on an edge of its result (False: every step above
            ``threshold`` is a new edge, the rule before the fill rules).
        max_edges: keep at most this many new edges, the longest (None: all).
        room: add at most this many pixels (None: all): every job keeps the same share
            of its new pixels, those nearest its edge (a job's pixels are in the order
            its synthesis region grew); a pass that fills the room hands on no edges.
        index: ``ldi.position_index()`` if the caller has it.

    Returns:
        :class:`Merged`.
    """
    color, disparity = ldi.color, ldi.disparity
    if overwrite_band and any(f.band.size for f in fills):
        color, disparity = color.copy(), disparity.copy()
        for f in fills:
            color[f.band] = f.band_color
            disparity[f.band] = f.band_disparity
        ldi = replace(ldi, color=color, disparity=disparity)
    sizes = [f.new_y.size for f in fills]
    if sum(sizes) == 0:
        return Merged(ldi, 0, np.zeros(1, np.int64), np.zeros(0, np.int64), index)

    rows, cols = ldi.lattice_shape
    cy = np.concatenate([f.new_y for f in fills])
    cx = np.concatenate([f.new_x for f in fills])
    cc = np.concatenate([f.color for f in fills]).astype(np.float32)
    cd = np.concatenate([f.disparity for f in fills]).astype(np.float32)
    cpos = (cy.astype(np.int64) + ldi.border) * cols + (cx + ldi.border)
    order_c = np.argsort(cpos, kind="stable")
    starts, order = index if index is not None else ldi.position_index()
    keep_sorted = _select(cpos[order_c], cd[order_c], starts, order, ldi.disparity,
                          np.float32(threshold))
    keep = np.sort(order_c[keep_sorted])
    full = room is not None and keep.size >= room
    if room is not None and keep.size > room:
        offsets = np.repeat(np.cumsum([0, *sizes[:-1]]), sizes)
        depth = (keep - offsets[keep]) / np.repeat(np.maximum(sizes, 1), sizes)[keep]
        keep = np.sort(keep[np.argsort(depth, kind="stable")[:max(room, 0)]])
    first = ldi.size
    added = int(keep.size)
    links = np.concatenate([ldi.links, np.full((added, 4), -1, np.int32)])
    ldi = replace(
        ldi,
        y=np.concatenate([ldi.y, cy[keep].astype(np.int32)]),
        x=np.concatenate([ldi.x, cx[keep].astype(np.int32)]),
        color=np.concatenate([ldi.color, cc[keep]]),
        disparity=np.concatenate([ldi.disparity, cd[keep]]),
        links=links,
        label=np.concatenate([ldi.label, np.full(added, label, np.uint8)]),
        alpha=np.concatenate([ldi.alpha, np.ones(added, np.float32)]),
    )
    pos = ldi.positions()
    starts, order = _appended(starts, order, pos[first:])
    job = np.repeat(np.arange(len(fills), dtype=np.int32), sizes)[keep]
    on_edge = np.concatenate([f.on_edge for f in fills])[keep]
    for linking in (False, True) if link_fills else (False,):
        _link_new(first, pos, ldi.disparity, links, starts, order, rows, cols,
                  np.float32(threshold), job, on_edge, linking)
    roots = _new_edges(first, pos, ldi.disparity, links, starts, order, rows, cols,
                       np.float32(threshold))
    sil = np.nonzero(roots >= 0)[0]
    ids, inverse, counts = np.unique(roots[sil], return_inverse=True, return_counts=True)
    big = counts >= max(1, min_edge_length)
    if full:
        big[:] = False
    if max_edges is not None and big.sum() > max_edges:
        longest = np.argsort(-counts, kind="stable")[:max(0, max_edges)]
        big = np.zeros_like(big)
        big[longest] = True
    sel = big[inverse]
    sil, inverse = sil[sel], inverse[sel]
    by_edge = np.argsort(inverse, kind="stable")
    edge_ptr = np.concatenate([[0], np.cumsum(counts[big])]).astype(np.int64)
    return Merged(ldi, added, edge_ptr, sil[by_edge].astype(np.int64), (starts, order))


def _appended(starts: np.ndarray, order: np.ndarray,
              new_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`LDI.position_index` after pixels ``N..N + n - 1`` at ``new_pos`` were
    appended to an LDI of ``N`` pixels whose index is ``(starts, order)`` (the same
    arrays, without sorting all pixels again: at each position the old pixels, then the
    new ones in index order)."""
    first = order.size
    positions = starts.size - 1
    shift = np.zeros(positions + 1, np.int64)
    np.cumsum(np.bincount(new_pos, minlength=positions), out=shift[1:])
    out = np.empty(first + new_pos.size, np.int64)
    slot_position = np.repeat(np.arange(positions), np.diff(starts))
    out[np.arange(first) + shift[slot_position]] = order
    by_position = np.argsort(new_pos, kind="stable")
    sorted_pos = new_pos[by_position]
    rank = np.arange(sorted_pos.size) - np.searchsorted(sorted_pos, sorted_pos)
    out[starts[sorted_pos + 1] + shift[sorted_pos] + rank] = first + by_position
    return starts + shift, out
