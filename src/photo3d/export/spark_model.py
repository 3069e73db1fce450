"""Spark's image of a set of splats as a linear operator on their colours.

With the splats' centres, sizes, opacities and the depth order fixed, a splat
renderer's image is linear in the colours: pixel ``p`` shows
``sum_i colour_i * alpha_i(p) * T_i(p)``, ``T_i(p)`` the transmittance of the splats
in front of ``i``. :func:`spark_weights` builds those weights as a sparse matrix for
one camera, the way Spark 2.2 (``@sparkjsdev/spark``, its default settings, as
tests/export/spark_renderer.py runs it) draws them:

* what Spark keeps of a splat file: centres as float16 (once as read, once more
  relative to the camera in its accumulator), log scales in 8 bits over [-12, 9],
  opacity and colour in 8 bits, rotations as an 8-bit octahedral axis and an
  8-bit angle (:func:`spark_quantized`);
* the 2D covariance ``J W S R R^T S^T W^T J^T`` of the splat's centre, widened by
  :data:`BLUR` px² on the diagonal, its peak opacity lowered by
  ``sqrt(det before / det after)`` (Spark's ``blurAmount`` and its compensation);
* the Gaussian cut at a Mahalanobis distance² of :data:`CUTOFF2` (``maxStdDev``
  sqrt(8)) and where the opacity falls under :data:`MIN_ALPHA`; splats behind the
  camera, outside the near/far planes or beyond :data:`CLIP_XY` of the frustum
  dropped;
* pixel centres at ``(column + 0.5, row + 0.5)``, the principal point at the
  image's centre, one focal length (three.js's vertical field of view);
* sorted by distance from the camera (Spark's radial sort), blended back to front
  with premultiplied alpha over nothing.

What it leaves out is Spark's 8-bit framebuffer (each blend rounds to 1/255).
"""

from __future__ import annotations

import numpy as np

from photo3d.camera import Camera
from photo3d.structures.splats import Splats

BLUR = 0.3
"""Spark's ``blurAmount``: px² added to the 2D covariance's diagonal."""
CUTOFF2 = 8.0
"""Spark's ``maxStdDev`` squared: the Gaussian ends at this Mahalanobis distance²."""
MIN_ALPHA = 0.5 / 255
"""Spark's ``minAlpha``: fragments (and splats) with less opacity are discarded."""
CLIP_XY = 1.4
"""Spark's ``clipXY``: splats whose centre lies beyond this many half-frustums are
dropped."""
NEAR, FAR = 0.01, 1000.0
"""The near and far planes of the test page's three.js camera."""
LN_SCALE = (-12.0, 9.0)
"""The range of Spark's 8-bit log scales."""
WEIGHT_FLOOR = 1e-4
"""Weights below this are left out of the operator (at most a few 1/255 per pixel
altogether)."""


def _half(x: np.ndarray) -> np.ndarray:
    """float16 rounding (to nearest), back as float64."""
    return np.asarray(x, np.float64).astype(np.float16).astype(np.float64)


def _quat_octahedral(q: np.ndarray) -> np.ndarray:
    """``(M, 4)`` w x y z quaternions as Spark's packed splats keep them (its
    ``encodeQuatOctXy88R8`` then ``decodeQuatOctXy88R8``)."""
    q = np.where(q[:, :1] < 0, -q, q).astype(np.float64)
    w = np.clip(q[:, 0], -1, 1)
    theta = 2 * np.arccos(w)
    s = np.sin(theta / 2)
    small = np.abs(s) < 1e-6
    axis = np.where(small[:, None], [1.0, 0.0, 0.0], q[:, 1:] / np.where(small, 1, s)[:, None])
    total = np.abs(axis).sum(1)
    px, py = axis[:, 0] / total, axis[:, 1] / total
    neg = axis[:, 2] < 0
    fx = np.where(neg, (1 - np.abs(py)) * np.where(px >= 0, 1, -1), px)
    fy = np.where(neg, (1 - np.abs(px)) * np.where(py >= 0, 1, -1), py)
    qu = np.clip(np.round((fx * 0.5 + 0.5) * 255), 0, 255) / 255 * 2 - 1
    qv = np.clip(np.round((fy * 0.5 + 0.5) * 255), 0, 255) / 255 * 2 - 1
    angle = np.clip(np.round(theta / np.pi * 255), 0, 255) / 255 * np.pi
    a = np.stack([qu, qv, 1 - np.abs(qu) - np.abs(qv)], 1)
    t = np.maximum(-a[:, 2], 0)
    a[:, 0] += np.where(a[:, 0] >= 0, -t, t)
    a[:, 1] += np.where(a[:, 1] >= 0, -t, t)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    return np.concatenate([np.cos(angle / 2)[:, None], a * np.sin(angle / 2)[:, None]], 1)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of ``(M, 4)`` (or ``(4,)``) w x y z quaternions."""
    aw, ax, ay, az = np.moveaxis(np.broadcast_to(a, np.broadcast_shapes(a.shape, b.shape)), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.broadcast_to(b, np.broadcast_shapes(a.shape, b.shape)), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], -1)


_FLIP_Q = np.array([0.0, 1.0, 0.0, 0.0])  # 180 degrees about x: OpenCV <-> three.js


def spark_quantized(splats: Splats, camera: Camera) -> Splats:
    """``splats`` (OpenCV axes) as Spark draws them from ``camera``: every value
    rounded as its packed splats and its accumulator keep it (see the module doc);
    float64, still OpenCV axes."""
    positions, colors, opacity, scales, rotations = splats.checked()
    origin = camera.position
    # as read (file axes = OpenCV), then relative to the view origin in three.js axes
    # (a sign change of y and z, which float16 rounding commutes with)
    centres = _half(_half(positions) - origin) + origin
    lo, hi = LN_SCALE
    step = (hi - lo) / 254
    code = np.clip(np.round((np.log(np.maximum(scales, 1e-30)) - lo) / step), 0, 254)
    scales = np.exp(lo + code * step)
    alpha = np.round(np.clip(opacity, 0, 1) * 255) / 255
    alpha = np.round(alpha / 2 * 255) / 255 * 2  # the accumulator keeps alpha / 2
    colors = np.round(np.clip(colors, 0, 1) * 255) / 255
    # most splats (the one-pixel discs) are not rotated: those are rounded once
    rotations = np.asarray(rotations, np.float64)
    turned = (rotations[:, 1:] != 0).any(1) | (rotations[:, 0] != 1)
    q = np.empty_like(rotations)
    for rows, given in ((turned, rotations[turned]), (~turned, np.array([[1.0, 0, 0, 0]]))):
        r = _quat_octahedral(given)
        q[rows] = _quat_mul(_FLIP_Q, _quat_octahedral(_quat_mul(_FLIP_Q, r)))  # three.js axes
    return Splats(centres, colors, alpha, scales, q)


def projected(splats: Splats, camera: Camera) -> tuple[np.ndarray, ...]:
    """The splats on ``camera``'s image as Spark places them.

    Returns:
        ``(u, v, cov2d, alpha, distance)``: centres in pixels ``(N,)`` each (x right,
        y down, pixel centres at +0.5), ``(N, 3)`` the widened 2D covariance
        ``(a, b, d)`` in px², ``(N,)`` peak opacity after Spark's compensation
        (0 for a dropped splat), ``(N,)`` distance from the camera (the sort key).
    """
    from photo3d.export._spark_raster import project

    k = camera.intrinsics
    f = 0.5 * k.height / np.tan(0.5 * k.fov[1])
    rot = np.ascontiguousarray(camera.pose[:3, :3], np.float64)
    t = np.ascontiguousarray(camera.pose[:3, 3], np.float64)
    u, v, cov, comp, distance = project(
        np.ascontiguousarray(splats.positions, np.float64),
        np.ascontiguousarray(splats.scales, np.float64),
        np.ascontiguousarray(splats.rotations, np.float64), rot, t, f, k.width, k.height,
        BLUR)
    z = np.asarray(splats.positions, np.float64) @ rot[2] + t[2]
    alpha = np.asarray(splats.opacity, np.float64) * comp
    visible = ((z > NEAR) & (z < FAR) & (np.abs(u - k.width / 2) <= CLIP_XY * k.width / 2)
               & (np.abs(v - k.height / 2) <= CLIP_XY * k.height / 2) & (alpha >= MIN_ALPHA))
    return u, v, cov, np.where(visible, alpha, 0.0), distance


def spark_weights(splats: Splats, camera: Camera, *, quantize: bool = True):
    """The weights of Spark's image of ``splats`` from ``camera``: a
    ``scipy.sparse.csc_matrix`` of shape ``(H * W, N)`` (pixels row-major, row 0 at
    the top) with ``image = weights @ colors`` (premultiplied over nothing) and
    ``coverage = weights.sum(1)`` (the alpha channel).

    ``quantize``: round the splats as Spark keeps them (:func:`spark_quantized`)
    first.

    Example:
        >>> from photo3d.camera import Intrinsics
        >>> k = Intrinsics.default(8, 8)  # fx = 8: a pixel is 1/8 wide at z = 1
        >>> one = Splats(np.array([[0.0625, 0.0625, 1]]), np.full((1, 3), 0.5),
        ...              np.full(1, 0.99), np.full((1, 3), 0.6 / 8), np.array([[1.0, 0, 0, 0]]))
        >>> w = spark_weights(one, Camera(k, np.eye(4))).toarray().reshape(8, 8)
        >>> round(float(w[4, 4]), 2), round(float(w[4, 5]), 2)  # its pixel, the next
        (0.55, 0.26)
    """
    import scipy.sparse

    weights, order = visible_weights(splats, camera, quantize=quantize)
    n = len(splats)
    counts = np.zeros(n, np.int64)
    counts[order] = np.diff(weights.indptr)
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    first = np.zeros(n, np.int64)
    first[order] = weights.indptr[:-1]
    gather = np.repeat(first - indptr[:-1], counts) + np.arange(weights.nnz)
    return scipy.sparse.csc_matrix((weights.data[gather], weights.indices[gather], indptr),
                                   shape=(weights.shape[0], n))


def visible_weights(splats: Splats, camera: Camera, *, quantize: bool = True,
                    floor: float = WEIGHT_FLOOR):
    """:func:`spark_weights` of the splats Spark draws from ``camera`` only, in the
    order it blends them (front to back): ``(weights (H * W, M) csc_matrix float32,
    order (M,) int64)``, column ``j`` the splat ``order[j]`` (cheaper: no
    reordering). ``floor``: weights below it are left out (they still hide what
    lies behind)."""
    import scipy.sparse

    from photo3d.export._spark_raster import rasterize

    if quantize:
        splats = spark_quantized(splats, camera)
    k = camera.intrinsics
    u, v, cov, alpha, distance = projected(splats, camera)
    order = np.argsort(distance, kind="stable").astype(np.int64)  # front to back
    order = order[alpha[order] > 0]
    rows, vals, counts = rasterize(order, u, v, cov, alpha, k.width, k.height, CUTOFF2,
                                   MIN_ALPHA, floor)
    indptr = np.zeros(len(order) + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    weights = scipy.sparse.csc_matrix((vals, rows, indptr),
                                      shape=(k.width * k.height, len(order)))
    return weights, order
