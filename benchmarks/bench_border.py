"""The frame beyond the photo, end to end (issue 27): each border fill, per photo.

Issue 27's check: each photo (longer side 640 px) loses its outer 24 px,
``photo3d.make`` builds the 3D photo of the rest (flat depth, default settings but
``Config.regions.border_fill``), it is rendered from its own camera over the full
frame and the hidden ring is scored against the true pixels
(:func:`photo3d.eval.heldout.make_border`). Default folder: the held-out split of
``scripts/data/fetch_photos.py`` (never used for training or for choosing a parameter).

Writes ``results/border.json`` (per photo and mean, per fill) and prints the means.
Usage: python benchmarks/bench_border.py [--folder data/photos/heldout]
           [--fills replicate,diffusion,structured,texture] [--out results/border.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info  # noqa: E402

from photo3d.config import Config  # noqa: E402
from photo3d.eval.heldout import make_border  # noqa: E402
from photo3d.eval.heldout_data import load_photo, photo_files  # noqa: E402

HERE = Path(__file__).parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=HERE.parent / "data/photos/heldout")
    parser.add_argument("--fills", default="replicate,diffusion,structured,texture")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "border.json")
    args = parser.parse_args()
    fills = args.fills.split(",")
    per: dict[str, dict[str, dict]] = {f: {} for f in fills}
    for path in photo_files(args.folder):
        image = load_photo(path)
        for fill in fills:
            config = Config()
            config = config.with_(regions=dataclasses.replace(config.regions, border_fill=fill))
            per[fill][path.name] = make_border(image, config=config)
        print(path.name, " ".join(f"{f} {per[f][path.name]['lpips']:.3f}" for f in fills),
              flush=True)
    mean = {f: {k: float(np.mean([r[k] for r in rows.values()]))
                for k in ("lpips", "psnr", "ssim")} for f, rows in per.items()}
    for f, m in mean.items():
        print(f"{f:12s} LPIPS {m['lpips']:.4f} PSNR {m['psnr']:.2f} SSIM {m['ssim']:.3f}")
    record = {"benchmark": "border", "machine": machine_info(), "folder": str(args.folder),
              "mean": mean, "photos": per, "markdown": table(mean, len(per[fills[0]])),
              "command": " ".join(["python", "benchmarks/bench_border.py", *sys.argv[1:]])}
    args.out.write_text(json.dumps(record, indent=1))


def table(mean: dict[str, dict[str, float]], photos: int) -> str:
    """The means as a markdown table, replication first as the reference."""
    ref = mean.get("replicate")
    rows = ["| border fill | ring LPIPS | vs replicate | ring PSNR | ring SSIM |",
            "| --- | --- | --- | --- | --- |"]
    for fill, m in mean.items():
        change = f"{100 * (m['lpips'] / ref['lpips'] - 1):+.1f} %" if ref else ""
        rows.append(f"| {fill} | {m['lpips']:.4f} | {change} | {m['psnr']:.2f} | "
                    f"{m['ssim']:.3f} |")
    return "\n".join(rows) + f"\n\nMean over {photos} photos.\n"


if __name__ == "__main__":
    main()
