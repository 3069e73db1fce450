"""The numba kernel of :mod:`photo3d.export.spark_model`: splats drawn front to back
into a transmittance buffer, each fragment's weight ``alpha * T`` recorded. Once a
pixel's transmittance ``T`` is under the floor no later fragment's weight can reach
it (``alpha <= 1``), so the pixel is skipped from then on (on the bundled sample
most of the hidden layers' fragments)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _footprint(u, v, a, b, d, width, height, cutoff2):
    """The pixel box of one splat's ellipse ``z2 <= cutoff2`` (clipped)."""
    rx = math.sqrt(cutoff2 * a)
    ry = math.sqrt(cutoff2 * d)
    x0 = max(0, int(math.ceil(u - rx - 0.5)))
    x1 = min(width - 1, int(math.floor(u + rx - 0.5)))
    y0 = max(0, int(math.ceil(v - ry - 0.5)))
    y1 = min(height - 1, int(math.floor(v + ry - 0.5)))
    return x0, x1, y0, y1


@njit(cache=True, nogil=True)
def _draw(order, u, v, cov, alpha, width, height, cutoff2, min_alpha, floor, capacity):
    trans = np.ones(width * height, np.float32)
    rows = np.empty(capacity, np.int32)
    vals = np.empty(capacity, np.float32)
    counts = np.zeros(len(order), np.int64)
    n = 0
    for k in range(len(order)):
        i = order[k]
        a, b, d = cov[i, 0], cov[i, 1], cov[i, 2]
        det = a * d - b * b
        qa, qb, qd = d / det, -2.0 * b / det, a / det  # z2 = qa dx² + qb dx dy + qd dy²
        # alpha exp(-z2 / 2) >= min_alpha only where z2 <= -2 ln(min_alpha / alpha)
        reach = min(cutoff2, -2.0 * math.log(min_alpha / alpha[i])) if alpha[i] > 0 else -1.0
        x0, x1, y0, y1 = _footprint(u[i], v[i], a, b, d, width, height, cutoff2)
        if n + (x1 - x0 + 1) * (y1 - y0 + 1) > len(rows):  # grow by half at least
            size = max(len(rows) * 3 // 2, n + (x1 - x0 + 1) * (y1 - y0 + 1))
            more_rows = np.empty(size, np.int32)
            more_vals = np.empty(size, np.float32)
            more_rows[:n] = rows[:n]
            more_vals[:n] = vals[:n]
            rows, vals = more_rows, more_vals
        start = n
        peak = np.float32(alpha[i])
        for y in range(y0, y1 + 1):
            dy = y + 0.5 - v[i]
            line = y * width
            for x in range(x0, x1 + 1):
                p = line + x
                if trans[p] < floor:  # no weight here reaches the floor any more (<= T)
                    continue
                dx = x + 0.5 - u[i]
                z2 = (qa * dx + qb * dy) * dx + qd * dy * dy
                if z2 > reach:
                    continue
                al = peak * math.exp(np.float32(-0.5 * z2))
                if al < min_alpha:
                    continue
                w = al * trans[p]
                trans[p] *= np.float32(1.0) - al
                if w >= floor:
                    rows[n] = p
                    vals[n] = w
                    n += 1
        counts[k] = n - start
    return rows[:n], vals[:n], counts  # views: the unused tail was never touched


def rasterize(order: np.ndarray, u: np.ndarray, v: np.ndarray, cov: np.ndarray,
              alpha: np.ndarray, width: int, height: int, cutoff2: float,
              min_alpha: float, floor: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fragments of the splats ``order`` (front to back) with a weight of at least
    ``floor``, grouped by splat in that order: ``(pixel (K,) int32, weight (K,)
    float32, count (len(order),) int64)``."""
    return _draw(order, u, v, cov, alpha, width, height, cutoff2, min_alpha, floor,
                 24 * len(order) + 1024)  # 21 per splat on the sample (floor 3e-3)


@njit(cache=True, nogil=True)
def project(positions, scales, rotations, rot, t, f, width, height, blur):
    """Each splat on the image as Spark places it: ``(u, v, cov (N, 3) a b d,
    compensation, distance)``; ``z <= 0`` gives ``compensation = 0``
    (:func:`photo3d.export.spark_model.projected` documents the rest)."""
    n = len(positions)
    u = np.zeros(n)
    v = np.zeros(n)
    cov = np.ones((n, 3))
    comp = np.zeros(n)
    dist = np.zeros(n)
    r = np.empty((3, 3))
    m = np.empty((3, 3))
    for i in range(n):
        wx, wy, wz = positions[i, 0], positions[i, 1], positions[i, 2]
        p0 = rot[0, 0] * wx + rot[0, 1] * wy + rot[0, 2] * wz + t[0]
        p1 = rot[1, 0] * wx + rot[1, 1] * wy + rot[1, 2] * wz + t[1]
        p2 = rot[2, 0] * wx + rot[2, 1] * wy + rot[2, 2] * wz + t[2]
        dist[i] = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        if p2 <= 0.0:
            continue
        w, x, y, z = rotations[i, 0], rotations[i, 1], rotations[i, 2], rotations[i, 3]
        r[0, 0] = 1 - 2 * (y * y + z * z)
        r[0, 1] = 2 * (x * y - w * z)
        r[0, 2] = 2 * (x * z + w * y)
        r[1, 0] = 2 * (x * y + w * z)
        r[1, 1] = 1 - 2 * (x * x + z * z)
        r[1, 2] = 2 * (y * z - w * x)
        r[2, 0] = 2 * (x * z - w * y)
        r[2, 1] = 2 * (y * z + w * x)
        r[2, 2] = 1 - 2 * (x * x + y * y)
        # m = rot @ r @ diag(scales): the Gaussian's axes in camera axes
        for a in range(3):
            for b in range(3):
                m[a, b] = (rot[a, 0] * r[0, b] + rot[a, 1] * r[1, b]
                           + rot[a, 2] * r[2, b]) * scales[i, b]
        # J (2 x 3) @ m, J = [[f/z, 0, -f x/z²], [0, f/z, -f y/z²]]
        j00, j02, j12 = f / p2, -f * p0 / (p2 * p2), -f * p1 / (p2 * p2)
        a0 = j00 * m[0, 0] + j02 * m[2, 0]
        a1 = j00 * m[0, 1] + j02 * m[2, 1]
        a2 = j00 * m[0, 2] + j02 * m[2, 2]
        b0 = j00 * m[1, 0] + j12 * m[2, 0]
        b1 = j00 * m[1, 1] + j12 * m[2, 1]
        b2 = j00 * m[1, 2] + j12 * m[2, 2]
        ca = a0 * a0 + a1 * a1 + a2 * a2
        cb = a0 * b0 + a1 * b1 + a2 * b2
        cd = b0 * b0 + b1 * b1 + b2 * b2
        det0 = ca * cd - cb * cb
        ca += blur
        cd += blur
        det = ca * cd - cb * cb
        u[i] = width / 2 + f * p0 / p2
        v[i] = height / 2 + f * p1 / p2
        cov[i, 0], cov[i, 1], cov[i, 2] = ca, cb, cd
        comp[i] = math.sqrt(max(0.0, det0 / det))
    return u, v, cov, comp, dist
