"""Before/after crops of the fill on the demo photo (the README's picture).

Renders the Middlebury motorcycle's right view (the real second photo's camera) with
two inpainters and writes, for the crops with the most disoccluded pixels, the real
right photo, each inpainter's view and the disocclusion mask side by side (2x zoom),
plus each inpainter's disoccluded PSNR/LPIPS on the whole view.
Writes ``benchmarks/results/fill_crops.png`` and ``fill_crops.json``.

Usage: python benchmarks/bench_fill_crops.py [--inpainters diffusion,structured]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402

from photo3d.eval.evaluate import render_method  # noqa: E402
from photo3d.eval.lpips import lpips  # noqa: E402
from photo3d.eval.metrics import psnr  # noqa: E402
from photo3d.eval.stereo_pair import motorcycle_pair  # noqa: E402
from photo3d.eval.warp import forward_warp  # noqa: E402


def pick_crops(mask: np.ndarray, size: int, count: int) -> list[tuple[int, int]]:
    """Top-left corners of ``count`` non-overlapping ``size`` crops with the most
    disoccluded pixels."""
    h, w = mask.shape
    cands = [(int(mask[y:y + size, x:x + size].sum()), y, x)
             for y in range(0, h - size + 1, size // 4) for x in range(0, w - size + 1, size // 4)]
    chosen: list[tuple[int, int]] = []
    for _, y, x in sorted(cands, reverse=True):
        if all(abs(y - cy) >= size or abs(x - cx) >= size for cy, cx in chosen):
            chosen.append((y, x))
        if len(chosen) == count:
            break
    return chosen


def main() -> None:
    from PIL import Image, ImageDraw

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inpainters", default="diffusion,structured")
    parser.add_argument("--size", type=int, default=120, help="crop size, px of the view")
    parser.add_argument("--crops", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args()
    names = args.inpainters.split(",")
    pair = motorcycle_pair()
    mask = forward_warp(pair.left, pair.disparity).disoccluded
    views = {n: render_method(n, pair)[0] for n in names}
    scores = {n: {"psnr": psnr(v, pair.right, mask), "lpips": lpips(v, pair.right, mask)}
              for n, v in views.items()}
    crops = pick_crops(mask, args.size, args.crops)
    cols = [("real right view", pair.right)] + [(n, views[n]) for n in names]
    cols.append(("disoccluded", np.repeat(mask[..., None], 3, axis=2).astype(np.float32)))
    z, s, label = 2, args.size, 16
    canvas = Image.new("RGB", (len(cols) * s * z, label + len(crops) * s * z), "white")
    draw = ImageDraw.Draw(canvas)
    for j, (name, img) in enumerate(cols):
        draw.text((j * s * z + 4, 2), name, fill="black")
        for i, (y, x) in enumerate(crops):
            tile = np.round(np.clip(img[y:y + s, x:x + s], 0, 1) * 255).astype(np.uint8)
            tile = Image.fromarray(tile).resize((s * z, s * z), Image.NEAREST)
            canvas.paste(tile, (j * s * z, label + i * s * z))
    args.out.mkdir(parents=True, exist_ok=True)
    canvas.save(args.out / "fill_crops.png")
    save_record({"scores": scores, "crops": crops, "crop_size": s}, args.out / "fill_crops.json",
                "fill_crops", "bench_fill_crops.py")
    for n, sc in scores.items():
        print(f"{n:12s} disoccluded PSNR {sc['psnr']:.2f} dB, LPIPS {sc['lpips']:.4f}")
    print(f"written: {args.out / 'fill_crops.png'}")


if __name__ == "__main__":
    main()
