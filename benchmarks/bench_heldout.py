"""Held-out fill benchmark (issue 27): first-pass region shapes on photos, the border
ring, and ``make``'s border, per backend.

What it runs is ``photo3d eval --heldout`` (:func:`photo3d.eval.heldout.evaluate_heldout`):
on every photo (longer side 640 px) 4 context/synthesis pairs of the pipeline's first
pass (the motorcycle's ground-truth disparity and the synthetic scenes' depth) are
pasted at places seeded by the photo's file name; each backend fills each synthesis
region from its context alone; LPIPS / PSNR / SSIM inside the region. Border: the outer
48 px hidden and extrapolated by each backend from the 62 px band inside them. Make
border: the outer 24 px hidden, ``photo3d.make`` (flat depth, default ``Config``) of
the rest rendered from its own camera over the full frame, the ring scored.

**Evaluation photos** (default; never to be used for training): scikit-image's
astronaut, coffee, chelsea, rocket, camera, coins, moon, brick, grass, gravel, clock
and text, and, where the packages are installed, matplotlib's grace_hopper and
scikit-learn's china and flower. Any folder can be given instead (``--folder``; e.g.
the held-out split of a wallpaper training set).

Caveat, recorded per photo as ``in_compact_training``: the compact nets shipped in
``src/photo3d/nets/compact`` were trained with ``photo3d train --images builtin``,
whose colour targets are 13 scikit-image photos (:data:`photo3d.train.builtin.PHOTOS`),
10 of the 12 above; for the ``learned`` backend only clock and text (and the
matplotlib / scikit-learn photos) are held out. The table reports the mean over
those too. Nets trained from now on must leave every evaluation photo out.

Usage: python benchmarks/bench_heldout.py [--folder DIR] [--methods diffusion,...]
           [--per-photo 4] [--no-make-border]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402

SKIMAGE = ("astronaut", "coffee", "chelsea", "rocket", "camera", "coins", "moon", "brick",
           "grass", "gravel", "clock", "text")
"""scikit-image evaluation photos."""


def optional_photos() -> dict[str, np.ndarray]:
    """matplotlib's grace_hopper and scikit-learn's china / flower, if installed."""
    out = {}
    try:
        import matplotlib.cbook as cbook
        from PIL import Image

        with cbook.get_sample_data("grace_hopper.jpg") as f, Image.open(f) as im:
            out["grace_hopper"] = np.asarray(im.convert("RGB"))
    except ImportError:
        pass
    try:
        from sklearn.datasets import load_sample_images

        for name, img in zip(("china", "flower"), load_sample_images().images, strict=True):
            out[name] = img
    except ImportError:
        pass
    return out


def write_default_photos(folder: Path) -> dict[str, str]:
    """The evaluation photos as lossless PNGs in ``folder``; name -> provenance."""
    from skimage import data

    from photo3d.io.images import to_float_image, write_image

    where = {}
    for name in SKIMAGE:
        write_image(folder / f"{name}.png", to_float_image(getattr(data, name)()))
        where[f"{name}.png"] = f"skimage.data.{name}"
    for name, img in optional_photos().items():
        write_image(folder / f"{name}.png", to_float_image(img))
        where[f"{name}.png"] = name
    return where


def _mean_over(photos: dict, names: list[str]) -> dict:
    out: dict = {}
    for part in ("regions", "border"):
        for method in photos[names[0]][part]:
            rows = [photos[n][part][method] for n in names]
            out.setdefault(part, {})[method] = {k: float(np.mean([r[k] for r in rows]))
                                                for k in rows[0]}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, help="photos to evaluate (default: the "
                        "evaluation photos listed in the docstring)")
    parser.add_argument("--methods", default="diffusion,structured,learned,replicate")
    parser.add_argument("--per-photo", type=int, default=4)
    parser.add_argument("--no-make-border", action="store_true")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "heldout.json")
    args = parser.parse_args()

    from photo3d.config import Config
    from photo3d.eval.heldout import evaluate_heldout, table
    from photo3d.eval.heldout_data import photo_files, region_bank
    from photo3d.train.builtin import PHOTOS as TRAINING

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.folder or Path(tmp)
        where = {} if args.folder else write_default_photos(folder)
        files = photo_files(folder)
        t = time.perf_counter()
        bank = region_bank()
        bank_s = time.perf_counter() - t
        t = time.perf_counter()
        result = evaluate_heldout(
            files, methods=args.methods.split(","), count=args.per_photo, bank=bank,
            make_config=None if args.no_make_border else Config(),
            progress=lambda line: print(f"  {line}", file=sys.stderr, flush=True))
        total = time.perf_counter() - t
    record = result.to_dict()
    for name, rec in record["photos"].items():
        rec["source"] = where.get(name, str(folder / name))
        rec["in_compact_training"] = Path(name).stem in TRAINING and not args.folder
    unseen = [n for n, r in record["photos"].items() if not r["in_compact_training"]]
    md = table(record)
    if unseen and len(unseen) < len(record["photos"]):
        record["mean_unseen_by_compact_nets"] = _mean_over(record["photos"], unseen)
        lp = {m: v.get("lpips", v["psnr"]) for m, v in
              record["mean_unseen_by_compact_nets"]["regions"].items()}
        md += (f"\nMean regions LPIPS over the {len(unseen)} photos the compact nets never "
               f"saw ({', '.join(unseen)}): "
               + ", ".join(f"{m} {v:.3f}" for m, v in lp.items()) + ".\n")
    seconds = {m: sum(r["seconds"][m] for r in record["photos"].values())
               for m in record["methods"]}
    md += (f"\nTime: {total:.0f} s for {len(record['photos'])} photos (region bank "
           f"{bank_s:.1f} s; fill and scoring per method, all photos: "
           + ", ".join(f"{m} {s:.0f} s" for m, s in seconds.items()) + ").\n")
    record.update(markdown=md, seconds_total=total, seconds_bank=bank_s,
                  seconds_per_method=seconds)
    save_record(record, args.out, "heldout", "bench_heldout.py")
    print(md)


if __name__ == "__main__":
    main()
