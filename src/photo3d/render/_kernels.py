"""Numba kernels of the CPU rasterizer (:mod:`photo3d.render.raster`).

Keep every helper in this file, or numba's on-disk cache (keyed by the kernel file's
timestamp) would not see a helper change. The per-sample helpers are inlined; those
called once per band or rarely (:func:`_texture_rows`, :func:`_resolve_rows`,
:func:`_finish_rows`, :func:`_draw_float`, :func:`_draw_clipped`) are calls, so
:func:`raster_frame`'s parallel body holds one copy of :func:`_draw`: it compiles in
under half the time, and runs as fast. :func:`_span` (three times a row) is a call
too: numba types and lowers it once, LLVM still inlines it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

FASTMATH = {"contract", "arcp", "nsz", "afn"}
"""LLVM's fast-math flags of the per-pixel kernels: fused multiply-adds, reciprocals
and no signed zeros, but not ``nnan`` / ``ninf`` (empty pixels hold ``inf`` depth and
the kernels test for it). A textured frame: 5 % less CPU, colours within 2e-5."""


@njit(cache=True, error_model="numpy", inline="always")
def _edge(sv, p, q):
    """Canonical edge ``p -> q``: origin, direction and the sign of ``p -> q``."""
    py, qy = np.float64(sv[p, 1]), np.float64(sv[q, 1])
    px, qx = np.float64(sv[p, 0]), np.float64(sv[q, 0])
    if py < qy or (py == qy and px <= qx):
        return px, py, qx - px, qy - py, 1.0
    return qx, qy, px - qx, py - qy, -1.0


@njit(cache=True, error_model="numpy", inline="always")
def _nearest(b0, b1, b2, v0, v1, v2):
    """The value ``v_k`` of the corner with the largest barycentric weight ``b_k`` (any
    positive multiple of the weights; ties go to the lower ``k``): constant over each
    corner's cell, the part of the triangle nearer that corner than the others in
    barycentric terms (bounded by the lines from the edges' midpoints to the
    centroid)."""
    if b0 >= b1 and b0 >= b2:
        return v0
    return v1 if b1 >= b2 else v2


@njit(cache=True, error_model="numpy", nogil=True)  # rare: called, not inlined
def _draw_float(sv, col, scale, i0, i1, i2, r0, r1, c0, c1, color, depth, count, alpha):
    """:func:`_draw` for huge screen coordinates, in float64 edge functions (exact
    for 1/256-snapped vertices) evaluated with each edge's end points in a canonical
    order; rows ``r0..r1`` and columns ``c0..c1`` are the clamped bounding box."""
    fringe = alpha.shape[0] > 0
    ay, ax = np.float64(sv[i0, 1]), np.float64(sv[i0, 0])
    iz0, iz1, iz2 = np.float64(sv[i0, 2]), np.float64(sv[i1, 2]), np.float64(sv[i2, 2])
    # Edge k is opposite vertex k; its value is the weight of vertex k.
    ox0, oy0, dx0, dy0, s0 = _edge(sv, i1, i2)
    ox1, oy1, dx1, dy1, s1 = _edge(sv, i2, i0)
    ox2, oy2, dx2, dy2, s2 = _edge(sv, i0, i1)
    area = s0 * (dx0 * (ay - oy0) - dy0 * (ax - ox0))
    if area == 0.0:
        return
    o = 1.0 if area > 0.0 else -1.0
    # Oriented edge values w = kx * (py - oy) - ky * (px - ox) >= 0 inside.
    kx0, ky0 = o * s0 * dx0, o * s0 * dy0
    kx1, ky1 = o * s1 * dx1, o * s1 * dy1
    kx2, ky2 = o * s2 * dx2, o * s2 * dy2
    # Top-left: inward normal (-ky, kx) points to +x, or to +y on a horizontal edge.
    tl0 = ky0 < 0.0 or (ky0 == 0.0 and kx0 > 0.0)
    tl1 = ky1 < 0.0 or (ky1 == 0.0 and kx1 > 0.0)
    tl2 = ky2 < 0.0 or (ky2 == 0.0 and kx2 > 0.0)
    area = abs(area)
    for y in range(r0, r1 + 1):
        yc = y + 0.5
        g0, g1, g2 = kx0 * (yc - oy0), kx1 * (yc - oy1), kx2 * (yc - oy2)
        for x in range(c0, c1 + 1):
            xc = x + 0.5
            w0 = g0 - ky0 * (xc - ox0)
            w1 = g1 - ky1 * (xc - ox1)
            w2 = g2 - ky2 * (xc - ox2)
            if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                continue
            if (w0 == 0.0 and not tl0) or (w1 == 0.0 and not tl1) or (w2 == 0.0 and not tl2):
                if (w0 == 0.0) + (w1 == 0.0) + (w2 == 0.0) < 2:  # not on a vertex
                    continue
            if count.shape[0] > 0:
                count[y, x] += 1
            # Perspective-correct: a_k / sum(a) are the barycentrics in 3D.
            a0, a1, a2 = w0 * iz0, w1 * iz1, w2 * iz2
            suma = a0 + a1 + a2
            z = np.float32(area / suma)
            if z < depth[y, x]:
                depth[y, x] = z
                if fringe:  # the nearest corner's colour and alpha
                    j = _nearest(a0, a1, a2, i0, i1, i2)
                    for ch in range(3):
                        color[y, x, ch] = min(max(col[j, ch] * scale, 0.0), 1.0)
                    color[y, x, 3] = alpha[j]
                else:
                    for ch in range(3):
                        v = (a0 * col[i0, ch] + a1 * col[i1, ch] + a2 * col[i2, ch]) / suma
                        color[y, x, ch] = min(max(v * scale, 0.0), 1.0)


_SPAN_MIN = 1
"""Boxes at least this many columns wide scan only the columns a row can cover (the
spans cost a multiply each since their quotients come from a reciprocal, so every box
but a one-column one: the triangles of a light mesh are mostly small)."""


@njit(cache=True, error_model="numpy")  # a call: inlined 3 times it cost 3 s to compile
def _span(w, s, inv, c0, lo, hi):
    """Narrow columns ``lo..hi`` of a row to those where the edge value ``w - s (x -
    c0)`` (``w`` at column ``c0``, integers) is >= 0; ``lo > hi`` when none is.
    ``inv``: ``1 / |s|`` (a float estimate of the quotient, corrected exactly)."""
    if s > 0:
        q = np.int64(math.floor(w * inv))
        if w - s * q < 0:
            q -= 1
        elif w - s * (q + 1) >= 0:
            q += 1
        hi = min(hi, c0 + q)
    elif s < 0:
        q = np.int64(math.floor(w * inv))
        if w + s * q < 0:
            q -= 1
        elif w + s * (q + 1) >= 0:
            q += 1
        lo = max(lo, c0 - q)
    elif w < 0:
        hi = lo - 1
    return lo, hi


@njit(cache=True, error_model="numpy", inline="always")
def _draw(sv, col, scale, i0, i1, i2, y_lo, y_hi, width, color, depth, count, uv, alpha):
    """Rasterize triangle ``(i0, i1, i2)`` of ``sv`` into rows ``[y_lo, y_hi)``.

    Edge functions are exact integers on the 1/256 px grid the vertices are snapped
    to (24.8 fixed point), stepped incrementally along each row; a row of a wide box
    is scanned only between its edges (:func:`_span`). ``uv``: ``col`` holds texture
    coordinates (two channels, not clamped). ``alpha``: ``(N,) float32`` vertex
    coverage, or ``(0,)`` for none (``color`` may then have three channels); with it,
    each sample takes the colour and (fourth channel) the alpha of the corner with
    the largest perspective-correct barycentric weight (:func:`_nearest`: the
    fringe of soft silhouettes, drawn as its pixels' footprints), not interpolated
    colours."""
    ay, by, cy = np.float64(sv[i0, 1]), np.float64(sv[i1, 1]), np.float64(sv[i2, 1])
    r0 = max(y_lo, math.ceil(min(ay, by, cy) - 0.5))
    r1 = min(y_hi - 1, math.floor(max(ay, by, cy) - 0.5))
    if r0 > r1:
        return
    iz0, iz1, iz2 = np.float64(sv[i0, 2]), np.float64(sv[i1, 2]), np.float64(sv[i2, 2])
    if iz0 < 0 or iz1 < 0 or iz2 < 0:
        return
    ax, bx, cx = np.float64(sv[i0, 0]), np.float64(sv[i1, 0]), np.float64(sv[i2, 0])
    c0 = max(0, math.ceil(min(ax, bx, cx) - 0.5))
    c1 = min(width - 1, math.floor(max(ax, bx, cx) - 0.5))
    if c0 > c1:
        return
    lim = 4194304.0  # 2^22 px: products stay within int64
    if max(abs(ax), abs(bx), abs(cx), abs(ay), abs(by), abs(cy)) > lim:
        _draw_float(sv, col, scale, i0, i1, i2, r0, r1, c0, c1, color, depth, count, alpha)
        return
    X0, Y0 = np.int64(ax * 256.0), np.int64(ay * 256.0)
    X1, Y1 = np.int64(bx * 256.0), np.int64(by * 256.0)
    X2, Y2 = np.int64(cx * 256.0), np.int64(cy * 256.0)
    # edge k opposite vertex k: from vertex (k+1) to (k+2); E_k(P) = (B - A) x (P - A)
    dx0, dy0 = X2 - X1, Y2 - Y1
    dx1, dy1 = X0 - X2, Y0 - Y2
    dx2, dy2 = X1 - X0, Y1 - Y0
    area = dx2 * (Y2 - Y0) - dy2 * (X2 - X0)
    if area == 0:
        return
    if area < 0:
        dx0, dy0, dx1, dy1, dx2, dy2 = -dx0, -dy0, -dx1, -dy1, -dx2, -dy2
        area = -area
    # inside: E_k = dx_k * (Py - Ay_k) - dy_k * (Px - Ax_k) >= 0 (A_k: start of edge k)
    tl0 = dy0 < 0 or (dy0 == 0 and dx0 > 0)
    tl1 = dy1 < 0 or (dy1 == 0 and dx1 > 0)
    tl2 = dy2 < 0 or (dy2 == 0 and dx2 > 0)
    px0 = np.int64(c0) * 256 + 128
    farea = np.float64(area)
    counting = count.shape[0] > 0
    r0c, g0c, b0c = col[i0, 0] * scale, col[i0, 1] * scale, col[i0, 2] * scale
    r1c, g1c, b1c = col[i1, 0] * scale, col[i1, 1] * scale, col[i1, 2] * scale
    r2c, g2c, b2c = col[i2, 0] * scale, col[i2, 1] * scale, col[i2, 2] * scale
    fringe = alpha.shape[0] > 0
    s0, s1, s2 = dy0 * 256, dy1 * 256, dy2 * 256
    inv0 = 1.0 / abs(s0) if s0 != 0 else 0.0
    inv1 = 1.0 / abs(s1) if s1 != 0 else 0.0
    inv2 = 1.0 / abs(s2) if s2 != 0 else 0.0
    # a_k = w_k / z_k and its colour-weighted sums are linear along a row: stepped by
    # adding, like the edge values (only the pixels a triangle wins divide)
    fs0, fs1, fs2 = np.float64(s0) * iz0, np.float64(s1) * iz1, np.float64(s2) * iz2
    da = -(fs0 + fs1 + fs2)
    dr = -(fs0 * r0c + fs1 * r1c + fs2 * r2c)
    dg = -(fs0 * g0c + fs1 * g1c + fs2 * g2c)
    db = -(fs0 * b0c + fs1 * b1c + fs2 * b2c)
    for y in range(r0, r1 + 1):
        py = np.int64(y) * 256 + 128
        w0 = dx0 * (py - Y1) - dy0 * (px0 - X1)
        w1 = dx1 * (py - Y2) - dy1 * (px0 - X2)
        w2 = dx2 * (py - Y0) - dy2 * (px0 - X0)
        x0, x1 = c0, c1
        if c1 - c0 >= _SPAN_MIN:  # only the columns all three edges can cover
            x0, x1 = _span(w0, s0, inv0, c0, x0, x1)
            x0, x1 = _span(w1, s1, inv1, c0, x0, x1)
            x0, x1 = _span(w2, s2, inv2, c0, x0, x1)
            w0 -= s0 * (x0 - c0)
            w1 -= s1 * (x0 - c0)
            w2 -= s2 * (x0 - c0)
        if x0 > x1:
            continue
        a0, a1, a2 = w0 * iz0, w1 * iz1, w2 * iz2
        sa = a0 + a1 + a2
        sr = a0 * r0c + a1 * r1c + a2 * r2c
        sg = a0 * g0c + a1 * g1c + a2 * g2c
        sb = a0 * b0c + a1 * b1c + a2 * b2c
        for x in range(x0, x1 + 1):
            if w0 >= 0 and w1 >= 0 and w2 >= 0:
                ok = True
                if (w0 == 0 and not tl0) or (w1 == 0 and not tl1) or (w2 == 0 and not tl2):
                    if (w0 == 0) + (w1 == 0) + (w2 == 0) < 2:
                        ok = False
                if ok:
                    if counting:
                        count[y, x] += 1
                    # z = area / sa, nearer than the depth buffer (no division)
                    if farea < depth[y, x] * sa:
                        inv = 1.0 / sa
                        depth[y, x] = np.float32(farea * inv)
                        if uv:  # texture coordinates: the texture lookup clamps them
                            color[y, x, 0] = sr * inv
                            color[y, x, 1] = sg * inv
                        elif fringe:  # the nearest corner's colour and alpha (its cell)
                            j = _nearest(w0 * iz0, w1 * iz1, w2 * iz2, i0, i1, i2)
                            color[y, x, 0] = min(max(col[j, 0] * scale, 0.0), 1.0)
                            color[y, x, 1] = min(max(col[j, 1] * scale, 0.0), 1.0)
                            color[y, x, 2] = min(max(col[j, 2] * scale, 0.0), 1.0)
                            color[y, x, 3] = alpha[j]
                        else:
                            color[y, x, 0] = min(max(sr * inv, 0.0), 1.0)
                            color[y, x, 1] = min(max(sg * inv, 0.0), 1.0)
                            color[y, x, 2] = min(max(sb * inv, 0.0), 1.0)
            w0 -= s0
            w1 -= s1
            w2 -= s2
            sa += da
            sr += dr
            sg += dg
            sb += db


@njit(cache=True, error_model="numpy", nogil=True)
def _draw_clipped(sv, col, i0, i1, i2, y_lo, y_hi, width, color, depth, count, uv, alpha):
    """:func:`_draw` of a triangle clipped at the near plane (few: a call, so
    :func:`raster_frame` inlines :func:`_draw` once, which halves its compile time)."""
    _draw(sv, col, 1.0, i0, i1, i2, y_lo, y_hi, width, color, depth, count, uv, alpha)


@njit(cache=True, error_model="numpy", inline="always")
def _occluded(sv, i0, i1, i2, y_lo, y_hi, width, tile_max, tile):
    """True if the triangle lies behind the farthest depth of every tile it touches."""
    iz = max(sv[i0, 2], sv[i1, 2], sv[i2, 2])
    if min(sv[i0, 2], sv[i1, 2], sv[i2, 2]) < 0 or iz <= 0:
        return False
    zmin = 1.0 / iz
    ys = (sv[i0, 1], sv[i1, 1], sv[i2, 1])
    xs = (sv[i0, 0], sv[i1, 0], sv[i2, 0])
    r0 = max(y_lo, math.ceil(min(ys) - 0.5))
    r1 = min(y_hi - 1, math.floor(max(ys) - 0.5))
    c0 = max(0, math.ceil(min(xs) - 0.5))
    c1 = min(width - 1, math.floor(max(xs) - 0.5))
    if r0 > r1 or c0 > c1:
        return True  # covers no sample of this band
    for ty in range((r0 - y_lo) // tile, (r1 - y_lo) // tile + 1):
        for tx in range(c0 // tile, c1 // tile + 1):
            if tile_max[ty, tx] >= zmin:
                return False
    return True


BLOCK = 64
"""Faces per culling block: consecutive faces of photo3d meshes are neighbours."""


@njit(parallel=True, cache=True, error_model="numpy", nogil=True)
def block_vertices(faces, block):
    """The distinct vertices of each block of ``block`` consecutive faces, as CSR:
    ``(offsets (nb + 1,) int64, ids int32)``. A block of a grid layer uses about a
    third as many vertices as it has corners, so bounds read a third of the data."""
    nb = (faces.shape[0] + block - 1) // block
    counts = np.zeros(nb + 1, np.int64)
    for b in prange(nb):
        t0, t1 = b * block, min((b + 1) * block, faces.shape[0])
        corners = np.sort(faces[t0:t1].ravel())
        n = 1
        for i in range(1, corners.size):
            n += corners[i] != corners[i - 1]
        counts[b + 1] = n
    offsets = np.cumsum(counts)
    ids = np.empty(offsets[-1], np.int32)
    for b in prange(nb):
        t0, t1 = b * block, min((b + 1) * block, faces.shape[0])
        corners = np.sort(faces[t0:t1].ravel())
        k = offsets[b]
        ids[k] = corners[0]
        for i in range(1, corners.size):
            if corners[i] != corners[i - 1]:
                k += 1
                ids[k] = corners[i]
    return offsets, ids


@njit(cache=True, error_model="numpy", nogil=True)  # serial: 0.2 ms, less than a fork
def block_bounds(sv, offsets, ids):
    """Per block of faces, its screen bounding box and nearest depth, for culling.

    Args:
        sv: ``(N, 3) float32`` screen vertices ``(x, y, 1 / z)`` (negative ``1 / z``:
            behind the near plane).
        offsets, ids: the blocks' vertices as CSR, from :func:`block_vertices`.

    Returns:
        ``(nb, 5) float64``: screen ``ymin, ymax, xmin, xmax`` and the largest inverse
        depth of each block; ``ymin = +inf`` marks a block with a vertex behind the
        near plane (never culled).

    Example:
        >>> faces = np.array([[0, 1, 2]], np.int32)
        >>> sv = np.array([[1, 2, 0.5], [3, 4, 0.25], [2, 5, 0.5]], np.float32)
        >>> block_bounds(sv, *block_vertices(faces, 64)).tolist()
        [[2.0, 5.0, 1.0, 3.0, 0.5]]
    """
    nb = offsets.shape[0] - 1
    out = np.empty((nb, 5), np.float64)
    for b in range(nb):
        y0, y1, x0, x1, izmax = np.inf, -np.inf, np.inf, -np.inf, 0.0
        behind = False
        for k in range(offsets[b], offsets[b + 1]):
            v = ids[k]
            iz = sv[v, 2]
            if iz < 0:
                behind = True
            y0, y1 = min(y0, sv[v, 1]), max(y1, sv[v, 1])
            x0, x1 = min(x0, sv[v, 0]), max(x1, sv[v, 0])
            izmax = max(izmax, iz)
        out[b, 0] = np.inf if behind else y0
        out[b, 1], out[b, 2], out[b, 3], out[b, 4] = y1, x0, x1, izmax
    return out


@njit(cache=True, error_model="numpy", inline="always")
def _block_skipped(bounds, b, y_lo, y_hi, width, tile_max, tile, use_tiles):
    """True if block ``b`` covers no sample of the band or is hidden in every tile."""
    if bounds[b, 0] == np.inf:
        return False
    r0 = max(y_lo, math.ceil(bounds[b, 0] - 0.5))
    r1 = min(y_hi - 1, math.floor(bounds[b, 1] - 0.5))
    c0 = max(0, math.ceil(bounds[b, 2] - 0.5))
    c1 = min(width - 1, math.floor(bounds[b, 3] - 0.5))
    if r0 > r1 or c0 > c1:
        return True
    if not use_tiles or bounds[b, 4] <= 0:
        return False
    zmin = 1.0 / bounds[b, 4]
    for ty in range((r0 - y_lo) // tile, (r1 - y_lo) // tile + 1):
        for tx in range(c0 // tile, c1 // tile + 1):
            if tile_max[ty, tx] >= zmin:
                return False
    return True


@njit(cache=True, error_model="numpy", nogil=True)
def _resolve_rows(color, depth, factor, r0, r1, out_color, out_cov, out_depth):
    """Supersampling resolve of output rows ``r0..r1-1``: the mean colour of the covered
    samples (``depth < inf``) of each ``factor x factor`` block, the covered fraction
    and the nearest depth (0, 0 and inf where nothing is covered). A fourth channel
    (alpha) is averaged like the colours."""
    inv = 1.0 / (factor * factor)
    four = color.shape[2] == 4
    for oy in range(r0, r1):
        for ox in range(out_cov.shape[1]):
            n = 0
            r = 0.0
            g = 0.0
            b = 0.0
            a = 0.0
            d = np.inf
            for y in range(oy * factor, oy * factor + factor):
                for x in range(ox * factor, ox * factor + factor):
                    z = depth[y, x]
                    if z < np.inf:
                        n += 1
                        r += color[y, x, 0]
                        g += color[y, x, 1]
                        b += color[y, x, 2]
                        if four:
                            a += color[y, x, 3]
                        d = min(d, z)
            if n > 0:
                out_color[oy, ox, 0] = r / n
                out_color[oy, ox, 1] = g / n
                out_color[oy, ox, 2] = b / n
                if four:
                    out_color[oy, ox, 3] = a / n
            else:
                out_color[oy, ox, 0] = 0.0
                out_color[oy, ox, 1] = 0.0
                out_color[oy, ox, 2] = 0.0
                if four:
                    out_color[oy, ox, 3] = 0.0
            out_cov[oy, ox] = n * inv
            out_depth[oy, ox] = d


@njit(parallel=True, cache=True, error_model="numpy", nogil=True)
def resolve(color, depth, factor):
    """Supersampling resolve of a whole ``(H, W)`` frame (H, W multiples of
    ``factor``): ``(color (H/f, W/f, C), coverage (H/f, W/f), depth (H/f, W/f))``
    (``C``: ``color``'s channels, 3 or 4), see :func:`_resolve_rows`.
    :func:`raster_frame` does the same per band, fused."""
    h, w = depth.shape[0] // factor, depth.shape[1] // factor
    out_color = np.empty((h, w, color.shape[2]), np.float32)
    out_cov = np.empty((h, w), np.float32)
    out_depth = np.empty((h, w), np.float32)
    rows = 8
    for i in prange((h + rows - 1) // rows):
        _resolve_rows(color, depth, factor, i * rows, min(h, (i + 1) * rows), out_color,
                      out_cov, out_depth)
    return out_color, out_cov, out_depth


@njit(cache=True, error_model="numpy", nogil=True, fastmath=FASTMATH)
def _texture_rows(color, depth, texture, y_lo, y_hi):
    """Deferred texturing of rows ``y_lo..y_hi-1``: every covered sample's colour
    holds ``(u, v, 0)`` texture coordinates (glTF convention: texel ``(row, col)``
    has its centre at ``((col + 0.5) / U, (row + 0.5) / T)``); replace them by the
    bilinear texture value in [0, 1], clamped at the edges. ``texture``: ``(T, U)
    uint32``, texels packed ``R | G << 8 | B << 16`` (:func:`pack_texture`: one load
    a texel instead of three). Per row, the texel indices and weights first, in a
    loop LLVM vectorizes, then the lookups; in float32 (values within 1e-6 of
    float64)."""
    th, tw = texture.shape[0], texture.shape[1]
    flat = texture.reshape(-1)
    ftw, fth = np.float32(tw), np.float32(th)
    zero, half, one = np.float32(0.0), np.float32(0.5), np.float32(1.0)
    xmax, ymax = np.float32(tw - 1), np.float32(th - 1)
    inv = np.float32(1.0 / 255.0)
    m = np.uint32(255)
    width = color.shape[1]
    index = np.empty(width, np.int64)
    fxs = np.empty(width, np.float32)
    fys = np.empty(width, np.float32)
    for y in range(y_lo, y_hi):
        for x in range(width):  # all pixels, no branch: an empty pixel's index and
            # weights (from whatever its colour holds) are never used
            fx = min(max(color[y, x, 0] * ftw - half, zero), xmax)
            fy = min(max(color[y, x, 1] * fth - half, zero), ymax)
            x0 = max(min(np.int64(fx), tw - 2), 0)  # clamped: a valid index whatever fx
            y0 = max(min(np.int64(fy), th - 2), 0)
            index[x] = y0 * tw + x0
            fxs[x] = fx - np.float32(x0)
            fys[x] = fy - np.float32(y0)
        for x in range(width):
            if depth[y, x] == np.inf:
                continue
            k = index[x]
            p00, p01, p10, p11 = flat[k], flat[k + 1], flat[k + tw], flat[k + tw + 1]
            ax, ay = fxs[x], fys[x]
            bx, by = one - ax, one - ay
            w00, w01, w10, w11 = bx * by * inv, ax * by * inv, bx * ay * inv, ax * ay * inv
            for ch in range(3):
                s = np.uint32(8 * ch)
                color[y, x, ch] = (np.float32((p00 >> s) & m) * w00
                                   + np.float32((p01 >> s) & m) * w01
                                   + np.float32((p10 >> s) & m) * w10
                                   + np.float32((p11 >> s) & m) * w11)


def pack_texture(texture):
    """``(T, U, 3) uint8`` -> ``(T, U) uint32`` texels ``R | G << 8 | B << 16``, what
    :func:`_texture_rows` reads (NumPy, once per mesh).

    Example:
        >>> hex(int(pack_texture(np.array([[[1, 2, 3]]], np.uint8))[0, 0]))
        '0x30201'
    """
    texture = np.asarray(texture, np.uint8)
    packed = texture[..., 0].astype(np.uint32)
    packed |= texture[..., 1].astype(np.uint32) << 8
    packed |= texture[..., 2].astype(np.uint32) << 16
    return packed


EDGE_BLEND = 0.125
"""Share of a neighbour's colour that ``smooth`` mixes into a pixel across a depth edge
(:func:`_finish_rows`): what a 2x2-supersampled pixel takes on average from the
surface beyond an edge that lies anywhere between the two pixel centres (half its
samples when the edge is within a quarter pixel of it, none otherwise)."""


@njit(cache=True, error_model="numpy", nogil=True, fastmath=FASTMATH)
def _finish_rows(color, depth, smooth, r0, r1, out_color, out_cov, out_depth, out_rgb, blend):
    """One sample per pixel, rows ``r0..r1-1``: the resolve of :func:`_resolve_rows`
    with ``factor = 1``, and with ``smooth > 0`` a covered pixel whose 4-neighbour is
    covered but more than ``smooth`` (relative) nearer or farther mixes in
    :data:`EDGE_BLEND` of that neighbour's colour, an edge antialiasing for one
    sample per pixel. Needs the rows next to its own drawn. ``out_rgb``: ``(H, W, 3)
    uint8`` receives the colours in 8 bits as well (as
    :func:`photo3d.render._resolve.to_rgb8`; black where nothing is covered), or
    ``(0, 0, 3)`` for none. A fourth channel (alpha) is copied and blended like the
    colours (0 where nothing is covered).

    ``blend``: ``color`` (four channels: the soft silhouettes' fringe) is instead
    blended over the frame ``out_color`` ``(H, W, 3)``, ``out_depth`` (and
    ``out_rgb``) drawn before, in place: where a covered pixel is at or in front of
    ``out_depth`` (within 0.1 %), ``a`` (its alpha) of its colour over
    ``out_color``, and ``out_depth`` the nearer; other pixels are left as they are
    (``out_cov`` is not used). :func:`photo3d.render._resolve.blend_fringe` with
    coverage 1, fused."""
    h, w = depth.shape
    grow = 1.0 + smooth
    rgb8 = out_rgb.shape[0] > 0
    four = color.shape[2] == 4
    for y in range(r0, r1):
        for x in range(w):
            z = depth[y, x]
            if blend:
                if z == np.inf or z > out_depth[y, x] * 1.001:
                    continue
            else:
                out_depth[y, x] = z
            if z == np.inf:
                out_cov[y, x] = 0.0
                out_color[y, x, 0], out_color[y, x, 1], out_color[y, x, 2] = 0.0, 0.0, 0.0
                if four:
                    out_color[y, x, 3] = 0.0
                if rgb8:
                    out_rgb[y, x, 0], out_rgb[y, x, 1], out_rgb[y, x, 2] = 0, 0, 0
                continue
            if not blend:
                out_cov[y, x] = 1.0
            r, g, b = color[y, x, 0], color[y, x, 1], color[y, x, 2]
            mr, mg, mb = r, g, b
            a = color[y, x, 3] if four else np.float32(0.0)
            ma = a
            # quick test: the 4-neighbours (clamped at the border) within range
            za, zb = depth[max(y - 1, 0), x], depth[min(y + 1, h - 1), x]
            zc, zd = depth[y, max(x - 1, 0)], depth[y, min(x + 1, w - 1)]
            if smooth > 0.0 and not (max(za, zb, zc, zd) <= z * grow
                                     and z <= min(za, zb, zc, zd) * grow):
                for k in range(4):
                    yy = y + (k == 1) - (k == 3)
                    xx = x + (k == 0) - (k == 2)
                    if yy < 0 or yy >= h or xx < 0 or xx >= w:
                        continue
                    zn = depth[yy, xx]
                    if zn < np.inf and abs(zn - z) > smooth * min(z, zn):
                        mr += EDGE_BLEND * (color[yy, xx, 0] - r)
                        mg += EDGE_BLEND * (color[yy, xx, 1] - g)
                        mb += EDGE_BLEND * (color[yy, xx, 2] - b)
                        if four:
                            ma += EDGE_BLEND * (color[yy, xx, 3] - a)
            if blend:
                if ma <= 0.0:
                    continue
                mr = ma * mr + (1.0 - ma) * out_color[y, x, 0]
                mg = ma * mg + (1.0 - ma) * out_color[y, x, 1]
                mb = ma * mb + (1.0 - ma) * out_color[y, x, 2]
                out_depth[y, x] = min(out_depth[y, x], z)
            elif four:
                out_color[y, x, 3] = ma
            out_color[y, x, 0], out_color[y, x, 1], out_color[y, x, 2] = mr, mg, mb
            if rgb8:  # from the float32 colours, as to_rgb8 of the frame
                out_rgb[y, x, 0] = _to_8bit(out_color[y, x, 0])
                out_rgb[y, x, 1] = _to_8bit(out_color[y, x, 1])
                out_rgb[y, x, 2] = _to_8bit(out_color[y, x, 2])


@njit(cache=True, error_model="numpy", inline="always")
def _to_8bit(v):
    """A colour in [0, 1] (clipped) -> ``uint8``, rounded half up (as ``to_rgb8``; a copy
    of ``_resolve._u8``: numba caches a kernel by its own file, so a helper inlined from
    another file would not recompile it when changed)."""
    return np.uint8(min(max(np.float64(v), 0.0), 1.0) * 255.0 + 0.5)


@njit(parallel=True, cache=True, error_model="numpy", nogil=True)
def apply_texture(color, depth, texture):
    """:func:`_texture_rows` over a whole ``(H, W)`` frame, in place (OpenGL path);
    ``texture``: ``(T, U) uint32`` from :func:`pack_texture`."""
    rows = 8
    h = depth.shape[0]
    for i in prange((h + rows - 1) // rows):
        _texture_rows(color, depth, texture, i * rows, min(h, (i + 1) * rows))
    return color


@njit(cache=True, error_model="numpy", inline="always")
def _band_rows(band, bands, height, unit):
    """Rows ``[y_lo, y_hi)`` of band ``band`` of ``bands``, bounds on multiples of ``unit``."""
    y_lo = band * (height // unit) // bands * unit
    y_hi = (band + 1) * (height // unit) // bands * unit if band < bands - 1 else height
    return y_lo, y_hi


@njit(cache=True, error_model="numpy", inline="always")
def _inner_rows(y_lo, y_hi, height):
    """Rows ``[lo, hi)`` of the band ``[y_lo, y_hi)`` whose row neighbours lie in the band
    or outside the image (``lo >= hi``: none)."""
    return (y_lo if y_lo == 0 else y_lo + 1), (y_hi if y_hi == height else y_hi - 1)


@njit(parallel=True, cache=True, error_model="numpy", nogil=True, fastmath=FASTMATH)
def raster_frame(sv, col, scale, faces, n_first, bounds, block, xsv, xcol, xfaces, height,
                 width, bands, background, count, color, depth, mask, factor, out_color, out_cov,
                 out_depth, texture, smooth, rgb, alpha, xalpha, blend):
    """Z-buffer render of ``faces`` over ``sv`` and ``xfaces`` over ``xsv``, in
    ``bands`` horizontal bands rendered in parallel; returns ``(color, depth, mask)``.

    ``sv``: ``(N, 3) float32`` screen vertices ``(x, y, 1 / z)``, ``faces``: ``(M, 3)
    int32``; ``xsv``, ``xfaces``: the triangles clipped at the near plane. ``col``:
    ``(N, 3)`` vertex colours (times ``scale`` in [0, 1]); ``xcol``: ``(K, 3)
    float32`` colours of ``xsv``. ``count``: ``(H, W) int32`` coverage counter
    (tests), or ``(0, 0)`` for none. ``color (H, W, 3) float32``,
    ``depth (H, W) float32`` and ``mask (H, W) bool`` receive the image (every
    element is written; callers reuse them across frames). With ``factor > 1`` each
    band is resolved as it finishes (:func:`_resolve_rows`, bands aligned to
    ``factor``) into ``out_color``, ``out_cov`` and ``out_depth`` at ``1 / factor``
    the size, while the samples are still in cache, and ``mask`` and the background
    are left unwritten; ``factor = 1`` copies them there, with ``smooth > 0``
    blending colours across depth edges (:func:`_finish_rows`): each band its rows
    whose neighbours it drew, the first and last row of each band once all are drawn;
    ``factor = 0``: no resolve. ``texture``: ``(T, U) uint32`` (:func:`pack_texture`)
    when ``col`` holds texture coordinates (deferred texturing per band, see :func:`_texture_rows`),
    ``(0, 0, 3)`` for vertex colours. ``rgb``: with ``factor = 1``, an ``(H, W, 3)
    uint8`` array that receives the colours in 8 bits too (one pass less for a
    video frame), or ``(0, 0, 3)``. ``alpha``, ``xalpha``: ``(N,)`` and ``(K,)
    float32`` vertex coverage of ``sv`` and ``xsv`` (the soft silhouettes' fringe),
    written as a fourth channel of ``color`` (and of ``out_color``; 0 where nothing
    is covered), each sample taking the colour and alpha of its triangle's corner of
    largest barycentric weight (:func:`_nearest`: one colour and alpha per corner's
    cell), or ``(0,)`` for none. ``blend`` (with ``factor = 1`` and ``alpha``):
    blend the result over the frame ``out_color``, ``out_depth`` and ``rgb`` hold
    instead of writing them (see :func:`_finish_rows`).

    ``faces[:n_first]`` are drawn first; later faces and blocks (``bounds`` from
    :func:`block_bounds`) are skipped when they lie behind the farthest depth drawn
    so far in every 8x8 tile they touch (hierarchical z: the image is the same, only
    work is saved). Blocks outside a band are skipped whole.

    Example:
        >>> sv = np.array([[0, 0, 0.5], [4, 0, 0.5], [0, 4, 0.5]], np.float32)
        >>> faces, empty = np.array([[0, 1, 2]], np.int32), np.zeros((0, 3), np.int32)
        >>> bounds = block_bounds(sv, *block_vertices(faces, 64))
        >>> color, depth = np.zeros((4, 4, 3), np.float32), np.zeros((4, 4), np.float32)
        >>> mask, none = np.zeros((4, 4), np.bool_), np.zeros((0, 0), np.float32)
        >>> _, depth, mask = raster_frame(
        ...     sv, np.ones((3, 3), np.float32), 1.0, faces, 1, bounds, 64,
        ...     np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), empty, 4, 4, 2,
        ...     np.zeros(3, np.float32), np.zeros((0, 0), np.int32), color, depth, mask, 0,
        ...     np.zeros((0, 0, 3), np.float32), none, none, np.zeros((0, 0), np.uint32),
        ...     0.0, np.zeros((0, 0, 3), np.uint8), np.zeros(0, np.float32),
        ...     np.zeros(0, np.float32), False)
        >>> mask.astype(int)
        array([[1, 1, 1, 0],
               [1, 1, 0, 0],
               [1, 0, 0, 0],
               [0, 0, 0, 0]])
        >>> float(depth[0, 0])
        2.0
    """
    tile = 8
    cull = count.shape[0] == 0  # the coverage counter must see every face
    uv = texture.shape[0] > 0
    four = color.shape[2] == 4
    unit = max(factor, 1)  # band boundaries on multiples of the resolve factor
    for i in prange(bands):
        # interleave so each thread gets bands from all over the image (prange hands
        # out contiguous index ranges; scenes are often busier at the top or bottom)
        band = (i % 2) * ((bands + 1) // 2) + i // 2
        y_lo, y_hi = _band_rows(band, bands, height, unit)
        for y in range(y_lo, y_hi):
            for x in range(width):
                depth[y, x] = np.inf
        nty = (y_hi - y_lo + tile - 1) // tile
        ntx = (width + tile - 1) // tile
        tile_max = np.full((max(nty, 1), ntx), np.inf, np.float32)
        use_tiles = False
        tiles_done = False
        for b in range((faces.shape[0] + block - 1) // block):
            t0 = b * block
            if t0 >= n_first and not tiles_done:
                tiles_done = True
                # first group done: farthest depth per tile, for culling the rest
                tile_max[:] = 0.0
                for y in range(y_lo, y_hi):
                    ty = (y - y_lo) // tile
                    for x in range(width):
                        if depth[y, x] > tile_max[ty, x // tile]:
                            tile_max[ty, x // tile] = depth[y, x]
                use_tiles = cull
            if cull and _block_skipped(bounds, b, y_lo, y_hi, width, tile_max, tile, use_tiles):
                continue
            for t in range(t0, min(t0 + block, faces.shape[0])):
                i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
                if use_tiles and _occluded(sv, i0, i1, i2, y_lo, y_hi, width, tile_max, tile):
                    continue
                _draw(sv, col, scale, i0, i1, i2, y_lo, y_hi, width, color, depth, count, uv,
                      alpha)
        for t in range(xfaces.shape[0]):
            i0, i1, i2 = xfaces[t, 0], xfaces[t, 1], xfaces[t, 2]
            _draw_clipped(xsv, xcol, i0, i1, i2, y_lo, y_hi, width, color, depth, count, uv,
                          xalpha)
        if texture.shape[0] > 0:
            _texture_rows(color, depth, texture, y_lo, y_hi)
        if factor == 1:  # the rows whose neighbours are all in this band
            lo, hi = _inner_rows(y_lo, y_hi, height)
            _finish_rows(color, depth, smooth, lo, hi, out_color, out_cov, out_depth, rgb, blend)
        elif factor > 1:
            _resolve_rows(color, depth, factor, y_lo // factor, y_hi // factor, out_color,
                          out_cov, out_depth)
        else:
            for y in range(y_lo, y_hi):
                for x in range(width):
                    hit = depth[y, x] < np.inf
                    mask[y, x] = hit
                    if not hit:  # colour is only written where a triangle wins
                        for ch in range(3):
                            color[y, x, ch] = background[ch]
                        if four:
                            color[y, x, 3] = 0.0
    if factor == 1:  # the first and last row of each band, once every band is drawn
        for band in range(bands):
            y_lo, y_hi = _band_rows(band, bands, height, unit)
            lo, hi = _inner_rows(y_lo, y_hi, height)
            _finish_rows(color, depth, smooth, y_lo, lo, out_color, out_cov, out_depth, rgb,
                         blend)
            _finish_rows(color, depth, smooth, max(hi, lo), y_hi, out_color, out_cov, out_depth,
                         rgb, blend)
    return color, depth, mask


