"""Splat colours fitted to photo3d's own render of the 3D photo, through Spark's
blend of all splats (``build_splats(ldi, fit=True)``; ``photo3d export`` fits by
default, ``--no-splat-fit`` does not).

Each splat of :mod:`photo3d.export.splats` takes its pixels' colour, but a splat
renderer blends every pixel's neighbours into it (Spark widens each splat by 0.3 px²
and halves a one-pixel splat's opacity), so the image comes out softer than photo3d's
render, most at the edges of texture. With the splats' centres, sizes, opacities and
depth order fixed the renderer's image is linear in their colours
(:func:`photo3d.export.spark_model.spark_weights`: ``image = W @ colors``), so the
colours that make Spark's view from the input camera closest to photo3d's render
``y`` of that camera are a least-squares problem:

    minimize ``|M (W c - y)|² + lam |c - c0|²``, ``0 <= c <= 1``

``M`` the pixels photo3d's render covers, ``c0`` the colours as built. The pull
``lam`` (:data:`REGULARIZATION`) toward ``c0`` keeps splats the input view barely
sees (behind others, at silhouettes) from taking extreme colours that other views
would show. :data:`ITERATIONS` rounds of conjugate gradients on the normal
equations (Jacobi-preconditioned, numba kernels in :mod:`._fit_kernels`), weights
under :data:`FLOOR` left out, then the colours are clipped to [0, 1]. ``y`` is
made from the LDI without rendering (:func:`input_view`).

Measured on the bundled sample (docs/outputs.md): Spark's view from the input
camera rises from 27.5 to 35.1 dB against photo3d's render, the circle path's
widest camera (not fitted) from 26.8 to 29.7 dB; 0.9 s of CPU more.
"""

from __future__ import annotations

import numpy as np

from photo3d.camera import Camera
from photo3d.structures.ldi import LDI
from photo3d.structures.splats import Splats

ITERATIONS = 4
"""Conjugate-gradient rounds (each two products with the sparse weights)."""
FLOOR = 3e-3
"""Weights below this are left out of the fit (a third of Spark's fragments on the
bundled sample, within 0.15 dB of the fit with all of them)."""
REGULARIZATION = 0.03
"""``lam``: the pull toward the colours as built, against squared pixel errors
(a one-pixel splat's weights have a squared sum of about 0.1 to 1)."""


SUPERSAMPLE_WEIGHT = 0.125
"""What a pixel of photo3d's render at the input camera takes from each of its four
neighbours' colours, per axis: its 2 x 2 supersamples lie a quarter pixel from the
centre, where the mesh interpolates between the pixel's vertex (3/4) and the
neighbour's (1/4), so the render is the photo filtered by ``[1/8, 3/4, 1/8]`` in
each direction (:func:`input_view`)."""


def input_view(ldi: LDI) -> tuple[np.ndarray, np.ndarray]:
    """photo3d's render of ``ldi`` from the input camera, made from the LDI without
    rendering: the photo's own pixels (label 1, the nearest at every position of
    the image) filtered as the render's supersampling filters them
    (:data:`SUPERSAMPLE_WEIGHT`). ``(color (H, W, 3) float32 in [0, 1], covered
    (H, W) bool)``, the pixels that hold one of the photo's own.

    It differs from :func:`reference_view` only where the render shows what lies
    behind a depth edge in the half pixel beyond it (on the bundled sample 40.7 dB
    apart, 5 % of the pixels holding 95 % of the difference), and takes 0.03 s
    instead of 0.5 s.

    Example:
        >>> import photo3d
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> color, covered = input_view(photo.ldi)
        >>> color.shape, bool(covered.all()), float(color[4, 4, 0])
        ((8, 8, 3), True, 0.5)
    """
    from photo3d.structures.ldi import LABEL_ORIGINAL

    h, w = ldi.height, ldi.width
    own = np.flatnonzero((ldi.label == LABEL_ORIGINAL) & (ldi.y >= 0) & (ldi.y < h)
                         & (ldi.x >= 0) & (ldi.x < w))
    at = ldi.y[own].astype(np.int64) * w + ldi.x[own]
    color = np.zeros((h * w, 3), np.float32)
    color[at] = ldi.color[own]
    covered = np.zeros(h * w, bool)
    covered[at] = True
    color, covered = color.reshape(h, w, 3), covered.reshape(h, w)
    a = np.float32(SUPERSAMPLE_WEIGHT)
    for axis in (0, 1):  # [a, 1 - 2a, a], the edge pixel repeated beyond the image
        padded = np.concatenate([color.take([0], axis), color, color.take([-1], axis)], axis)
        before, after = (padded.take(np.arange(i, i + color.shape[axis]), axis) for i in (0, 2))
        color = (1 - 2 * a) * color + a * (before + after)
    return np.clip(color, 0, 1), covered


def reference_view(ldi: LDI, camera: Camera | None = None) -> tuple[np.ndarray, np.ndarray]:
    """photo3d's own render of ``ldi`` (the full mesh, numba, no hole filling) from
    ``camera`` (None: the input camera): ``(color (H, W, 3) float32 in [0, 1],
    covered (H, W) bool)``, the reference the fit aims at."""
    from photo3d.config import Config
    from photo3d.photo import Photo3D
    from photo3d.render.renderer import Renderer, RenderSettings

    camera = Camera(ldi.intrinsics, np.eye(4)) if camera is None else camera
    with Renderer(Photo3D(ldi, Config()).mesh(),
                  RenderSettings(fill_holes=False, backend="numba")) as renderer:
        view = renderer.render(camera)
    return np.asarray(view.color, np.float32), np.asarray(view.mask, bool)


def fit_colors(splats: Splats, camera: Camera, color: np.ndarray, covered: np.ndarray, *,
               iterations: int = ITERATIONS, regularization: float = REGULARIZATION,
               floor: float = FLOOR) -> Splats:
    """``splats`` with colours fitted so that Spark's view from ``camera`` comes
    closest to ``color`` over ``covered`` (see the module doc).

    Args:
        splats: the splats (positions, sizes, opacities and rotations are kept).
        camera: the camera to fit (the input camera).
        color: ``(H, W, 3) float`` in [0, 1], the image to match (photo3d's render).
        covered: ``(H, W) bool``, the pixels that count.
        iterations: conjugate-gradient rounds.
        regularization: the pull toward the colours as built.
        floor: Spark's weights below this are left out of the fit.

    Returns:
        :class:`~photo3d.structures.splats.Splats`, colours in [0, 1]; splats the
        camera does not see keep theirs.
    """
    from dataclasses import replace

    from photo3d.export._fit_kernels import diagonal, gather, normal, render
    from photo3d.export.spark_model import visible_weights

    weights, order = visible_weights(splats, camera, floor=floor)  # (pixels, seen splats)
    indptr, rows, vals = weights.indptr, weights.indices, weights.data  # CSC
    mask = np.asarray(covered, np.float32).ravel()
    y = np.asarray(color, np.float32).reshape(-1, 3) * mask[:, None]
    colors = np.clip(np.asarray(splats.colors, np.float32), 0, 1)
    c0 = colors[order]
    lam = np.float32(regularization)
    precondition = 1 / (diagonal(indptr, rows, vals, mask) + lam)[:, None]
    image = np.empty_like(y)
    render(indptr, rows, vals, c0, image)
    r = np.empty_like(c0)
    gather(indptr, rows, vals, mask, y - image, r)  # the right side minus normal(c0)
    x = c0.copy()
    z = r * precondition
    p = z.copy()
    rz = (r * z).sum(0)
    for _ in range(iterations):
        q = normal(indptr, rows, vals, mask, p, lam, image)
        step = rz / np.maximum((p * q).sum(0), 1e-30)
        x += p * step
        r -= q * step
        z = r * precondition
        rz, previous = (r * z).sum(0), rz
        p = z + p * (rz / np.maximum(previous, 1e-30))
    colors[order] = np.clip(x, 0, 1)
    return replace(splats, colors=colors)
