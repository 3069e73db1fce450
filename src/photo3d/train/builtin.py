"""A training folder from data available offline (``photo3d train ... --images builtin``).

* ``images/``: photos shipped with scikit-image (:data:`PHOTOS`, no depth: paste
  targets for the colour net) and ray-cast synthetic scenes of textured planes
  (:func:`photo3d.eval.synthetic.random_scene`, seeds from 1000 on; the evaluation
  uses seeds 0-4) with exact depth;
* ``depth/``: the scenes' disparity ``1 / z`` (``.pfm``), matched by stem;
* ``shapes/``: the Middlebury motorcycle's ground-truth disparity, a *shape-only*
  source: its region shapes join the pool, its pixels are never a training target
  (the motorcycle pair is the real novel-view benchmark).

:func:`scene_disparity` gives a scene's disparity alone (no colour: cheap): the region
shapes of a colour-net training on photos without depth (see
:func:`photo3d.train.dataset.prepare_data`).

The synthetic scenes' textures are four of the photos, so colour statistics overlap;
real training wants a large photo collection with estimated depth (the paper: COCO
with MegaDepth).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from photo3d.camera import Intrinsics
from photo3d.errors import require
from photo3d.io.depth import write_pfm
from photo3d.io.images import to_float_image, write_image

PHOTOS = ("astronaut", "coffee", "chelsea", "rocket", "hubble_deep_field",
          "immunohistochemistry", "retina", "camera", "moon", "coins", "brick", "grass",
          "gravel")
"""scikit-image sample photos used as colour targets."""
FIRST_SEED = 1000
"""Synthetic training scenes use seeds ``FIRST_SEED, FIRST_SEED + 1, ...``."""


def write_builtin(folder: str | Path, *, scenes: int = 48, width: int = 512, height: int = 384,
                  photos: tuple[str, ...] = PHOTOS, motorcycle_shapes: bool = True,
                  progress: Callable[[str, float], None] | None = None) -> Path:
    """Write the built-in training folder (``images/``, ``depth/``, ``shapes/``).

    Args:
        folder: where to write (created; existing files are overwritten).
        scenes: number of synthetic scenes.
        width, height: size of the synthetic scenes in pixels.
        photos: scikit-image photo names.
        motorcycle_shapes: add the motorcycle disparity as a shape-only source.
        progress: ``progress("builtin data", fraction)``.

    Returns:
        ``folder``.

    Example:
        >>> import tempfile
        >>> d = write_builtin(tempfile.mkdtemp(), scenes=1, width=32, height=24,
        ...                   photos=("coins",), motorcycle_shapes=False)
        >>> sorted(p.name for p in (d / "images").iterdir())
        ['coins.png', 'scene1000.png']
        >>> [p.name for p in (d / "depth").iterdir()]
        ['scene1000.pfm']
    """
    skdata = require("skimage.data", "sample", purpose="--images builtin",
                     package="scikit-image")
    from photo3d.eval.synthetic import cast, random_scene

    folder = Path(folder)
    for sub in ("images", "depth", "shapes"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    report = progress or (lambda stage, fraction: None)
    total = len(photos) + scenes + 1
    for i, name in enumerate(photos):
        write_image(folder / "images" / f"{name}.png", to_float_image(getattr(skdata, name)()))
        report("builtin data", (i + 1) / total)
    k = Intrinsics.default(width, height)
    for i in range(scenes):
        image, z = cast(random_scene(FIRST_SEED + i), k, 0.0)
        write_image(folder / "images" / f"scene{FIRST_SEED + i}.png", image)
        write_pfm(folder / "depth" / f"scene{FIRST_SEED + i}.pfm", (1.0 / z).astype(np.float32))
        report("builtin data", (len(photos) + i + 1) / total)
    if motorcycle_shapes:
        from photo3d.sample import motorcycle

        write_pfm(folder / "shapes" / "motorcycle.pfm", np.asarray(motorcycle().disparity))
    report("builtin data", 1.0)
    return folder


def scene_disparity(seed: int, width: int, height: int) -> np.ndarray:
    """The disparity ``1 / z`` of :func:`photo3d.eval.synthetic.random_scene` ``(seed)``
    seen from the origin with the default intrinsics (focal ``max(width, height)``),
    at pixel centres; no colour is rendered.

    Returns:
        ``(height, width) float32``, > 0.

    Example:
        >>> d = scene_disparity(FIRST_SEED, 32, 24)
        >>> d.shape, bool(d.max() > d.min() > 0)
        ((24, 32), True)
    """
    from photo3d.eval.synthetic import random_scene

    k = Intrinsics.default(width, height)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    rx, ry = (xx + 0.5 - k.cx) / k.fx, (yy + 0.5 - k.cy) / k.fy
    z = np.full((height, width), np.inf)
    for p in random_scene(seed):
        x, y = rx * p.z, ry * p.z
        hit = (x >= p.x0) & (x <= p.x1) & (y >= p.y0) & (y <= p.y1) & (p.z < z)
        z[hit] = p.z
    z[~np.isfinite(z)] = max(p.z for p in random_scene(seed))
    return (1.0 / z).astype(np.float32)
