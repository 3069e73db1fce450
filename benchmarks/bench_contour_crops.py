"""Before/after crops of the contour growth and far-first hole fill (README picture).

Renders the right view of the Middlebury motorcycle and of synthetic scene 2 with
the ``diffusion`` fill, before (depth edges where the depth map puts them,
``grow_foreground=0``; uncovered pixels filled from both sides, ``hole_fill="both"``)
and now (edges moved one photo pixel into the far side, the farther side filled
first: the defaults), and writes the crops where the change lowers the disoccluded
LPIPS map most: real right view, before, now, disocclusion mask (zoomed, nearest).
Writes ``benchmarks/results/contour_crops.png`` and ``contour_crops.json``.

Usage: python benchmarks/bench_contour_crops.py [--crops 2]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402

from photo3d.config import Config  # noqa: E402
from photo3d.eval.evaluate import photo3d_of_pair  # noqa: E402
from photo3d.eval.lpips import lpips_map  # noqa: E402
from photo3d.eval.stereo_pair import motorcycle_pair  # noqa: E402
from photo3d.eval.synthetic import synthetic_pair  # noqa: E402
from photo3d.eval.warp import forward_warp  # noqa: E402
from photo3d.render.renderer import RenderSettings  # noqa: E402


def right_view(pair, grow: float, holes: str) -> np.ndarray:
    """The right view with the diffusion fill, ``grow_foreground`` and ``hole_fill``."""
    config = Config()
    config = config.with_(preprocess=replace(config.preprocess, grow_foreground=grow))
    return photo3d_of_pair(pair, config).render(pair.right_camera,
                        settings=RenderSettings(ssaa=2, hole_fill=holes)).color


PAIRS = {"motorcycle": (motorcycle_pair, 96, 2), "synthetic2": (lambda: synthetic_pair(2), 48, 4)}


def best_crops(gain: np.ndarray, size: int, count: int) -> list[tuple[int, int]]:
    """Top-left corners of ``count`` separate ``size`` crops with the largest ``gain``."""
    score = ndimage.uniform_filter(gain, size)
    h, w = gain.shape
    corners = []
    for _ in range(count):
        y, x = np.unravel_index(int(np.argmax(score)), score.shape)
        y0, x0 = min(max(0, y - size // 2), h - size), min(max(0, x - size // 2), w - size)
        corners.append((int(y0), int(x0)))
        score[max(0, y - size):y + size, max(0, x - size):x + size] = -np.inf
    return corners


def main() -> None:
    from PIL import Image, ImageDraw

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--crops", type=int, default=2, help="crops per pair")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args()
    rows, record = [], {}
    for name, (make_pair, size, zoom) in PAIRS.items():
        pair = make_pair()
        mask = forward_warp(pair.left, pair.disparity).disoccluded
        views = [right_view(pair, 0.0, "both"), right_view(pair, 1.0, "far")]
        gain = (lpips_map(views[0], pair.right) - lpips_map(views[1], pair.right)) * mask
        corners = best_crops(gain, size, args.crops)
        record[name] = corners
        cols = [pair.right, *views, np.repeat(mask[..., None], 3, axis=2).astype(np.float32)]
        for y, x in corners:
            tiles = [Image.fromarray(np.round(np.clip(c[y:y + size, x:x + size], 0, 1) * 255)
                                     .astype(np.uint8)).resize((size * zoom, size * zoom),
                                                               Image.NEAREST) for c in cols]
            rows.append(tiles)
    width = max(sum(t.size[0] + 4 for t in r) for r in rows)
    label = 16
    canvas = Image.new("RGB", (width, label + sum(r[0].size[1] + 4 for r in rows)),
                       (170, 170, 170))
    draw = ImageDraw.Draw(canvas)
    cell = rows[0][0].size[0] + 4
    for j, title in enumerate(("real right view", "before", "now", "disoccluded (white)")):
        draw.text((j * cell + 4, 2), title, fill="black")
    top = label
    for r in rows:
        left = 0
        for t in r:
            canvas.paste(t, (left, top))
            left += t.size[0] + 4
        top += r[0].size[1] + 4
    args.out.mkdir(parents=True, exist_ok=True)
    canvas.save(args.out / "contour_crops.png")
    save_record({"crops": record}, args.out / "contour_crops.json", "contour_crops",
                "bench_contour_crops.py")
    print(f"written: {args.out / 'contour_crops.png'}")


if __name__ == "__main__":
    main()
