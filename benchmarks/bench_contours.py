"""Contours and uncovered pixels: the depth-edge growth and the far-first hole fill.

At an occluding contour the photo's pixels mix both sides' colours. With the depth
edge where the depth map puts it, the far side's mixed pixels stay with the
background and draw a thin foreground-coloured line along the far side of every
revealed area; ``PreprocessConfig.grow_foreground`` (default 1 photo pixel) moves
the edge out so they go with the object. Where no fill covers what the camera
uncovers, the renderer fills the pixels from their surroundings:
``RenderSettings.hole_fill`` ``"both"`` (both sides alike, before) or ``"far"``
(the farther side first, the default). This scores, for ``diffusion`` and
``structured`` in three settings (growth 0 / both sides = before; growth 1 / both
sides; growth 1 / far side = now), on the motorcycle pair and the synthetic scenes
(same renders as ``photo3d eval``):

* disoccluded PSNR and LPIPS of the right view;
* the share of disoccluded pixels that no triangle of the mesh covers (the renderer's
  hole filling paints them, whatever the fill);
* PSNR of the input view rendered from the 3D photo against the photo itself.

Writes ``results/contours.json``. Usage: python benchmarks/bench_contours.py
[--synthetic 5]
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _pairs import score_all_pairs  # noqa: E402

from photo3d.camera import Camera  # noqa: E402
from photo3d.config import Config  # noqa: E402
from photo3d.eval.evaluate import photo3d_of_pair  # noqa: E402
from photo3d.eval.lpips import lpips  # noqa: E402
from photo3d.eval.metrics import psnr  # noqa: E402
from photo3d.eval.warp import forward_warp  # noqa: E402
from photo3d.render.renderer import RenderSettings  # noqa: E402

FILLS = ("diffusion", "structured")
SETTINGS = ((0.0, "both"), (1.0, "both"), (1.0, "far"))  # (grow_foreground, hole_fill)


def score_pair(pair) -> dict[str, dict[str, float]]:
    """Scores of every fill and setting on one pair (keys ``"<fill> grow=<px> <hole_fill>"``)."""
    mask = forward_warp(pair.left, pair.disparity).disoccluded
    out = {}
    for fill in FILLS:
        for grow, holes in SETTINGS:
            settings = RenderSettings(ssaa=2, hole_fill=holes)
            config = Config().with_(inpainter=fill)
            config = config.with_(preprocess=replace(config.preprocess, grow_foreground=grow))
            photo = photo3d_of_pair(pair, config)
            view = photo.render(pair.right_camera, settings=settings)
            same = photo.render(Camera(pair.left_camera, np.eye(4)), settings=settings)
            out[f"{fill} grow={grow:g} {holes}"] = {
                "psnr": psnr(view.color, pair.right, mask),
                "lpips": lpips(view.color, pair.right, mask),
                "uncovered": float((~view.mask[mask]).mean()),
                "input_view_psnr": psnr(same.color, pair.left),
                "edges_per_pass": photo.stats["edges"],
            }
    return out


def main() -> None:
    score_all_pairs(score_pair, "contours", "bench_contours.py", __doc__)


if __name__ == "__main__":
    main()
