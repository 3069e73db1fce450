"""Shared canvases: the patches of one pass that the nets may fill together (docs/learned.md).

Each depth edge has its own patch (context + synthesis, bounding box + margin), and
on a cluttered photo the patches of neighbouring edges overlap many times over, so
running a net per patch sends several times the image area through it. Here the
patches of a pass are combined into fewer, larger *canvases*, each filled by one net
run, without letting one edge's synthesis read another edge's foreground:

1. **Groups.** Patches are taken largest first and put in the first group they do
   not conflict with. Patch ``P`` conflicts with a group when, on the lattice,

   * P's synthesis covers a context pixel of the group, or P's context covers a
     synthesis pixel of the group (a hole would see what hides it);
   * P's context and the group's hold different pixels at one position (different
     LDI layers: told apart by their disparity);
   * within ``reach`` pixels of P's synthesis (or of the group's), the other side has
     a context pixel that is nearer than every context pixel of the synthesis' own
     patch by more than ``threshold`` (a foreground beside the hole).

   Inside a group every lattice position holds at most one context pixel, so the
   group's patches can share one image: contexts add up, syntheses add up.
2. **Clusters.** Inside a group, patches whose windows overlap are merged into one
   canvas (their union bounding box) when that box is no larger than the boxes it
   replaces (so merging never adds pixels); the others stay canvases of their own.

A canvas is an ordinary :class:`~photo3d.structures.patch.Patch`; the result of each
member patch is the canvas result cropped to the member's window (only its synthesis
pixels are used). Where two members' syntheses overlap they get one prediction
instead of two different ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation

from photo3d.inpaint.crops import overlap
from photo3d.structures.patch import InpaintResult, Patch


@dataclass(frozen=True)
class Canvas:
    """Patches filled together.

    Attributes:
        patch: the combined patch (lattice window = union of the members' windows).
        members: indices of the member patches in the list given to
            :func:`share_canvases`.
    """

    patch: Patch
    members: tuple[int, ...]


class _Group:
    def __init__(self, shape: tuple[int, int]) -> None:
        self.ctx = np.zeros(shape, bool)
        self.syn = np.zeros(shape, bool)
        self.disp = np.zeros(shape, np.float32)
        self.near = np.zeros(shape, bool)  # within reach of a synthesis: the hole's side
        self.syn_floor = np.full(shape, np.inf, np.float32)  # nearest own context there
        self.members: list[int] = []


def _near(syn: np.ndarray, ctx: np.ndarray, reach: int) -> np.ndarray:
    """Pixels within ``reach`` of ``syn`` (8-neighbour steps), outside ``syn`` and
    ``ctx``, on the window grown by ``reach`` on every side."""
    r = max(0, reach)
    grown = np.pad(syn, r)
    if r:
        grown = binary_dilation(grown, structure=np.ones((3, 3), bool), iterations=r)
    return grown & ~np.pad(syn | ctx, r)


def _clip(win: tuple[slice, slice], shape: tuple[int, int], reach: int):
    """``win`` grown by ``reach``, clipped to ``shape``: (canvas slices, local slices)."""
    (a, b), (c, d) = (win[0].start - reach, win[0].stop + reach), (win[1].start - reach,
                                                                    win[1].stop + reach)
    ca, cb, cc, cd = max(a, 0), min(b, shape[0]), max(c, 0), min(d, shape[1])
    return (slice(ca, cb), slice(cc, cd)), (slice(ca - a, cb - a), slice(cc - c, cd - c))


def _conflicts(g: _Group, win, ctx, syn, disp, near, top, threshold) -> bool:
    gc, gs = g.ctx[win], g.syn[win]
    if (gs & ctx).any() or (gc & syn).any():
        return True
    both = gc & ctx
    if both.any() and (g.disp[win][both] != disp[both]).any():
        return True
    # a context of the group beside P's hole, nearer than all of P's context
    big, local = near
    beside = local & g.ctx[big]
    if beside.any() and (g.disp[big][beside] > top + threshold).any():
        return True
    # P's context beside a hole of the group, nearer than that hole's own context
    beside = g.near[win] & ctx & ~gc
    return bool(beside.any() and (disp[beside] > g.syn_floor[win][beside] + threshold).any())


def share_canvases(patches: Sequence[Patch], *, reach: int = 8, threshold: float = 0.04,
                   unit: int = 1, cluster: bool = True) -> list[Canvas]:
    """Combine the patches of one pass into canvases (see the module docstring).

    Args:
        patches: the pass's patches (lattice windows given by their ``origin``).
        reach: pixels around a synthesis region checked for another edge's foreground.
        threshold: disparity margin of that check (the discontinuity threshold).
        unit: the nets' inputs are padded to multiples of this: areas are compared
            after padding when clusters are merged.
        cluster: False: one canvas per group (its members' union bounding box).

    Returns:
        Canvases covering every patch exactly once.

    Example:
        >>> ctx = np.zeros((6, 8), bool); ctx[:, :3] = True
        >>> p = Patch(np.zeros((6, 8, 3), np.float32), np.full((6, 8), 0.2, np.float32) * ctx,
        ...           np.zeros((6, 8), np.float32), ctx, ~ctx, (0, 0))
        >>> q = Patch(p.color, p.disparity, p.edges, ctx, ~ctx, (0, 3))
        >>> [c.members for c in share_canvases([p, q])]  # q's context is in p's hole
        [(0,), (1,)]
        >>> r = Patch(p.color, p.disparity, p.edges, ctx, ~ctx, (2, 0))  # same layer
        >>> [(c.members, c.patch.shape) for c in share_canvases([p, r])]
        [((0, 1), (8, 8))]
    """
    if not patches:
        return []
    y0 = min(p.origin[0] for p in patches)
    x0 = min(p.origin[1] for p in patches)
    y1 = max(p.origin[0] + p.shape[0] for p in patches)
    x1 = max(p.origin[1] + p.shape[1] for p in patches)
    shape = (y1 - y0, x1 - x0)
    order = sorted(range(len(patches)), key=lambda i: -patches[i].shape[0] * patches[i].shape[1])
    groups: list[_Group] = []
    for i in order:
        p = patches[i]
        h, w = p.shape
        win = (slice(p.origin[0] - y0, p.origin[0] - y0 + h),
               slice(p.origin[1] - x0, p.origin[1] - x0 + w))
        ctx = p.context.astype(bool)
        syn = p.synthesis.astype(bool) & ~ctx
        disp = np.where(ctx, p.disparity, 0).astype(np.float32)
        big, small = _clip(win, shape, reach)
        near = (big, _near(syn, ctx, reach)[small])
        top = float(disp[ctx].max()) if ctx.any() else 0.0
        for g in groups:
            if not _conflicts(g, win, ctx, syn, disp, near, top, threshold):
                break
        else:
            g = _Group(shape)
            groups.append(g)
        g.ctx[win] |= ctx
        g.syn[win] |= syn
        g.disp[win][ctx] = disp[ctx]
        g.near[big] |= near[1]
        floor = g.syn_floor[big]
        floor[near[1]] = np.minimum(floor[near[1]], top)
        g.members.append(i)
    canvases = []
    for g in groups:
        members_of = (_clusters([patches[i] for i in g.members], unit) if cluster
                      else [list(range(len(g.members)))])
        for members in members_of:
            idx = tuple(sorted(g.members[k] for k in members))
            canvases.append(Canvas(_combine([patches[i] for i in idx]), idx))
    return canvases


def _box(p: Patch) -> tuple[int, int, int, int]:
    return p.origin[0], p.origin[1], p.origin[0] + p.shape[0], p.origin[1] + p.shape[1]


def _area(b, unit: int = 1) -> int:
    return -(-(b[2] - b[0]) // unit) * unit * (-(-(b[3] - b[1]) // unit) * unit)


def _clusters(members: Sequence[Patch], unit: int = 1) -> list[list[int]]:
    """Indices of ``members`` merged greedily while the union box (padded to ``unit``)
    is no larger than the boxes it replaces."""
    clusters: list[tuple[tuple[int, int, int, int], int, list[int]]] = []  # box, area, idx
    for k, p in enumerate(members):
        box, area, idx = _box(p), _area(_box(p), unit), [k]
        merged = True
        while merged:
            merged = False
            for c, (cb, ca, ci) in enumerate(clusters):
                overlap = cb[0] < box[2] and box[0] < cb[2] and cb[1] < box[3] and box[1] < cb[3]
                union = (min(cb[0], box[0]), min(cb[1], box[1]), max(cb[2], box[2]),
                         max(cb[3], box[3]))
                if overlap and _area(union, unit) <= ca + area:
                    box, area, idx = union, _area(union, unit), ci + idx
                    del clusters[c]
                    merged = True
                    break
        clusters.append((box, area, idx))
    return [sorted(ci) for _, _, ci in clusters]


def _combine(members: Sequence[Patch]) -> Patch:
    if len(members) == 1:
        return members[0]
    y0 = min(p.origin[0] for p in members)
    x0 = min(p.origin[1] for p in members)
    h = max(p.origin[0] + p.shape[0] for p in members) - y0
    w = max(p.origin[1] + p.shape[1] for p in members) - x0
    color = np.zeros((h, w, 3), np.float32)
    disparity = np.zeros((h, w), np.float32)
    edges = np.zeros((h, w), np.float32)
    context = np.zeros((h, w), bool)
    synthesis = np.zeros((h, w), bool)
    for p in members:
        win = (slice(p.origin[0] - y0, p.origin[0] - y0 + p.shape[0]),
               slice(p.origin[1] - x0, p.origin[1] - x0 + p.shape[1]))
        ctx = p.context.astype(bool)
        color[win][ctx] = p.color[ctx]
        disparity[win][ctx] = p.disparity[ctx]
        edges[win] = np.maximum(edges[win], np.where(ctx, p.edges, 0))
        context[win] |= ctx
        synthesis[win] |= p.synthesis.astype(bool) & ~ctx
    return Patch(color, disparity, edges, context, synthesis & ~context, (y0, x0),
                 members[0].scale)


def split_result(canvas: Canvas, result: InpaintResult,
                 patches: Sequence[Patch]) -> list[InpaintResult]:
    """The canvas ``result`` cropped to each member's window, in ``canvas.members`` order.

    Example:
        >>> ctx = np.zeros((4, 4), bool); ctx[:, :2] = True
        >>> p = Patch(np.zeros((4, 4, 3), np.float32), np.zeros((4, 4), np.float32),
        ...           np.zeros((4, 4), np.float32), ctx, ~ctx, (0, 0))
        >>> c = share_canvases([p])[0]
        >>> r = InpaintResult(np.ones((4, 4, 3), np.float32), np.ones((4, 4), np.float32),
        ...                   np.zeros((4, 4), np.float32))
        >>> split_result(c, r, [p])[0].color.shape
        (4, 4, 3)
    """
    y0, x0 = canvas.patch.origin
    out = []
    for i in canvas.members:
        p = patches[i]
        win = (slice(p.origin[0] - y0, p.origin[0] - y0 + p.shape[0]),
               slice(p.origin[1] - x0, p.origin[1] - x0 + p.shape[1]))
        out.append(InpaintResult(result.color[win], result.disparity[win], result.edges[win]))
    return out


def joint_patch(patches: Sequence[Patch], *, reach: int = 8,
                threshold: float = 0.04) -> Patch | None:
    """One patch over all of ``patches`` (the edge net's joint input of a pass), or None
    when their contexts disagree somewhere (two LDI layers at one position: then they
    cannot share an image).

    Its synthesis is the union of the syntheses; its context is the union of the
    contexts minus every synthesis pixel and minus the *foreground beside a hole*:
    context pixels within ``reach`` of a patch's synthesis, outside that patch's
    context, and nearer than all of that patch's context by more than ``threshold``
    (what hides that hole must not guide its edges).

    Example:
        >>> ctx = np.zeros((4, 6), bool); ctx[:, :2] = True
        >>> p = Patch(np.zeros((4, 6, 3), np.float32), np.full((4, 6), 0.2, np.float32) * ctx,
        ...           np.zeros((4, 6), np.float32), ctx, ~ctx, (0, 0))
        >>> q = Patch(p.color, p.disparity, p.edges, ctx, ~ctx, (0, 2))  # ctx in p's hole
        >>> j = joint_patch([p, q]); j.shape, int(j.context.sum()), int(j.synthesis.sum())
        ((4, 8), 8, 24)
        >>> joint_patch([p, Patch(p.color, p.disparity * 2, p.edges, ctx, ~ctx, (0, 0))]) is None
        True
    """
    y0 = min(p.origin[0] for p in patches)
    x0 = min(p.origin[1] for p in patches)
    h = max(p.origin[0] + p.shape[0] for p in patches) - y0
    w = max(p.origin[1] + p.shape[1] for p in patches) - x0
    color = np.zeros((h, w, 3), np.float32)
    disparity = np.zeros((h, w), np.float32)
    edges = np.zeros((h, w), np.float32)
    context = np.zeros((h, w), bool)
    synthesis = np.zeros((h, w), bool)
    wins = []
    for p in patches:
        win = (slice(p.origin[0] - y0, p.origin[0] - y0 + p.shape[0]),
               slice(p.origin[1] - x0, p.origin[1] - x0 + p.shape[1]))
        wins.append(win)
        ctx = p.context.astype(bool)
        both = context[win] & ctx
        if both.any() and (disparity[win][both] != p.disparity[both]).any():
            return None
        color[win][ctx] = p.color[ctx]
        disparity[win][ctx] = p.disparity[ctx]
        edges[win][ctx] = p.edges[ctx]
        context[win] |= ctx
        synthesis[win] |= p.synthesis.astype(bool) & ~ctx
    foreground = np.zeros((h, w), bool)
    for p, win in zip(patches, wins, strict=True):
        ctx = p.context.astype(bool)
        syn = p.synthesis.astype(bool) & ~ctx
        if not ctx.any() or not syn.any():
            continue
        top = float(p.disparity[ctx].max())
        big, small = _clip(win, (h, w), reach)
        near = _near(syn, ctx, reach)[small]
        foreground[big] |= near & context[big] & (disparity[big] > top + threshold)
    keep = context & ~synthesis & ~foreground
    return Patch(color * keep[..., None], disparity * keep, edges * keep, keep, synthesis,
                 (y0, x0), patches[0].scale)


def edges_in(p: Patch, joint: Sequence[tuple[np.ndarray, tuple[int, int]]]) -> np.ndarray:
    """``p``'s context edges plus the new edges of joint edge-net runs in its synthesis.

    Args:
        p: a patch (or canvas).
        joint: ``(new (H, W) bool, origin (y0, x0))`` per joint run.

    Returns:
        ``(h, w) float32`` 0/1.

    Example:
        >>> ctx = np.zeros((2, 4), bool); ctx[:, :2] = True
        >>> p = Patch(np.zeros((2, 4, 3), np.float32), np.zeros((2, 4), np.float32),
        ...           np.zeros((2, 4), np.float32), ctx, ~ctx, (0, 1))
        >>> edges_in(p, [(np.ones((2, 8), bool), (0, 0))]).astype(int).tolist()
        [[0, 0, 1, 1], [0, 0, 1, 1]]
    """
    own = np.where(p.context, p.edges, 0).astype(np.float32)
    crop = np.zeros(p.shape, bool)
    for new, origin in joint:
        crop |= window(new, origin, p)
    return np.maximum(own, (crop & p.synthesis & ~p.context).astype(np.float32))


def window(a: np.ndarray, origin: tuple[int, int], p: Patch) -> np.ndarray:
    """The part of ``a`` (``(H, W, ...)``, top-left pixel at lattice ``origin``) under
    ``p``'s lattice window, zeros where ``a`` does not reach.

    Example:
        >>> p = Patch(np.zeros((2, 3, 3), np.float32), np.zeros((2, 3), np.float32),
        ...           np.zeros((2, 3), np.float32), np.zeros((2, 3), bool),
        ...           np.ones((2, 3), bool), (1, 2))
        >>> window(np.arange(12).reshape(3, 4), (0, 0), p).tolist()
        [[6, 7, 0], [10, 11, 0]]
    """
    out = np.zeros((*p.shape, *a.shape[2:]), a.dtype)
    (y0, x0), (h, w) = p.origin, p.shape
    both = overlap((y0, x0, y0 + h, x0 + w), a.shape[:2], origin)
    if both is not None:
        out[both[0]] = a[both[1]]
    return out


def trim(p: Patch, unit: int) -> Patch:
    """``p`` cropped towards the bounding box of its context and synthesis: of the empty
    margin around them it keeps what fits in their size rounded up to multiples of
    ``unit`` (a net pads its input to those anyway), so the padded size shrinks where
    the margin alone made it grow, and nothing changes elsewhere.

    Example:
        >>> ctx = np.zeros((140, 40), bool); ctx[20:120, 10:30] = True
        >>> syn = np.zeros((140, 40), bool); syn[20:120, 30:35] = True
        >>> p = Patch(np.zeros((140, 40, 3), np.float32), np.zeros((140, 40), np.float32),
        ...           np.zeros((140, 40), np.float32), ctx, syn, (5, 5))
        >>> t = trim(p, 128); t.shape, t.origin  # 140 rows pad to 256, their 100 to 128
        ((128, 40), (11, 5))
    """
    m = p.context.astype(bool) | p.synthesis.astype(bool)
    if not m.any():
        return p
    box = []
    for axis, size in enumerate(p.shape):
        idx = np.nonzero(m.any(1 - axis))[0]
        lo, hi = int(idx[0]), int(idx[-1]) + 1
        want = min(size, -(-(hi - lo) // unit) * unit)
        a = max(0, min(lo - (want - (hi - lo)) // 2, size - want))
        box.append((a, a + want))
    (y0, y1), (x0, x1) = box
    if (y0, x0, y1, x1) == (0, 0, *p.shape):
        return p
    win = (slice(y0, y1), slice(x0, x1))
    return Patch(p.color[win], p.disparity[win], p.edges[win], p.context[win],
                 p.synthesis[win], (p.origin[0] + y0, p.origin[1] + x0), p.scale)
