"""Crops of held-out regions: what each fill paints where the truth is known.

For each photo, the largest region pair the held-out benchmark places on it
(``photo3d eval --heldout``'s placements, the same seed) is filled by each method from
its context alone; one row per photo: the input (the region to fill in grey), each
fill, the truth. Writes one JPEG grid (default ``docs/img/heldout_regions.jpg``).

Usage: python benchmarks/heldout_crops.py [--folder data/photos/heldout] [--photos 4]
           [--methods diffusion,structured] [--out docs/img/heldout_regions.jpg]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from photo3d.eval.heldout import backend, fill
from photo3d.eval.heldout_data import SIZE, load_photo, photo_files, place, region_bank

REPO = Path(__file__).resolve().parents[1]
PAD = 16
"""Pixels of photo shown around the region's window."""


def row(image: np.ndarray, name: str, bank, fills: dict, *, height: int) -> list[np.ndarray]:
    """Input, each fill and the truth around the photo's largest placed region."""
    places = place(image.shape[:2], bank, name)
    p = max(places, key=lambda q: int(bank[q.shape].synthesis.sum()))
    s = bank[p.shape]
    sh, sw = s.shape
    h, w = image.shape[:2]
    y0, y1 = max(p.y - PAD, 0), min(p.y + sh + PAD, h)
    x0, x1 = max(p.x - PAD, 0), min(p.x + sw + PAD, w)
    mask = np.zeros((h, w), bool)
    mask[p.y:p.y + sh, p.x:p.x + sw] = s.synthesis
    shown = image.copy()
    shown[mask] = 0.5
    tiles = [shown]
    for fill_with in fills.values():
        out = image.copy()
        out[p.y:p.y + sh, p.x:p.x + sw] = np.where(
            s.synthesis[..., None], fill(fill_with, image, s.context, s.synthesis, (p.y, p.x)),
            image[p.y:p.y + sh, p.x:p.x + sw])
        tiles.append(out)
    tiles.append(image)
    crops = []
    for t in tiles:
        crop = Image.fromarray((np.clip(t[y0:y1, x0:x1], 0, 1) * 255).astype(np.uint8))
        crops.append(np.asarray(crop.resize((round(crop.width * height / crop.height), height),
                                            Image.LANCZOS)))
    return crops


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=REPO / "data" / "photos" / "heldout")
    parser.add_argument("--photos", type=int, default=4)
    parser.add_argument("--methods", default="diffusion,structured")
    parser.add_argument("--height", type=int, default=200)
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "img" / "heldout_regions.jpg")
    args = parser.parse_args()
    methods = args.methods.split(",")
    fills = {m: backend(m) for m in methods}
    bank = region_bank(SIZE)
    files = photo_files(args.folder)
    step = max(1, len(files) // args.photos)  # spread over the folder, not its first few
    rows = [row(load_photo(f, SIZE), f.name, bank, fills, height=args.height)
            for f in files[::step][:args.photos]]
    labels = ["input (grey: to fill)", *methods, "truth"]
    widths = [max(r[i].shape[1] for r in rows) for i in range(len(labels))]
    gap, top = 6, 18
    grid = Image.new("RGB", (sum(widths) + gap * (len(widths) - 1),
                             top + len(rows) * (args.height + gap)), "white")
    draw = ImageDraw.Draw(grid)
    x = 0
    for i, label in enumerate(labels):
        draw.text((x + 4, 3), label, fill="black")
        for j, r in enumerate(rows):
            grid.paste(Image.fromarray(r[i]), (x, top + j * (args.height + gap)))
        x += widths[i] + gap
    args.out.parent.mkdir(parents=True, exist_ok=True)
    grid.save(args.out, quality=85)
    print(f"wrote {args.out} ({len(rows)} photos: "
          f"{', '.join(f.name for f in files[::step][:args.photos])})")


if __name__ == "__main__":
    main()
