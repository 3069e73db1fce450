"""Context-aware diffusion: the "Facebook 3D photo" baseline of the paper.

Colour and disparity of the synthesis region are the harmonic interpolation of the
context: each synthesis pixel becomes the average of its 4-neighbours that are
context or synthesis pixels (neighbours outside both are ignored, a free boundary).
Values therefore come from the context only and stay within its range. The solve
starts from a breadth-first fill outwards from the context and runs successive
over-relaxation until the largest update is below ``tolerance`` (default 1e-3,
a quarter of a grey level). The sweeps are raster-order Gauss-Seidel, value for value,
but visit the pixels along the diagonals of bands of :data:`BAND` rows, so that the
processor need not wait for one pixel's update before the next (a quarter less time).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace

import numba
import numpy as np

from photo3d.parallel import map_ordered
from photo3d.progress import CountProgress
from photo3d.structures.patch import InpaintResult, Patch

BAND = 4
"""Rows the relaxation sweeps at once, along diagonals (:func:`diffuse_in_place`)."""


@numba.njit(cache=True, nogil=True)
def diffuse_in_place(values, context, synthesis, iterations, tolerance, omega):  # pragma: no cover
    """Fill ``values`` under ``synthesis`` in place: a breadth-first guess from the
    known neighbours, then over-relaxed Laplace (Gauss-Seidel) iterations.

    Args:
        values: ``(h, w, c) float64`` known under ``context``; overwritten under
            ``synthesis``.
        context, synthesis: ``(h, w) bool``.
        iterations: at most this many relaxation sweeps.
        tolerance: stop when no value changes by more than this.
        omega: over-relaxation factor in (1, 2).

    Returns:
        ``(h, w) bool`` the pixels reached (known or filled).

    Example:
        >>> v = np.zeros((1, 3, 1)); v[0, 0, 0] = 1.0
        >>> ctx = np.array([[True, False, False]])
        >>> reached = diffuse_in_place(v, ctx, ~ctx, 100, 1e-6, 1.9)
        >>> bool(reached.all()), float(v[0, 2, 0].round(3))
        (True, 1.0)
    """
    h, w, c = values.shape
    known = context.copy()
    dys = (0, 0, -1, 1)
    dxs = (-1, 1, 0, 0)
    # Breadth-first initial guess: mean of already known neighbours. It starts from the
    # context pixels next to the synthesis region, in raster order (the others would
    # queue nothing).
    qy = np.empty(h * w, np.int64)
    qx = np.empty(h * w, np.int64)
    head = 0
    tail = 0
    queued = context.copy()
    for y in range(h):
        for x in range(w):
            if context[y, x]:
                for k in range(4):
                    yy, xx = y + dys[k], x + dxs[k]
                    if 0 <= yy < h and 0 <= xx < w and synthesis[yy, xx]:
                        qy[tail] = y
                        qx[tail] = x
                        tail += 1
                        break
    acc = np.empty(c, np.float64)  # one buffer: an allocation per pixel cost a third
    while head < tail:
        y, x = qy[head], qx[head]
        head += 1
        if not known[y, x]:
            acc[:] = 0.0
            n = 0
            for k in range(4):
                yy, xx = y + dys[k], x + dxs[k]
                if 0 <= yy < h and 0 <= xx < w and known[yy, xx]:
                    for ch in range(c):
                        acc[ch] += values[yy, xx, ch]
                    n += 1
            for ch in range(c):
                values[y, x, ch] = acc[ch] / max(n, 1)
            known[y, x] = True
        for k in range(4):
            yy, xx = y + dys[k], x + dxs[k]
            if 0 <= yy < h and 0 <= xx < w and synthesis[yy, xx] and not queued[yy, xx]:
                queued[yy, xx] = True
                qy[tail] = yy
                qx[tail] = xx
                tail += 1
    # Successive over-relaxation on the reached synthesis pixels, with each pixel's
    # valid neighbours (context or synthesis) precomputed as flat indices.
    flat = values.reshape(h * w, c)
    # int32: half the index bytes each sweep streams (a patch is far below 2**31 pixels)
    unknown = np.empty(h * w, np.int32)
    nbr = np.empty((h * w, 4), np.int32)
    cnt = np.empty(h * w, np.int32)
    m = 0
    # The sweep's order: bands of BAND rows, each along its diagonals (row y0 + k at
    # column s - k, for s = 0, 1, ...). Every pixel still reads its upper and left
    # neighbours after, and its lower and right ones before, their update, as in raster
    # order, so the values are the same; but consecutive pixels no longer wait for each
    # other's update (a pixel's left neighbour was updated BAND pixels earlier).
    for y0 in range(0, h, BAND):
        rows = min(BAND, h - y0)
        for s in range(w + rows - 1):
            for k in range(rows):
                y = y0 + k
                x = s - k
                if x < 0 or x >= w or not (synthesis[y, x] and known[y, x]):
                    continue
                n = 0
                for j in range(4):
                    yy, xx = y + dys[j], x + dxs[j]
                    if 0 <= yy < h and 0 <= xx < w and (context[yy, xx] or synthesis[yy, xx]):
                        nbr[m, n] = yy * w + xx
                        n += 1
                if n > 0:
                    unknown[m] = y * w + x
                    cnt[m] = n
                    m += 1
    if c == 4:  # colour + disparity (structured), unrolled; the same sums in the same order
        for _ in range(iterations):
            worst = 0.0
            for i in range(m):
                u = unknown[i]
                n = cnt[i]
                inv = 1.0 / n
                q = nbr[i, 0]
                a0 = 0.0 + flat[q, 0]
                a1 = 0.0 + flat[q, 1]
                a2 = 0.0 + flat[q, 2]
                a3 = 0.0 + flat[q, 3]
                for k in range(1, n):
                    q = nbr[i, k]
                    a0 += flat[q, 0]
                    a1 += flat[q, 1]
                    a2 += flat[q, 2]
                    a3 += flat[q, 3]
                d0 = omega * (a0 * inv - flat[u, 0])
                d1 = omega * (a1 * inv - flat[u, 1])
                d2 = omega * (a2 * inv - flat[u, 2])
                d3 = omega * (a3 * inv - flat[u, 3])
                flat[u, 0] += d0
                flat[u, 1] += d1
                flat[u, 2] += d2
                flat[u, 3] += d3
                worst = max(worst, abs(d0), abs(d1), abs(d2), abs(d3))
            if worst < tolerance:
                break
        return known
    if c == 1:  # the texture weight's detail
        for _ in range(iterations):
            worst = 0.0
            for i in range(m):
                u = unknown[i]
                n = cnt[i]
                inv = 1.0 / n
                a0 = 0.0 + flat[nbr[i, 0], 0]
                for k in range(1, n):
                    a0 += flat[nbr[i, k], 0]
                d0 = omega * (a0 * inv - flat[u, 0])
                flat[u, 0] += d0
                worst = max(worst, abs(d0))
            if worst < tolerance:
                break
        return known
    for _ in range(iterations):
        worst = 0.0
        for i in range(m):
            u = unknown[i]
            n = cnt[i]
            inv = 1.0 / n
            for ch in range(c):
                acc0 = 0.0
                for k in range(n):
                    acc0 += flat[nbr[i, k], ch]
                delta = omega * (acc0 * inv - flat[u, ch])
                flat[u, ch] += delta
                if abs(delta) > worst:
                    worst = abs(delta)
        if worst < tolerance:
            break
    return known


KERNELS = ((diffuse_in_place, "(float32[:, :, ::1], boolean[:, ::1], boolean[:, ::1], int64, "
                              "float64, float64)"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def diffuse(
    values: np.ndarray,
    context: np.ndarray,
    synthesis: np.ndarray,
    *,
    iterations: int = 300,
    tolerance: float = 1e-3,
) -> np.ndarray:
    """Harmonic fill of ``synthesis`` from ``context``.

    Args:
        values: ``(h, w, c) float32``; only values under ``context`` are read.
        context: ``(h, w) bool`` known pixels.
        synthesis: ``(h, w) bool`` unknown pixels (disjoint from ``context``).
        iterations: maximum relaxation sweeps.
        tolerance: stop when no value changes more than this.

    Returns:
        ``(h, w, c) float32``: the context as given, the synthesis filled; synthesis
        pixels not connected to any context pixel get the context mean, everything
        else is zero.

    Example:
        >>> v = np.zeros((1, 5, 1), np.float32); v[0, 0] = 0.0; v[0, 4] = 1.0
        >>> ctx = np.array([[True, False, False, False, True]])
        >>> out = diffuse(v, ctx, ~ctx)
        >>> np.round(out[0, :, 0], 2).tolist()
        [0.0, 0.25, 0.5, 0.75, 1.0]
    """
    out = np.where(context[..., None], values, 0).astype(np.float32)
    if not synthesis.any():
        return out
    reached = diffuse_in_place(out, context, synthesis, iterations, tolerance, 1.9)
    lost = synthesis & ~reached
    if lost.any():
        out[lost] = out[context].mean(axis=0) if context.any() else 0.0
    return out


def diffuse_coarse(values: np.ndarray, context: np.ndarray, synthesis: np.ndarray, *,
                   iterations: int = 300, tolerance: float = 1e-3) -> np.ndarray:
    """:func:`diffuse` on a grid half as fine, for a smooth field whose fine detail
    does not matter (the texture weight's carried detail): a quarter of the pixels,
    about a fifth of the sweeps' work.

    A 2x2 block holding context pixels is known, at their mean; a block holding only
    synthesis pixels (and pixels of neither) is filled; every synthesis pixel takes
    its block's value. On the sample's patches the texture detail carried so differs
    from the exact harmonic fill by as much on average as :func:`diffuse`'s own
    (0.0013; its largest difference 0.053 against 0.036), for 9 sweeps' work
    instead of 42.

    Args:
        values: ``(h, w)`` or ``(h, w, c) float32``; only values under ``context``
            are read.
        context, synthesis: ``(h, w) bool``, disjoint.
        iterations, tolerance: :func:`diffuse`'s, on the coarse grid.

    Returns:
        float32, shaped as ``values``: the context as given, the synthesis filled,
        zero elsewhere.

    Example:
        >>> v = np.zeros((4, 16), np.float32); v[:, :2] = 1.0
        >>> ctx = np.zeros((4, 16), bool); ctx[:, :2] = ctx[:, 14:] = True
        >>> out = diffuse_coarse(v, ctx, ~ctx)
        >>> [round(float(x), 2) for x in out[0, ::2]]  # one value per 2x2 block
        [1.0, 0.86, 0.71, 0.57, 0.43, 0.29, 0.14, 0.0]
    """
    flat = values.ndim == 2
    values = values[..., None] if flat else values
    h, w = context.shape
    rows, cols = (h + 1) // 2, (w + 1) // 2

    def blocks(a: np.ndarray) -> np.ndarray:  # the sum of each 2x2 block (slices:
        pad = ((0, 2 * rows - h), (0, 2 * cols - w)) + ((0, 0),) * (a.ndim - 2)
        a = np.pad(a, pad)                    # a third of a reduction's time)
        return a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]

    known = blocks(context.view(np.uint8))
    total = blocks(np.where(context[..., None], values, 0).astype(np.float32))
    coarse_context = known > 0
    coarse = (total / np.maximum(known, 1)[..., None]).astype(np.float32)
    coarse_synthesis = blocks(synthesis) & ~coarse_context
    filled = diffuse(coarse, coarse_context, coarse_synthesis, iterations=iterations,
                     tolerance=tolerance)
    up = np.repeat(np.repeat(filled, 2, axis=0), 2, axis=1)[:h, :w]
    out = np.where(context[..., None], values, np.where(synthesis[..., None], up, 0))
    return out[..., 0].astype(np.float32) if flat else out.astype(np.float32)


@dataclass(frozen=True)
class DiffusionOptions:
    """What changes the ``diffusion`` backend's output (``config.json`` records it).

    Attributes:
        iterations: at most this many solver iterations (:func:`diffuse`).
        tolerance: the solver stops when no value changes by more than this.
    """

    iterations: int = 300
    tolerance: float = 1e-3


class DiffusionInpainter:
    """Backend ``"diffusion"``: fills colour and disparity by :func:`diffuse`.

    Predicts no new edges (the ``edges`` output is zero); new depth edges can still
    appear where synthesis regions of different depth layers meet, and the pipeline
    inpaints behind them in a further pass.

    Example:
        >>> from photo3d.inpaint import get_inpainter
        >>> inp = get_inpainter("diffusion")
        >>> ctx = np.zeros((4, 4), bool); ctx[:, :2] = True
        >>> p = Patch(np.ones((4, 4, 3), np.float32) * ctx[..., None],
        ...           np.full((4, 4), 0.5, np.float32) * ctx, np.zeros((4, 4), np.float32),
        ...           ctx, ~ctx, (0, 0))
        >>> r = inp.inpaint([p])[0]
        >>> float(r.color[0, 3, 0]), float(r.disparity[3, 3])
        (1.0, 0.5)
    """

    name = "diffusion"
    margin = 1
    later_context = 1.0
    """Later passes grow contexts as deep as the first (read by the pipeline)."""
    paper_context = False
    """Contexts take photo3d's rules too (read by the pipeline)."""
    patchwise = True
    """Each patch is filled on its own: the pipeline may give a pass's patches in batches."""

    def __init__(self, options: DiffusionOptions | None = None, **changes) -> None:
        """``options`` (default: its defaults) with ``changes`` (e.g. ``iterations=50``)."""
        self.options = replace(options or DiffusionOptions(), **changes)

    def settings(self) -> dict[str, object]:
        """What changes this backend's output, JSON-able (``config.json`` records it).

        Example:
            >>> DiffusionInpainter(iterations=50).settings()
            {'name': 'diffusion', 'iterations': 50, 'tolerance': 0.001}
        """
        return {"name": self.name, **asdict(self.options)}

    def inpaint(
        self, patches: Sequence[Patch], *, progress: CountProgress | None = None,
        pass_index: int = 0,
    ) -> list[InpaintResult]:
        """Fill every patch's synthesis region (every pass alike)."""

        def one(p: Patch) -> InpaintResult:
            stacked = np.concatenate([p.color, p.disparity[..., None]], axis=2)
            out = diffuse(stacked, p.context, p.synthesis, iterations=self.options.iterations,
                          tolerance=self.options.tolerance)
            return InpaintResult(
                color=np.clip(out[..., :3], 0.0, 1.0),
                disparity=out[..., 3],
                edges=np.zeros(p.shape, np.float32),
            )

        results = []
        # The solver releases the GIL, so patches run in parallel threads (the budget's:
        # the output does not depend on it).
        for i, result in enumerate(map_ordered(one, patches, name="diffusion")):
            results.append(result)
            if progress is not None:
                progress(i + 1, len(patches))
        return results

