"""Numba kernels of the CPU rasterizer (:mod:`photo3d.render.raster`).

Kernels inline their helpers: keep every helper in this file, or numba's on-disk
cache (keyed by the kernel file's timestamp) would not see a helper change.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, error_model="numpy", inline="always")
def _edge(sv, p, q):
    """Canonical edge ``p -> q``: origin, direction and the sign of ``p -> q``."""
    py, qy = np.float64(sv[p, 1]), np.float64(sv[q, 1])
    px, qx = np.float64(sv[p, 0]), np.float64(sv[q, 0])
    if py < qy or (py == qy and px <= qx):
        return px, py, qx - px, qy - py, 1.0
    return qx, qy, px - qx, py - qy, -1.0


@njit(cache=True, error_model="numpy", inline="always")
def _draw_float(sv, col, scale, i0, i1, i2, r0, r1, c0, c1, color, depth, count):
    """:func:`_draw` for huge screen coordinates, in float64 edge functions (exact
    for 1/256-snapped vertices) evaluated with each edge's end points in a canonical
    order; rows ``r0..r1`` and columns ``c0..c1`` are the clamped bounding box."""
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
                for ch in range(3):
                    v = (a0 * col[i0, ch] + a1 * col[i1, ch] + a2 * col[i2, ch]) / suma * scale
                    color[y, x, ch] = min(max(v, 0.0), 1.0)


@njit(cache=True, error_model="numpy", inline="always")
def _draw(sv, col, scale, i0, i1, i2, y_lo, y_hi, width, color, depth, count):
    """Rasterize triangle ``(i0, i1, i2)`` of ``sv`` into rows ``[y_lo, y_hi)``.

    Edge functions are exact integers on the 1/256 px grid the vertices are snapped
    to (24.8 fixed point), stepped incrementally along each row."""
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
        _draw_float(sv, col, scale, i0, i1, i2, r0, r1, c0, c1, color, depth, count)
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
    for y in range(r0, r1 + 1):
        py = np.int64(y) * 256 + 128
        w0 = dx0 * (py - Y1) - dy0 * (px0 - X1)
        w1 = dx1 * (py - Y2) - dy1 * (px0 - X2)
        w2 = dx2 * (py - Y0) - dy2 * (px0 - X0)
        s0, s1, s2 = dy0 * 256, dy1 * 256, dy2 * 256
        for x in range(c0, c1 + 1):
            if w0 >= 0 and w1 >= 0 and w2 >= 0:
                ok = True
                if (w0 == 0 and not tl0) or (w1 == 0 and not tl1) or (w2 == 0 and not tl2):
                    if (w0 == 0) + (w1 == 0) + (w2 == 0) < 2:
                        ok = False
                if ok:
                    if count.shape[0] > 0:
                        count[y, x] += 1
                    a0, a1, a2 = w0 * iz0, w1 * iz1, w2 * iz2
                    inv = 1.0 / (a0 + a1 + a2)
                    z = np.float32(farea * inv)
                    if z < depth[y, x]:
                        depth[y, x] = z
                        inv *= scale
                        for ch in range(3):
                            v = (a0 * col[i0, ch] + a1 * col[i1, ch] + a2 * col[i2, ch]) * inv
                            color[y, x, ch] = min(max(v, 0.0), 1.0)
            w0 -= s0
            w1 -= s1
            w2 -= s2


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


@njit(parallel=True, cache=True, error_model="numpy")
def _block_bounds(sv, faces, block):
    """Per block of ``block`` consecutive faces: screen ``ymin, ymax, xmin, xmax`` and
    the largest inverse depth; ``ymin = +inf`` marks a block with a vertex behind the
    near plane (never culled)."""
    nb = (faces.shape[0] + block - 1) // block
    out = np.empty((nb, 5), np.float64)
    for b in prange(nb):
        y0, y1, x0, x1, izmax = np.inf, -np.inf, np.inf, -np.inf, 0.0
        behind = False
        for t in range(b * block, min((b + 1) * block, faces.shape[0])):
            for j in range(3):
                v = faces[t, j]
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


@njit(parallel=True, cache=True, error_model="numpy")
def _raster(sv, col, scale, faces, n_first, bounds, block, xsv, xcol, xfaces, height, width,
            bands, background, count):
    """Z-buffer render of ``faces`` over ``sv`` and ``xfaces`` over ``xsv``.

    ``col``: ``(N, 3)`` vertex colours (times ``scale`` in [0, 1]); ``xcol``:
    ``(K, 3) float32`` colours of ``xsv``. ``count``: ``(H, W) int32`` coverage
    counter (tests), or ``(0, 0)`` for none. ``faces[:n_first]`` are drawn first;
    later faces and blocks
    (``bounds`` from :func:`_block_bounds`) are skipped when they lie behind the
    farthest depth drawn so far in every 8x8 tile they touch (hierarchical z: the
    image is the same, only work is saved). Blocks outside a band are skipped whole.
    """
    tile = 8
    color = np.empty((height, width, 3), np.float32)
    depth = np.empty((height, width), np.float32)
    mask = np.empty((height, width), np.bool_)
    cull = count.shape[0] == 0  # the coverage counter must see every face
    for i in prange(bands):
        # interleave so each thread gets bands from all over the image (prange hands
        # out contiguous index ranges; scenes are often busier at the top or bottom)
        band = (i % 2) * ((bands + 1) // 2) + i // 2
        y_lo = band * height // bands
        y_hi = (band + 1) * height // bands
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
                _draw(sv, col, scale, i0, i1, i2, y_lo, y_hi, width, color, depth, count)
        for t in range(xfaces.shape[0]):
            i0, i1, i2 = xfaces[t, 0], xfaces[t, 1], xfaces[t, 2]
            _draw(xsv, xcol, 1.0, i0, i1, i2, y_lo, y_hi, width, color, depth, count)
        for y in range(y_lo, y_hi):
            for x in range(width):
                hit = depth[y, x] < np.inf
                mask[y, x] = hit
                if not hit:  # colour is only written where a triangle wins
                    for ch in range(3):
                        color[y, x, ch] = background[ch]
    return color, depth, mask


