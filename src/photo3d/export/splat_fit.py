"""Splat colours fitted to photo3d's own render of the 3D photo, through Spark's
blend of all splats (``build_splats(ldi, fit=True)``, ``photo3d export --fit``).

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
equations (Jacobi-preconditioned), then the colours are clipped to [0, 1].

Measured on the bundled sample (docs/outputs.md): Spark's view from the input
camera rises from 27.5 to about 36.5 dB against photo3d's render, the circle
path's widest camera (not fitted) from 26.8 to about 30 dB; about 3 s more.
"""

from __future__ import annotations

import numpy as np

from photo3d.camera import Camera
from photo3d.structures.ldi import LDI
from photo3d.structures.splats import Splats

ITERATIONS = 5
"""Conjugate-gradient rounds (each two products with the sparse weights)."""
REGULARIZATION = 0.03
"""``lam``: the pull toward the colours as built, against squared pixel errors
(a one-pixel splat's weights have a squared sum of about 0.1 to 1)."""


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
               iterations: int = ITERATIONS, regularization: float = REGULARIZATION
               ) -> Splats:
    """``splats`` with colours fitted so that Spark's view from ``camera`` comes
    closest to ``color`` over ``covered`` (see the module doc).

    Args:
        splats: the splats (positions, sizes, opacities and rotations are kept).
        camera: the camera to fit (the input camera).
        color: ``(H, W, 3) float`` in [0, 1], the image to match (photo3d's render).
        covered: ``(H, W) bool``, the pixels that count.
        iterations: conjugate-gradient rounds.
        regularization: the pull toward the colours as built.

    Returns:
        :class:`~photo3d.structures.splats.Splats`, colours in [0, 1]; splats the
        camera does not see keep theirs.
    """
    from dataclasses import replace

    from photo3d.export.spark_model import visible_weights

    weights, order = visible_weights(splats, camera)  # (pixels, seen splats) CSC
    mask = np.asarray(covered, np.float32).reshape(-1, 1)
    y = np.asarray(color, np.float32).reshape(-1, 3) * mask
    colors = np.clip(np.asarray(splats.colors, np.float32), 0, 1)
    c0 = colors[order]
    lam = np.float32(regularization)
    norms = np.asarray(weights.multiply(weights).T @ mask).ravel()  # diag(W^T M W)
    precondition = (1 / (norms + lam)).astype(np.float32)[:, None]
    transposed = weights.T.tocsr()

    def normal(x: np.ndarray) -> np.ndarray:  # (W^T M W + lam) x
        return transposed @ ((weights @ x) * mask) + lam * x

    x = c0.copy()
    r = transposed @ (y - (weights @ x) * mask)  # the right side minus normal(c0)
    z = r * precondition
    p = z.copy()
    rz = (r * z).sum(0)
    for _ in range(iterations):
        q = normal(p)
        step = rz / np.maximum((p * q).sum(0), 1e-30)
        x += p * step
        r -= q * step
        z = r * precondition
        rz, previous = (r * z).sum(0), rz
        p = z + p * (rz / np.maximum(previous, 1e-30))
    colors[order] = np.clip(x, 0, 1)
    return replace(splats, colors=colors)
