"""Structure before texture: continue the context's edges into the synthesis region.

The paper's edge stage draws the lines and surface boundaries of the hidden area
before colour is filled. This is its classical counterpart, per patch:

1. *Edges of the context*: colour gradients (Sobel on each channel, only between
   context pixels) thinned by non-maximum suppression and kept above
   ``threshold``; disparity steps inside the context count as edges too.
2. *Seeds*: edge pixels within ``reach`` px of the synthesis region, strongest first.
3. *Direction*: the structure tensor of the colour gradients in a disc of
   ``radius`` context pixels around the seed; its minor eigenvector is the edge's
   tangent. Seeds with a weak orientation (coherence below ``coherence``) are skipped.
4. *Continuation*: a straight, 4-connected line from the seed along the tangent
   into the synthesis region, until it reaches context again, an earlier line, the
   patch border or ``max_length`` px. A seed closer than 2 px to an earlier line is
   the same edge and is skipped.

The lines are a ``(h, w) bool`` structure map; :mod:`photo3d.inpaint.structured`
fills each side of them separately.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _gradients(color, disparity, context, disp_step):  # pragma: no cover - jit
    """Sobel gradients (gy, gx) summed over channels as a structure tensor, with
    magnitude; zero wherever the 3x3 window leaves the context. Disparity steps
    between context neighbours are reported as ``jump``."""
    h, w, c = color.shape
    jxx = np.zeros((h, w), np.float32)
    jxy = np.zeros((h, w), np.float32)
    jyy = np.zeros((h, w), np.float32)
    mag = np.zeros((h, w), np.float32)
    jump = np.zeros((h, w), np.bool_)
    for y in range(1, h - 1):
        for x in range(1, w - 1):
            if not context[y, x]:
                continue
            full = True
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    if not context[y + dy, x + dx]:
                        full = False
            if not full:
                continue
            sxx = 0.0
            sxy = 0.0
            syy = 0.0
            for ch in range(c):
                gx = ((color[y - 1, x + 1, ch] + 2 * color[y, x + 1, ch] + color[y + 1, x + 1, ch])
                      - (color[y - 1, x - 1, ch] + 2 * color[y, x - 1, ch]
                         + color[y + 1, x - 1, ch])) / 8.0
                gy = ((color[y + 1, x - 1, ch] + 2 * color[y + 1, x, ch] + color[y + 1, x + 1, ch])
                      - (color[y - 1, x - 1, ch] + 2 * color[y - 1, x, ch]
                         + color[y - 1, x + 1, ch])) / 8.0
                sxx += gx * gx
                sxy += gx * gy
                syy += gy * gy
            jxx[y, x] = sxx
            jxy[y, x] = sxy
            jyy[y, x] = syy
            mag[y, x] = np.sqrt(sxx + syy)
            d = disparity[y, x]
            if (abs(disparity[y, x + 1] - d) > disp_step
                    or abs(disparity[y + 1, x] - d) > disp_step):
                jump[y, x] = True
    return jxx, jxy, jyy, mag, jump


@numba.njit(cache=True, nogil=True)
def _tangent(jxx, jxy, jyy, context, y, x, radius):  # pragma: no cover - jit
    """Unit tangent (ty, tx) and coherence of the structure tensor around (y, x)."""
    h, w = context.shape
    axx = 0.0
    axy = 0.0
    ayy = 0.0
    r2 = radius * radius
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            yy, xx = y + dy, x + dx
            if dy * dy + dx * dx > r2 or yy < 0 or xx < 0 or yy >= h or xx >= w:
                continue
            if not context[yy, xx]:
                continue
            axx += jxx[yy, xx]
            axy += jxy[yy, xx]
            ayy += jyy[yy, xx]
    tr = axx + ayy
    if tr <= 1e-12:
        return 0.0, 0.0, 0.0
    diff = np.sqrt((axx - ayy) ** 2 + 4 * axy * axy)
    l1 = 0.5 * (tr + diff)
    l2 = 0.5 * (tr - diff)
    coh = ((l1 - l2) / (l1 + l2 + 1e-12)) ** 2
    # Major eigenvector (gradient direction) of [[axx, axy], [axy, ayy]] in (x, y).
    if abs(axy) > 1e-12:
        gx, gy = l1 - ayy, axy
    elif axx >= ayy:
        gx, gy = 1.0, 0.0
    else:
        gx, gy = 0.0, 1.0
    n = np.sqrt(gx * gx + gy * gy)
    # The tangent (x, y) is perpendicular to the gradient.
    return -gy / n, gx / n, coh


@numba.njit(cache=True, nogil=True)
def _continue(color, disparity, context, synthesis, threshold, disp_step, reach, radius,
              coherence, max_length, support_factor, min_length):  # pragma: no cover - jit
    h, w = context.shape
    jxx, jxy, jyy, mag, jump = _gradients(color, disparity, context, disp_step)
    # Distance (4-neighbour steps, capped) from the synthesis region.
    dist = np.full((h, w), 1 << 20, np.int32)
    qy = np.empty(h * w, np.int32)
    qx = np.empty(h * w, np.int32)
    head = 0
    tail = 0
    for y in range(h):
        for x in range(w):
            if synthesis[y, x]:
                dist[y, x] = 0
                qy[tail] = y
                qx[tail] = x
                tail += 1
    while head < tail:
        y, x = qy[head], qx[head]
        head += 1
        if dist[y, x] >= reach:
            continue
        for k in range(4):
            yy = y + (0, 0, -1, 1)[k]
            xx = x + (-1, 1, 0, 0)[k]
            if 0 <= yy < h and 0 <= xx < w and dist[yy, xx] > dist[y, x] + 1:
                dist[yy, xx] = dist[y, x] + 1
                qy[tail] = yy
                qx[tail] = xx
                tail += 1
    # Seeds: thinned edge pixels near the synthesis region.
    n = 0
    sy = np.empty(h * w, np.int32)
    sx = np.empty(h * w, np.int32)
    ss = np.empty(h * w, np.float32)
    for y in range(1, h - 1):
        for x in range(1, w - 1):
            if not context[y, x] or dist[y, x] > reach:
                continue
            m = mag[y, x]
            strong = m > threshold
            if strong:
                # Non-maximum suppression across the edge (gradient direction).
                g = np.sqrt(jxx[y, x] + jyy[y, x])
                gx = np.sqrt(jxx[y, x]) / (g + 1e-12)
                gy = np.sqrt(jyy[y, x]) / (g + 1e-12)
                if jxy[y, x] < 0:
                    gy = -gy
                ox = int(np.round(gx))
                oy = int(np.round(gy))
                if mag[y + oy, x + ox] > m or mag[y - oy, x - ox] > m:
                    strong = False
            if strong or jump[y, x]:
                sy[n] = y
                sx[n] = x
                ss[n] = m + (1.0 if jump[y, x] else 0.0)
                n += 1
    order = np.argsort(-ss[:n])
    lines = np.zeros((h, w), np.bool_)
    owner = np.full((h, w), -1, np.int32)
    for oi in range(n):
        y0 = sy[order[oi]]
        x0 = sx[order[oi]]
        # Same edge as an earlier line?
        near = False
        for dy in range(-2, 3):
            for dx in range(-2, 3):
                yy, xx = y0 + dy, x0 + dx
                if 0 <= yy < h and 0 <= xx < w and owner[yy, xx] >= 0:
                    near = True
        if near:
            continue
        # int64 centres, as the second call's: one compiled _tangent, not two
        tx, ty, coh = _tangent(jxx, jxy, jyy, context, np.int64(y0), np.int64(x0), radius)
        if coh < coherence:
            continue
        # Which way leads into the synthesis region (within reach + 1 px)?
        sign = 0.0
        for s in (1.0, -1.0):
            for k in range(1, 2 * (reach + 2)):
                yy = int(np.floor(y0 + 0.5 + s * ty * 0.5 * k))
                xx = int(np.floor(x0 + 0.5 + s * tx * 0.5 * k))
                if yy < 0 or xx < 0 or yy >= h or xx >= w:
                    break
                if synthesis[yy, xx]:
                    sign = s
                    break
            if sign != 0.0:
                break
        if sign == 0.0:
            continue
        # Re-estimate the direction on a disc wholly behind the seed (away from the
        # synthesis region, where the disc around the seed is cut off).
        by = int(np.floor(y0 + 0.5 - sign * ty * radius))
        bx = int(np.floor(x0 + 0.5 - sign * tx * radius))
        if 0 <= by < h and 0 <= bx < w and context[by, bx]:
            ux, uy, ucoh = _tangent(jxx, jxy, jyy, context, by, bx, radius)
            if ucoh >= coherence:
                if ux * tx + uy * ty < 0:
                    ux, uy = -ux, -uy
                tx, ty = ux, uy
        # Centre the line on the edge: the gradient-weighted mean offset across it.
        nx, ny = -ty, tx
        num = 0.0
        den = 0.0
        for k in range(-2, 3):
            yy = int(np.floor(y0 + 0.5 + k * ny))
            xx = int(np.floor(x0 + 0.5 + k * nx))
            if 0 <= yy < h and 0 <= xx < w and context[yy, xx]:
                num += k * mag[yy, xx]
                den += mag[yy, xx]
        off = num / den if den > 0 else 0.0
        fy0 = y0 + off * ny
        fx0 = x0 + off * nx
        # Evidence: how far back into the context the edge runs straight.
        support = 0
        for k in range(1, 2 * max_length):
            yy = int(np.floor(fy0 + 0.5 - sign * ty * 0.5 * k))
            xx = int(np.floor(fx0 + 0.5 - sign * tx * 0.5 * k))
            if yy < 0 or xx < 0 or yy >= h or xx >= w or not context[yy, xx]:
                break
            # Strongest response across the line within 1 px of it.
            m = max(mag[yy, xx], max(mag[max(yy - 1, 0), xx], mag[min(yy + 1, h - 1), xx]),
                    max(mag[yy, max(xx - 1, 0)], mag[yy, min(xx + 1, w - 1)]))
            if m < 0.5 * threshold and not jump[yy, xx]:
                break
            support = k // 2
            owner[yy, xx] = oi  # this edge's pixels seed no second line
        # Refine the direction: a line through the edge's centre at points along its
        # straight run (a long baseline beats the tensor's staircase bias).
        if support >= 6:
            npts = 0
            sy_ = 0.0
            sx_ = 0.0
            syy = 0.0
            sxx = 0.0
            sxy = 0.0
            for t in range(0, min(support, 3 * radius) + 1, 2):
                cy = fy0 - sign * ty * t
                cx = fx0 - sign * tx * t
                num = 0.0
                den = 0.0
                for k in range(-2, 3):
                    yy = int(np.floor(cy + 0.5 + k * ny))
                    xx = int(np.floor(cx + 0.5 + k * nx))
                    if 0 <= yy < h and 0 <= xx < w and context[yy, xx]:
                        num += k * mag[yy, xx]
                        den += mag[yy, xx]
                if den <= 0:
                    continue
                qy_ = cy + num / den * ny
                qx_ = cx + num / den * nx
                npts += 1
                sy_ += qy_
                sx_ += qx_
                syy += qy_ * qy_
                sxx += qx_ * qx_
                sxy += qx_ * qy_
            if npts >= 3:
                my_, mx_ = sy_ / npts, sx_ / npts
                cxx = sxx / npts - mx_ * mx_
                cyy = syy / npts - my_ * my_
                cxy = sxy / npts - mx_ * my_
                ang = 0.5 * np.arctan2(2 * cxy, cxx - cyy)
                ux, uy = np.cos(ang), np.sin(ang)
                if ux * tx + uy * ty < 0:
                    ux, uy = -ux, -uy
                if ux * tx + uy * ty > 0.95:  # a refinement, not a new edge
                    tx, ty = ux, uy
                    # through the fitted line, at the seed
                    d = (fx0 - mx_) * ux + (fy0 - my_) * uy
                    fx0, fy0 = mx_ + d * ux, my_ + d * uy
        length = max_length
        if support_factor > 0:
            length = min(max_length, int(support_factor * support) + 1)
        if length < min_length:
            continue
        # March, 4-connected, through the synthesis region.
        py, px = int(np.floor(fy0 + 0.5)), int(np.floor(fx0 + 0.5))
        entered = False
        # The segment from the seed to the synthesis region is marked too (owner
        # only), so the same edge does not seed twice.
        for k in range(1, 2 * (max_length + reach + 2)):
            yy = int(np.floor(fy0 + 0.5 + sign * ty * 0.5 * k))
            xx = int(np.floor(fx0 + 0.5 + sign * tx * 0.5 * k))
            if yy == py and xx == px:
                continue
            if yy < 0 or xx < 0 or yy >= h or xx >= w:
                break
            if yy != py and xx != px:  # diagonal step: add a 4-connecting pixel
                cy, cx = py, xx
                if synthesis[cy, cx] and not lines[cy, cx]:
                    lines[cy, cx] = True
                    owner[cy, cx] = oi
            if synthesis[yy, xx]:
                entered = True
                if lines[yy, xx] and owner[yy, xx] != oi:
                    break
                lines[yy, xx] = True
                owner[yy, xx] = oi
            elif entered:
                # Reached context again (a hole with both sides known): the edge the
                # line lands on is this one's continuation and seeds no second line.
                for j in range(k, k + 2 * (reach + 2)):
                    yy = int(np.floor(fy0 + 0.5 + sign * ty * 0.5 * j))
                    xx = int(np.floor(fx0 + 0.5 + sign * tx * 0.5 * j))
                    if yy < 0 or xx < 0 or yy >= h or xx >= w or not context[yy, xx]:
                        break
                    owner[yy, xx] = oi
                break
            else:
                owner[yy, xx] = oi
            py, px = yy, xx
            if entered and 0.5 * k > length + reach:
                break
    return lines


KERNELS = ((_continue, "(float32[:, :, ::1], float32[:, ::1], boolean[:, ::1], boolean[:, ::1], "
                       "float32, float32, int64, int64, float64, int64, float64, int64)"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def continue_edges(
    color: np.ndarray,
    disparity: np.ndarray,
    context: np.ndarray,
    synthesis: np.ndarray,
    *,
    threshold: float = 0.06,
    disparity_step: float = 0.02,
    reach: int = 3,
    radius: int = 5,
    coherence: float = 0.6,
    max_length: int = 80,
    support_factor: float = 0.0,
    min_length: int = 0,
) -> np.ndarray:
    """Continue the context's edges into the synthesis region as straight lines.

    Args:
        color: ``(h, w, 3) float32`` in [0, 1] (read under ``context`` only).
        disparity: ``(h, w) float32`` normalised disparity (read under ``context``).
        context: ``(h, w) bool`` known pixels.
        synthesis: ``(h, w) bool`` pixels to fill.
        threshold: Sobel gradient magnitude (per unit of colour) that makes an edge.
        disparity_step: disparity difference between context neighbours that makes
            an edge.
        reach: seeds lie within this many px of the synthesis region.
        radius: px of the disc whose structure tensor gives the edge direction.
        coherence: minimum orientation coherence in [0, 1] of a seed.
        max_length: longest continuation into the synthesis region, px.
        support_factor: if > 0, a line continues at most this many times as far as
            the edge runs straight in the context (its support).
        min_length: lines allowed less than this many px are dropped.

    Returns:
        ``(h, w) bool``: the continued lines, 4-connected, inside ``synthesis`` only.

    Example:
        >>> col = np.zeros((20, 30, 3), np.float32); col[10:] = 1.0   # horizontal edge
        >>> ctx = np.zeros((20, 30), bool); ctx[:, :10] = True
        >>> lines = continue_edges(col * ctx[..., None], np.zeros((20, 30), np.float32),
        ...                        ctx, ~ctx)
        >>> sorted(set(np.nonzero(lines)[0].tolist()))   # the row of the edge
        [9]
        >>> int(lines[:, 10:].any(axis=0).sum())          # continued across the hole
        20
    """
    col = np.ascontiguousarray(np.where(context[..., None], color, 0), np.float32)
    disp = np.ascontiguousarray(np.where(context, disparity, 0), np.float32)
    return _continue(col, disp, np.ascontiguousarray(context), np.ascontiguousarray(synthesis),
                     np.float32(threshold), np.float32(disparity_step), int(reach),
                     int(radius), float(coherence), int(max_length), float(support_factor),
                     int(min_length))
