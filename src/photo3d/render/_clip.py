"""Vertex stage of the rasterizer: transform, project, snap, clip at the near plane.

Screen vertices are rows of a ``(N, 3) float32`` array ``[u, v, 1/z]``:
``(u, v)`` image coordinates in pixels (pixel ``(y, x)`` has its centre at
``(x + 0.5, y + 0.5)``, see :mod:`photo3d.camera`), snapped to a ``1/SUBPIXEL`` grid so
that edge functions evaluated in float64 are exact near the image and a vertex placed
on a pixel centre lands exactly on it; ``z`` is camera depth. A vertex in front of
the near plane has ``1/z > 0``; one behind it is flagged with ``1/z = -1``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

SUBPIXEL = 256.0
"""Screen coordinates are multiples of ``1 / SUBPIXEL`` pixel (as GPUs do)."""

_LIMIT = 1e15  # |u|, |v| clamp: keeps absurd inputs finite


@njit(cache=True, error_model="numpy", inline="always")
def _snap(u: float) -> float:
    u = min(max(u, -_LIMIT), _LIMIT)
    return np.floor(u * SUBPIXEL + 0.5) * (1.0 / SUBPIXEL)


@njit(cache=True, error_model="numpy", inline="always")
def _camera(vertices, i, rot, trans):
    """World vertex ``i`` -> float64 camera coordinates ``(x, y, z)``."""
    x = np.float64(vertices[i, 0])
    y = np.float64(vertices[i, 1])
    z = np.float64(vertices[i, 2])
    cx = rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z + trans[0]
    cy = rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z + trans[1]
    cz = rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z + trans[2]
    return cx, cy, cz


@njit(cache=True, error_model="numpy", inline="always")
def _emit(out, j, x, y, z, k):
    """Write the screen vertex of camera point ``(x, y, z)`` to row ``j`` of ``out``."""
    iz = 1.0 / z
    out[j, 0] = _snap(k[0] * x * iz + k[2])
    out[j, 1] = _snap(k[1] * y * iz + k[3])
    out[j, 2] = iz


@njit(cache=True, error_model="numpy", nogil=True)  # serial: 0.4 ms, less than a fork
def project_vertices(vertices, rot, trans, k, near, sv):
    """Screen vertices of all world vertices.

    Args:
        vertices: ``(N, 3) float32`` world coordinates.
        rot, trans: ``(3, 3)``, ``(3,)`` float64 camera-from-world rotation, translation.
        k: ``(4,) float64`` ``fx, fy, cx, cy``.
        near: near-plane depth, > 0.
        sv: ``(N, 3) float32`` output, overwritten.

    Returns:
        ``(sv, n_behind, n_bad)``: ``(N, 3) float32`` screen vertices, the number of
        vertices behind the near plane and the number with non-finite coordinates.
    """
    n = vertices.shape[0]
    n_behind = 0
    n_bad = 0
    for i in range(n):
        x, y, z = _camera(vertices, i, rot, trans)
        finite = abs(x) < np.inf and abs(y) < np.inf and abs(z) < np.inf
        if finite and z >= near:
            _emit(sv, i, x, y, z, k)
        else:
            if finite:
                n_behind += 1
            else:
                n_bad += 1
            sv[i, 0] = 0.0
            sv[i, 1] = 0.0
            sv[i, 2] = -1.0
    return sv, n_behind, n_bad


@njit(cache=True, error_model="numpy", nogil=True)
def clip_near(sv, faces, vertices, colors, scale, rot, trans, k, near, alpha):
    """Clip the triangles that cross the near plane (Sutherland-Hodgman).

    A triangle with one vertex behind becomes a quad (two triangles), one with two
    behind a smaller triangle; triangles entirely behind are dropped. Kept vertices
    are copied from ``sv`` and each crossing edge is cut from its front end, so
    triangles sharing an edge share the new vertex bit for bit (no cracks).

    Args:
        sv: ``(N, 3) float32`` screen vertices from :func:`project_vertices`.
        faces: ``(M, 3) int32``; vertices, rot, trans, k, near as there.
        colors: ``(N, 3)`` float32 or uint8 vertex colours, times ``scale`` in [0, 1].
        alpha: ``(N,) float32`` vertex coverage, or ``(0,)`` for none.

    Returns:
        ``(xsv, xcol, xfaces, xalpha)``: ``(K, 3) float32`` new screen vertices, their
        ``(K, 3) float32`` colours in [0, 1], ``(F, 3) int32`` triangles over them and
        the ``(K,) float32`` coverage of the new vertices (interpolated like the
        colours; ``(0,)`` when ``alpha`` is). The nearest-corner coverage of a clipped
        triangle is then that of its pieces' corners: an approximation near the
        camera only.
    """
    has_alpha = alpha.shape[0] > 0
    m = faces.shape[0]
    n_cross = 0
    for t in range(m):
        nb = (sv[faces[t, 0], 2] < 0) + (sv[faces[t, 1], 2] < 0) + (sv[faces[t, 2], 2] < 0)
        if nb == 1 or nb == 2:
            n_cross += 1
    xsv = np.empty((4 * n_cross, 3), np.float32)
    xcol = np.empty((4 * n_cross, 3), np.float32)
    xfaces = np.empty((2 * n_cross, 3), np.int32)
    xalpha = np.empty(4 * n_cross if has_alpha else 0, np.float32)
    nv = 0
    nf = 0
    for t in range(m):
        nb = (sv[faces[t, 0], 2] < 0) + (sv[faces[t, 1], 2] < 0) + (sv[faces[t, 2], 2] < 0)
        if nb != 1 and nb != 2:
            continue
        start = nv
        for j in range(3):
            a = faces[t, j]
            b = faces[t, (j + 1) % 3]
            a_front = sv[a, 2] > 0
            if a_front:
                xsv[nv, :] = sv[a, :]
                for c in range(3):
                    xcol[nv, c] = colors[a, c] * scale
                if has_alpha:
                    xalpha[nv] = alpha[a]
                nv += 1
            if a_front != (sv[b, 2] > 0):
                f, h = (a, b) if a_front else (b, a)
                fx, fy, fz = _camera(vertices, f, rot, trans)
                hx, hy, hz = _camera(vertices, h, rot, trans)
                s = (near - fz) / (hz - fz)
                _emit(xsv, nv, fx + s * (hx - fx), fy + s * (hy - fy), near, k)
                for c in range(3):
                    cf = colors[f, c] * scale
                    xcol[nv, c] = cf + s * (colors[h, c] * scale - cf)
                if has_alpha:
                    xalpha[nv] = alpha[f] + s * (alpha[h] - alpha[f])
                nv += 1
        for j in range(nv - start - 2):
            xfaces[nf, 0] = start
            xfaces[nf, 1] = start + j + 1
            xfaces[nf, 2] = start + j + 2
            nf += 1
    return xsv[:nv], xcol[:nv], xfaces[:nf], xalpha[:nv if has_alpha else 0]
