"""The adaptive splats' blocks: a quadtree over each layer of an LDI that joins
linked 2 x 2 blocks where the colour is flat and the surface planar, and the
Gaussian that covers a block on its plane (used by :mod:`photo3d.export.splats`).

A block of level ``L`` is ``2**L`` pixels on a side, anchored at its top-left pixel,
whose lattice position (border included) is a multiple of ``2**L``. Four blocks of
level ``L - 1`` become one when their anchors are linked as a square (walking the
LDI's links ``2**(L - 1)`` steps right and down: all four on one layer, no depth
edge between them) and the union is

* flat in colour: every channel's range over the block's pixels within
  ``color_tolerance`` (sRGB, [0, 1]);
* planar: the four sub-blocks' inverse depths (affine in the image for a plane) fit
  a plane within ``depth_tolerance`` of the block's inverse depth (the bilinear
  twist ``|d00 + d11 - d01 - d10|``), and so do each sub-block's own slopes (a fold
  inside the block is not planar).

The joined block's splat sits at its pixels' mean 3D point with their mean colour,
and spans the block on its plane: its two long axes are the block's sides in 3D
(the slope measured between the sub-blocks), so a block on a slanted floor is an
anisotropic, tilted Gaussian, one facing the camera a disc.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d.structures.ldi import LDI

_RIGHT, _DOWN = 1, 3


@dataclass(frozen=True)
class Blocks:
    """The blocks a quadtree left: one per splat.

    Attributes:
        pixel: ``(M,) int64`` the anchor pixel (LDI index) of each block.
        level: ``(M,) int8`` its level: a side of ``2**level`` pixels.
        positions: ``(M, 3) float32`` mean 3D point of its pixels (camera axes).
        colors: ``(M, 3) float32`` mean colour.
        opacity: ``(M,) float32`` mean opacity.
        axis_u: ``(M, 3) float32`` the 3D step of one pixel to the right on the
            block's plane (zero for single pixels: unknown).
        axis_v: ``(M, 3) float32`` the same, one pixel down.
    """

    pixel: np.ndarray
    level: np.ndarray
    positions: np.ndarray
    colors: np.ndarray
    opacity: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray


def merge_blocks(ldi: LDI, positions: np.ndarray, colors: np.ndarray,
                 opacity: np.ndarray, *, levels: int, color_tolerance: float | np.ndarray,
                 depth_tolerance: float) -> Blocks:
    """The quadtree of ``ldi`` (see the module doc), ``levels`` rounds at most.

    Args:
        ldi: the layered depth image (lattice positions and links).
        positions: ``(N, 3)`` each LDI pixel's 3D point (camera axes).
        colors: ``(N, 3)`` each pixel's colour, sRGB in [0, 1].
        opacity: ``(N,)`` each pixel's opacity.
        levels: largest level (``levels = 4``: blocks up to 16 x 16 pixels).
        color_tolerance: largest colour range in a block, per channel: one for all,
            or ``(N,)`` one per pixel (a block takes its pixels' smallest).
        depth_tolerance: largest departure from a plane, relative (of inverse depth).

    Returns:
        :class:`Blocks`, those of level 0 being single pixels.

    Example:
        >>> import numpy as np
        >>> from photo3d.stages.ldi import from_image
        >>> from photo3d.camera import unproject
        >>> ldi = from_image(np.full((8, 8, 3), 0.5, np.float32), np.ones((8, 8), np.float32))
        >>> p = unproject(ldi.x, ldi.y, ldi.depth(), ldi.intrinsics)
        >>> b = merge_blocks(ldi, p, ldi.color, np.ones(ldi.size), levels=3,
        ...                  color_tolerance=0.01, depth_tolerance=0.01)
        >>> len(b.pixel) < ldi.size, int(b.level.max()) >= 2
        (True, True)
    """
    n = ldi.size
    links = ldi.links
    b = ldi.border
    level_of = np.zeros(n, np.int8)  # level of the block a pixel anchors; -1: absorbed
    pos = np.array(positions, np.float32)
    col = np.array(colors, np.float32)
    alpha = np.array(opacity, np.float32)
    lo_c, hi_c = col.copy(), col.copy()
    tolerance = np.broadcast_to(np.asarray(color_tolerance, np.float32), (n,)).copy()
    disp = 1.0 / pos[:, 2]
    slope = np.zeros((n, 2), np.float32)  # inverse depth per pixel, right and down
    axis_u = np.zeros((n, 3), np.float32)
    axis_v = np.zeros((n, 3), np.float32)
    p = np.flatnonzero(((ldi.y + b) % 2 == 0) & ((ldi.x + b) % 2 == 0))
    for level in range(1, levels + 1):
        step, side = 1 << (level - 1), 1 << level
        p = p[(level_of[p] == level - 1) & ((ldi.y[p] + b) % side == 0)
              & ((ldi.x[p] + b) % side == 0)]
        q = _walk(links, p, _RIGHT, step)
        r = _walk(links, p, _DOWN, step)
        s = _walk(links, q, _DOWN, step)
        ok = (q >= 0) & (r >= 0) & (s >= 0)
        p, q, r, s = p[ok], q[ok], r[ok], s[ok]
        ok = ((_walk(links, r, _RIGHT, step) == s) & (level_of[q] == level - 1)
              & (level_of[r] == level - 1) & (level_of[s] == level - 1))
        quad = np.stack([p[ok], q[ok], r[ok], s[ok]])
        hi, lo, tol = _max4(hi_c[quad]), -_max4(-lo_c[quad]), -_max4(-tolerance[quad])
        flat = (hi - lo).max(axis=1) <= tol
        quad, hi, lo, tol = quad[:, flat], hi[flat], lo[flat], tol[flat]
        d = disp[quad]
        limit = depth_tolerance * _mean4(d)
        du = (d[1] + d[3] - d[0] - d[2]) / (2 * step)  # the block's slope, per pixel
        dv = (d[2] + d[3] - d[0] - d[1]) / (2 * step)
        planar = np.abs(d[0] + d[3] - d[1] - d[2]) <= limit
        if level > 1:  # the sub-blocks' own slopes agree with the block's
            sub = slope[quad]
            planar &= (_max4(np.abs(sub[..., 0] - du)) * side <= limit) & (
                _max4(np.abs(sub[..., 1] - dv)) * side <= limit)
        quad, d = quad[:, planar], d[:, planar]
        if quad.shape[1] == 0:
            break
        a = quad[0]
        c0, c1, c2, c3 = pos[quad]
        axis_u[a] = (c1 + c3 - c0 - c2) * np.float32(0.5 / step)
        axis_v[a] = (c2 + c3 - c0 - c1) * np.float32(0.5 / step)
        pos[a] = (c0 + c1 + c2 + c3) * np.float32(0.25)
        disp[a] = _mean4(d)
        col[a] = _mean4(col[quad])
        alpha[a] = _mean4(alpha[quad])
        lo_c[a], hi_c[a], tolerance[a] = lo[planar], hi[planar], tol[planar]
        slope[a, 0], slope[a, 1] = du[planar], dv[planar]
        level_of[quad[1:].ravel()] = -1
        level_of[a] = level
        p = a
    keep = np.flatnonzero(level_of >= 0)
    return Blocks(pixel=keep, level=level_of[keep], positions=pos[keep], colors=col[keep],
                  opacity=alpha[keep], axis_u=axis_u[keep], axis_v=axis_v[keep])


def block_gaussians(axis_u: np.ndarray, axis_v: np.ndarray, *, thickness: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Scales and rotations of Gaussians spanning ``axis_u`` and ``axis_v``.

    The covariance is ``A A^T`` with ``A = [axis_u axis_v]`` (the two sides of a block
    scaled to standard deviations), plus a third axis along their normal
    ``thickness`` times the mean of the other two.

    Args:
        axis_u: ``(M, 3)`` first side (camera axes), not parallel to ``axis_v``.
        axis_v: ``(M, 3)`` second side.
        thickness: the third axis relative to the other two.

    Returns:
        ``(scales (M, 3) float32, rotations (M, 4) float32 w x y z)``: the Gaussian's
        standard deviations along its own axes and the unit quaternion turning its
        axes into camera axes.

    Example:
        >>> s, q = block_gaussians(np.array([[2.0, 0, 0]]), np.array([[0, 1.0, 1.0]]),
        ...                        thickness=0.1)
        >>> s.astype(float).round(3).tolist()
        [[2.0, 1.414, 0.171]]
        >>> q.astype(float).round(3).tolist()  # turned 45 degrees about x
        [[0.924, 0.383, 0.0, 0.0]]
    """
    u_, v_ = np.asarray(axis_u, np.float64), np.asarray(axis_v, np.float64)
    # the 2 x 2 Gram matrix [[e, f], [f, g]] of the sides: its eigenvectors turn
    # them into the covariance's principal axes (a closed-form SVD)
    e, f, g = (u_ * u_).sum(1), (u_ * v_).sum(1), (v_ * v_).sum(1)
    angle = 0.5 * np.arctan2(2 * f, e - g)
    cos, sin = np.cos(angle)[:, None], np.sin(angle)[:, None]
    first, second = cos * u_ + sin * v_, cos * v_ - sin * u_  # orthogonal
    sigma = np.stack([np.linalg.norm(first, axis=1), np.linalg.norm(second, axis=1)], 1)
    rotation = np.empty((len(u_), 3, 3))
    rotation[:, :, 0] = first / np.maximum(sigma[:, :1], 1e-30)
    rotation[:, :, 1] = second / np.maximum(sigma[:, 1:], 1e-30)
    rotation[:, :, 2] = np.cross(rotation[:, :, 0], rotation[:, :, 1])  # right-handed
    scales = np.empty((len(u_), 3), np.float32)
    scales[:, :2] = sigma
    scales[:, 2] = thickness * sigma.mean(axis=1)
    return np.maximum(scales, 1e-9), quaternions(rotation)


def quaternions(matrices: np.ndarray) -> np.ndarray:
    """``(M, 4) float32`` unit quaternions ``(w, x, y, z)`` of rotation matrices
    ``(M, 3, 3)``, ``w >= 0``.

    Example:
        >>> quaternions(np.eye(3)[None]).tolist()
        [[1.0, 0.0, 0.0, 0.0]]
    """
    m = matrices
    t = np.stack([1 + m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2],
                  1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2],
                  1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2],
                  1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2]], axis=1)
    best = t.argmax(axis=1)  # the largest component, computed from the trace
    q = np.empty((len(m), 4))
    # every row of the four below holds 4 * the largest component times each
    rows = [
        [t[:, 0], m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]],
        [m[:, 2, 1] - m[:, 1, 2], t[:, 1], m[:, 1, 0] + m[:, 0, 1], m[:, 0, 2] + m[:, 2, 0]],
        [m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] + m[:, 0, 1], t[:, 2], m[:, 2, 1] + m[:, 1, 2]],
        [m[:, 1, 0] - m[:, 0, 1], m[:, 0, 2] + m[:, 2, 0], m[:, 2, 1] + m[:, 1, 2], t[:, 3]],
    ]
    for i in range(4):
        here = best == i
        q[here] = np.stack([c[here] for c in rows[i]], axis=1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.astype(np.float32)


def _max4(values: np.ndarray) -> np.ndarray:
    """The largest of ``values[0..3]`` (faster than ``max(axis=0)``)."""
    return np.maximum(np.maximum(values[0], values[1]), np.maximum(values[2], values[3]))


def _mean4(values: np.ndarray) -> np.ndarray:
    """The mean of ``values[0..3]``."""
    return (values[0] + values[1] + values[2] + values[3]) * np.float32(0.25)


def _walk(links: np.ndarray, start: np.ndarray, direction: int, steps: int) -> np.ndarray:
    """The pixels ``steps`` links from ``start`` in ``direction`` (-1 where a link
    is missing)."""
    at = start.copy()
    for _ in range(steps):
        good = at >= 0
        at[good] = links[at[good], direction]
    return at
