"""``photo3d make IMAGE -o OUT``: one photo (and its depth) to a 3D photo folder."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from photo3d.cli.options import (
    STAGE_LABELS,
    add_depth_sources,
    add_make_options,
    config_from,
    inpainter_options,
    list_files,
    render_settings_from,
    resolve_depth,
    videos_from,
)
from photo3d.cli.progress import StageBar
from photo3d.config import Config


def add_parser(sub) -> None:
    """Register ``make`` on the subparsers ``sub``."""
    mk = sub.add_parser("make", help="make a 3D photo from an image and a depth map")
    mk.add_argument("image", type=Path, help="JPEG, PNG, TIFF, WebP or HEIC photo")
    add_depth_sources(mk)
    add_make_options(mk, out_required=True)
    mk.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d make``; returns the exit status."""
    from photo3d.depth.sources import load_photo

    def depth():
        est = resolve_depth(args)
        image = est.image if est.image is not None else load_photo(args.image)
        return image, est.depth, est.kind

    return run_make(args, None, depth, config_from(args))


def run_make(args: argparse.Namespace, image, depth, config: Config) -> int:
    """Validate everything cheap first, then resolve depth (if a callable), make, save.

    ``depth`` may be a callable returning ``(image, depth, depth_kind)``: it runs
    only after the options are known to be valid (it can be slow: stereo, models).
    """
    from photo3d.inpaint import get_inpainter
    from photo3d.output import check_output
    from photo3d.pipeline import make

    check_output(args.out, overwrite=args.overwrite)
    videos = [] if args.no_video else videos_from(args)
    settings = render_settings_from(args)
    backend = get_inpainter(config.inpainter, **inpainter_options(args, config.inpainter))
    if callable(depth):
        image, depth, kind = depth()
        config = config.with_(depth_kind=kind)
    bar = StageBar(args.quiet)
    try:
        photo = make(image, depth=depth, config=config, inpainter=backend, progress=bar)
        bar("mesh", 0.0)
        t = time.perf_counter()
        photo.save(args.out, overwrite=args.overwrite,
                   ply=None if args.ply == "none" else args.ply, glb=not args.no_glb,
                   full_glb=args.full_glb,
                   viewer=not args.no_viewer, videos=videos, render_settings=settings,
                   progress=bar)
        photo.timings["save + video" if videos else "save"] = time.perf_counter() - t
        bar("video", 1.0)
    finally:
        bar.close()
    if not args.quiet:
        summary(photo, args.out)
    return 0


def summary(photo, out: Path) -> None:
    """Print what was made, where the time went and the files written."""
    w, h = photo.stats["working_size"]
    print(f"3D photo written to {out}/ ({w}x{h}, {photo.ldi.size:,} LDI pixels, "
          f"{photo.stats['passes']} inpainting pass(es), edges per pass {photo.stats['edges']})")
    total = sum(photo.timings.values())
    parts = ", ".join(f"{STAGE_LABELS.get(k, k)} {v:.2f}s" for k, v in photo.timings.items())
    print(f"time: {total:.2f}s ({parts})")
    list_files(out)
