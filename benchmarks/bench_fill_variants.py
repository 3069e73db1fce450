"""What each step of the ``structured`` fill is worth, and how far any fill is from the bar.

Issue 14 asks a new default fill for 10 % lower LPIPS than diffusion in the
disoccluded pixels, on the real pair and on the synthetic mean. This scores, on the
motorcycle pair and the synthetic scenes (same renders as ``photo3d eval``):

* ``diffusion``; ``structured`` (the backend as shipped) and its steps alone:
  ``lines`` (continued edges + piecewise diffusion, no texture), ``texture`` (PatchMatch
  texture on plain diffusion, no lines);
* ``oracle-blur-S``: the diffusion render with its disoccluded pixels replaced by the
  real right view blurred by a Gaussian of S px: how good a fill must be (where
  structure is right to within S px) to reach a given score.

Writes ``results/fill_variants.json``. Usage: python benchmarks/bench_fill_variants.py
[--synthetic 5]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).parent))
from _pairs import score_all_pairs  # noqa: E402

from photo3d.config import Config  # noqa: E402
from photo3d.eval.evaluate import _photo3d_view  # noqa: E402
from photo3d.eval.lpips import lpips  # noqa: E402
from photo3d.eval.metrics import psnr  # noqa: E402
from photo3d.eval.warp import forward_warp  # noqa: E402
from photo3d.inpaint import get_inpainter  # noqa: E402
from photo3d.inpaint.structured import StructuredInpainter  # noqa: E402

FILLS = {
    "diffusion": lambda: get_inpainter("diffusion"),
    "structured": lambda: StructuredInpainter(),
    "lines": lambda: StructuredInpainter(texture=0.0),
    "texture": lambda: StructuredInpainter(lines=False),
}
BLURS = (1, 2, 4)


def score_pair(pair) -> dict[str, dict[str, float]]:
    """Disoccluded PSNR and LPIPS of every fill and oracle on one pair."""
    mask = forward_warp(pair.left, pair.disparity).disoccluded
    images = {name: _photo3d_view(pair, Config().with_(inpainter="structured"), make())
              for name, make in FILLS.items()}
    for s in BLURS:
        blurred = np.stack([ndimage.gaussian_filter(pair.right[..., c], s) for c in range(3)],
                           -1)
        images[f"oracle-blur-{s}"] = np.where(mask[..., None], blurred, images["diffusion"])
    return {name: {"psnr": psnr(img, pair.right, mask), "lpips": lpips(img, pair.right, mask)}
            for name, img in images.items()}


def main() -> None:
    score_all_pairs(score_pair, "fill_variants", "bench_fill_variants.py", __doc__)


if __name__ == "__main__":
    main()
