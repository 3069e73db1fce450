"""Synthetic stereo scenes with exact ground truth, rendered by ray casting.

A scene is a stack of fronto-parallel textured rectangles (photo textures from the
images shipped with scikit-image) in front of a textured back plane. Both views are
rendered here by intersecting each pixel's rays with the planes (3x3 samples per
pixel), independently of photo3d's renderer, so disocclusions of known size and
several layers can be scored exactly. The left depth is the exact depth at pixel
centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d.camera import Camera, Intrinsics
from photo3d.eval.stereo_pair import StereoPair


@dataclass(frozen=True)
class Plane:
    """Axis-aligned rectangle at depth ``z``: ``x0 <= X <= x1``, ``y0 <= Y <= y1``."""

    z: float
    x0: float
    x1: float
    y0: float
    y1: float
    texture: np.ndarray  # (h, w, 3) float32


def _textures() -> list[np.ndarray]:
    from skimage import data

    imgs = [data.astronaut(), data.coffee(), data.chelsea(), data.rocket()]
    return [np.asarray(i, np.float32) / 255.0 for i in imgs]


def random_scene(seed: int, *, layers: int = 3) -> list[Plane]:
    """A back plane at depth 8 and ``layers`` rectangles between depth 2 and 6."""
    rng = np.random.default_rng(seed)
    tex = _textures()
    planes = [Plane(8.0, -5, 5, -4, 4, tex[int(rng.integers(len(tex)))])]
    for z in np.sort(rng.uniform(2.0, 6.0, layers))[::-1]:
        w, h = rng.uniform(0.25, 0.6, 2) * z
        cx, cy = rng.uniform(-0.35, 0.35, 2) * z
        planes.append(Plane(float(z), cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2,
                            tex[int(rng.integers(len(tex)))]))
    return planes


def _bilinear(tex: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    h, w = tex.shape[:2]
    x = np.clip(u * (w - 1), 0, w - 1)
    y = np.clip(v * (h - 1), 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    return ((1 - fy) * ((1 - fx) * tex[y0, x0] + fx * tex[y0, x1])
            + fy * ((1 - fx) * tex[y1, x0] + fx * tex[y1, x1]))


def cast(planes: list[Plane], k: Intrinsics, centre_x: float, *, samples: int = 3):
    """Render the scene from a camera at ``(centre_x, 0, 0)`` looking down +z.

    Returns ``(image (H, W, 3), depth (H, W))``; depth at pixel centres."""
    offsets = (np.arange(samples) + 0.5) / samples
    image = np.zeros((k.height, k.width, 3), np.float64)
    yy, xx = np.mgrid[0:k.height, 0:k.width].astype(np.float64)
    depth = None
    for oy in offsets:
        for ox in offsets:
            rx = (xx + ox - k.cx) / k.fx
            ry = (yy + oy - k.cy) / k.fy
            z_best = np.full(rx.shape, np.inf)
            col = np.zeros(rx.shape + (3,))
            for p in planes:
                wx, wy = centre_x + rx * p.z, ry * p.z
                hit = (wx >= p.x0) & (wx <= p.x1) & (wy >= p.y0) & (wy <= p.y1) & (p.z < z_best)
                if hit.any():
                    u = (wx[hit] - p.x0) / (p.x1 - p.x0)
                    v = (wy[hit] - p.y0) / (p.y1 - p.y0)
                    col[hit] = _bilinear(p.texture, u, v)
                    z_best[hit] = p.z
            image += col
            if abs(ox - 0.5) < 1e-9 and abs(oy - 0.5) < 1e-9:
                depth = z_best
    if depth is None:  # even sample counts: depth from a separate centre ray
        depth = cast(planes, k, centre_x, samples=1)[1]
    return (image / samples**2).astype(np.float32), depth.astype(np.float32)


def synthetic_pair(seed: int, *, width: int = 320, height: int = 240,
                   baseline: float = 0.25) -> StereoPair:
    """A synthetic rectified pair (depth units: those of the scene; baseline along +x).

    Example:
        >>> pair = synthetic_pair(0, width=64, height=48)
        >>> pair.left.shape, bool(np.isfinite(pair.disparity).all())
        ((48, 64, 3), True)
    """
    k = Intrinsics.default(width, height)
    planes = random_scene(seed)
    left, z = cast(planes, k, 0.0)
    right, _ = cast(planes, k, baseline)
    disp = (k.fx * baseline / z).astype(np.float32)  # doffs = 0: same principal point
    return StereoPair(left, right, disp, k, Camera.translated(k, (baseline, 0.0, 0.0)),
                      float(baseline), 0.0)
