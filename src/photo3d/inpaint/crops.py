"""Edge-net crops: a few rectangles of a pass's joint canvas that cover its synthesis
pixels (docs/learned.md, shared work).

The edge net's output matters only inside synthesis regions, but a pass's joint canvas
(:func:`~photo3d.inpaint.canvas.joint_patch`) is the union bounding box of all
patches, mostly context and empty space. :func:`cover` picks rectangles whose *cores*
hold every target pixel exactly once; each net run sees its core grown by ``halo``
pixels on every side (then grown further to the multiple of ``unit`` the net is padded
to anyway, so the padding is real content), and only its core's output is kept.

Windows are cut from the input one run over the whole canvas would get (the canvas
zero-padded, centred, to multiples of ``unit``): they may reach into that padding
(their pixels outside the canvas are zeros), their sizes are multiples of ``unit``,
and they start at multiples of ``phase`` (the net's total stride) in that frame, so
each window meets the net's strides as the whole run does. A net whose every output
pixel depends only on inputs within ``halo`` then gives the whole run's output in
every core exactly (instance norm breaks this: its statistics are the window's).

Cores come from a guillotine split of a coarse grid of ``cell`` x ``cell`` pixels:
a rectangle of cells is kept as one run (its core = the exact bounding box of its
target pixels) or cut in two along a grid line, whichever sends fewer padded pixels
through the net; a run larger than ``max_pixels`` padded pixels (memory) is always
cut.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter

Box = tuple[int, int, int, int]
"""``(y0, x0, y1, x1)``: rows ``y0:y1``, columns ``x0:x1``."""


def overlap(window: Box, shape: tuple[int, int],
            origin: tuple[int, int] = (0, 0)) -> tuple[tuple[slice, slice],
                                                      tuple[slice, slice]] | None:
    """Where ``window`` and an array of ``shape`` placed at ``origin`` (both in one
    frame) overlap: ``(slices in the window, slices in the array)``, or None.

    Example:
        >>> overlap((-2, 1, 3, 4), (2, 2))  # rows -2..2, cols 1..3 over a 2x2 array
        ((slice(2, 4, None), slice(0, 1, None)), (slice(0, 2, None), slice(1, 2, None)))
    """
    y0, x0, y1, x1 = window
    a, b = max(y0, origin[0]), max(x0, origin[1])
    c, d = min(y1, origin[0] + shape[0]), min(x1, origin[1] + shape[1])
    if c <= a or d <= b:
        return None
    return ((slice(a - y0, c - y0), slice(b - x0, d - x0)),
            (slice(a - origin[0], c - origin[0]), slice(b - origin[1], d - origin[1])))


@dataclass(frozen=True)
class Crop:
    """One net run over part of a canvas.

    Attributes:
        window: the canvas pixels the net sees (:data:`Box`; may reach beyond the
            canvas, into the padding of a run over the whole canvas: zeros).
        core: the pixels whose output is kept (:data:`Box`, inside ``window``).
    """

    window: Box
    core: Box

    def slices(self) -> tuple[slice, slice]:
        """The core's slices in the canvas."""
        y0, x0, y1, x1 = self.core
        return slice(y0, y1), slice(x0, x1)

    def take(self, image: np.ndarray) -> np.ndarray:
        """The window of ``image`` ``(C, H, W)``, zeros outside the canvas."""
        y0, x0, y1, x1 = self.window
        h, w = image.shape[-2:]
        if y0 >= 0 and x0 >= 0 and y1 <= h and x1 <= w:
            return image[..., y0:y1, x0:x1]
        out = np.zeros((*image.shape[:-2], y1 - y0, x1 - x0), image.dtype)
        both = overlap(self.window, (h, w))
        if both is not None:
            out[(..., *both[0])] = image[(..., *both[1])]
        return out

    def local(self) -> tuple[slice, slice]:
        """The core's slices inside the window."""
        (y0, x0, y1, x1), (wy, wx) = self.core, self.window[:2]
        return slice(y0 - wy, y1 - wy), slice(x0 - wx, x1 - wx)


def _round_up(n: int, unit: int) -> int:
    return -(-n // unit) * unit


def _span(lo: int, hi: int, size: int, halo: int, unit: int, phase: int) -> tuple[int, int]:
    """Rows (or columns) ``a:b`` of the window of ``lo:hi`` (see :func:`window`)."""
    full = _round_up(size, unit)
    off = (full - size) // 2  # where the canvas sits in the whole run's padded input
    lo, hi = lo + off, hi + off
    want = min(full, _round_up(min(full, hi + halo) - max(0, lo - halo), unit))

    def fits(v: int) -> bool:  # phase, and the halo on both sides (or the input's border)
        return (0 <= v <= full - want and v % phase == 0
                and (v == 0 or v <= lo - halo) and (v + want == full or v + want >= hi + halo))

    while want < full:
        centre = (lo + hi - want) // 2
        low, high = max(0, hi + halo - want), min(full - want, lo - halo)
        first = centre - centre % phase
        starts = [v for v in (first, first + phase, low + -low % phase, high - high % phase,
                              0, full - want) if fits(v)]
        if starts:
            a = min(starts, key=lambda v: abs(v - centre))
            return a - off, a + want - off
        want = min(full, want + unit)
    return -off, full - off


def window(core: Box, shape: tuple[int, int], halo: int, unit: int, phase: int = 1) -> Box:
    """The window of ``core`` on a canvas of ``shape`` (see the module docstring): ``core``
    grown by at least ``halo``, to multiples of ``unit``, starting at multiples of
    ``phase`` in the frame of the canvas padded (centred) to multiples of ``unit``.

    Example:
        >>> window((50, 50, 60, 60), (200, 300), 8, 32)  # 26 x 26 -> 32 x 32
        (39, 39, 71, 71)
        >>> window((50, 50, 60, 60), (200, 300), 8, 32, phase=4)  # canvas at (12, 10)
        (40, 38, 72, 70)
        >>> window((0, 0, 10, 10), (20, 20), 4, 32)  # the whole padded canvas
        (-6, -6, 26, 26)
    """
    (y0, y1), (x0, x1) = (_span(core[0], core[2], shape[0], halo, unit, phase),
                          _span(core[1], core[3], shape[1], halo, unit, phase))
    return y0, x0, y1, x1


def cost(core: Box, shape: tuple[int, int], halo: int, unit: int, phase: int = 1) -> int:
    """Pixels of the net run over ``core`` (the area of its :func:`window`)."""
    y0, x0, y1, x1 = window(core, shape, halo, unit, phase)
    return (y1 - y0) * (x1 - x0)


def cover(target: np.ndarray, *, halo: int | None, unit: int, max_pixels: int,
          phase: int = 1, cell: int = 32) -> list[Crop]:
    """Crops whose cores hold every ``target`` pixel exactly once (module docstring).

    Args:
        target: ``(H, W) bool`` pixels whose output is needed.
        halo: surroundings each core's window adds on every side; None: the whole
            run's input in one run, or in horizontal bands of at most about
            ``max_pixels`` (each band sees only its own rows).
        unit: the net's input is padded to multiples of this.
        max_pixels: padded pixels one run may take (memory).
        phase: the net's total stride (see :func:`window`).
        cell: grid step of the split (pixels).

    Returns:
        Crops with pairwise disjoint cores (empty when ``target`` is empty).

    Example:
        >>> t = np.zeros((400, 1000), bool); t[10:20, 10:20] = t[300:320, 900:960] = True
        >>> [c.core for c in cover(t, halo=16, unit=8, max_pixels=10**6)]
        [(10, 10, 20, 20), (300, 900, 320, 960)]
        >>> [c.window for c in cover(t, halo=None, unit=32, max_pixels=10**6)]
        [(-8, -12, 408, 1012)]
    """
    if not target.any():
        return []
    shape = target.shape
    if halo is None:  # the whole run's input, in bands of whole units
        (h, w), full = shape, (_round_up(shape[0], unit), _round_up(shape[1], unit))
        off = ((full[0] - h) // 2, (full[1] - w) // 2)
        step = max(1, max_pixels // (unit * full[1])) * unit  # rows per band
        cuts = [*range(-off[0], full[0] - off[0], step), full[0] - off[0]]
        crops = []
        for a, b in zip(cuts[:-1], cuts[1:], strict=True):
            rows = target[max(a, 0):max(b, 0)]
            if rows.any():
                ys, xs = np.nonzero(rows.any(1))[0] + max(a, 0), np.nonzero(rows.any(0))[0]
                crops.append(Crop((a, -off[1], b, full[1] - off[1]),
                                  (int(ys[0]), int(xs[0]), int(ys[-1]) + 1, int(xs[-1]) + 1)))
        return crops
    return _Splitter(target, halo, unit, max_pixels, cell, phase).run()


class _Splitter:
    """Guillotine split of the occupied cells of a grid (see :func:`cover`)."""

    def __init__(self, target: np.ndarray, halo: int, unit: int, max_pixels: int,
                 cell: int, phase: int) -> None:
        self.shape, self.halo, self.unit, self.max_pixels = target.shape, halo, unit, max_pixels
        self.phase = phase
        h, w = target.shape
        gh, gw = -(-h // cell), -(-w // cell)
        pad = np.zeros((gh * cell, gw * cell), bool)
        pad[:h, :w] = target
        blocks = pad.reshape(gh, cell, gw, cell)
        self.occupied = blocks.any((1, 3))
        rows, cols = blocks.any(3), blocks.any(1)  # (gh, cell, gw), (gh, gw, cell)
        big = np.iinfo(np.int64).max
        # exact bounding box of the target pixels inside each cell (canvas pixels)
        first_r = np.where(rows.any(1), rows.argmax(1), cell)
        last_r = np.where(rows.any(1), cell - 1 - rows[:, ::-1].argmax(1), -1)
        first_c = np.where(cols.any(2), cols.argmax(2), cell)
        last_c = np.where(cols.any(2), cell - 1 - cols[:, :, ::-1].argmax(2), -1)
        gy = np.arange(gh)[:, None] * cell
        gx = np.arange(gw)[None, :] * cell
        occ = self.occupied
        self.y0 = np.where(occ, gy + first_r, big)
        self.y1 = np.where(occ, gy + last_r + 1, -1)
        self.x0 = np.where(occ, gx + first_c, big)
        self.x1 = np.where(occ, gx + last_c + 1, -1)
        self.memo: dict[Box, tuple[int, list[Box]]] = {}

    def _shrink(self, r: Box) -> Box | None:
        occ = self.occupied[r[0]:r[2], r[1]:r[3]]
        if not occ.any():
            return None
        ys, xs = np.nonzero(occ.any(1))[0], np.nonzero(occ.any(0))[0]
        return r[0] + int(ys[0]), r[1] + int(xs[0]), r[0] + int(ys[-1]) + 1, r[1] + int(xs[-1]) + 1

    def _core(self, r: Box) -> Box:
        s = (slice(r[0], r[2]), slice(r[1], r[3]))
        return (int(self.y0[s].min()), int(self.x0[s].min()), int(self.y1[s].max()),
                int(self.x1[s].max()))

    def _cost(self, r: Box) -> int:
        return cost(self._core(r), self.shape, self.halo, self.unit, self.phase)

    def _splits(self, r: Box) -> list[tuple[Box, Box]]:
        out = []
        for k in range(r[0] + 1, r[2]):
            out.append(((r[0], r[1], k, r[3]), (k, r[1], r[2], r[3])))
        for k in range(r[1] + 1, r[3]):
            out.append(((r[0], r[1], r[2], k), (r[0], k, r[2], r[3])))
        return out

    def best(self, r: Box, depth: int = 0) -> tuple[int, list[Box]]:
        """Least padded pixels for the occupied cells of the (shrunk) cell box ``r``,
        and the cell boxes of its runs."""
        if r in self.memo:
            return self.memo[r]
        whole = self._cost(r)
        best = (whole, [r]) if whole <= self.max_pixels else (np.iinfo(np.int64).max, [r])
        ranked = []
        for a, b in self._splits(r):
            a, b = self._shrink(a), self._shrink(b)
            if a is None or b is None:
                continue
            ranked.append((self._cost(a) + self._cost(b), a, b))
        ranked.sort(key=lambda t: t[0])
        for _, a, b in ranked[:2 if depth < 3 else 1]:
            ca, runs_a = self.best(a, depth + 1)
            cb, runs_b = self.best(b, depth + 1)
            if ca + cb < best[0]:
                best = (ca + cb, runs_a + runs_b)
        self.memo[r] = best
        return best

    def run(self) -> list[Crop]:
        root = self._shrink((0, 0, *self.occupied.shape))
        assert root is not None
        crops = []
        for r in self.best(root)[1]:
            core = self._core(r)
            crops.append(Crop(window(core, self.shape, self.halo, self.unit, self.phase),
                              core))
        return crops


def grow(mask: np.ndarray, halo: int | None) -> np.ndarray:
    """``mask`` dilated by a ``(2 halo + 1)`` square (None: everything).

    Example:
        >>> grow(np.eye(1, 5, 2, dtype=bool), 1).astype(int).tolist()
        [[0, 1, 1, 1, 0]]
    """
    if halo is None:
        return np.ones_like(mask, bool)
    return maximum_filter(mask, size=2 * halo + 1, mode="constant", cval=False)
