"""``photo3d make IMAGE -o OUT``: one photo (and its depth) to a 3D photo folder."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from photo3d.cli.options import (
    add_depth_sources,
    add_make_options,
    config_from,
    inpainter_options,
    list_files,
    render_settings_from,
    resolve_depth,
    videos_from,
)
from photo3d.cli.progress import STAGE_LABELS, StageBar
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
    from photo3d.output import stage_photo
    from photo3d.pipeline import make
    from photo3d.resources import check_memory

    check_memory((9, 16), config, at_least=True)  # a 16:9 photo, before reading the input
    videos = [] if args.no_video else videos_from(args)
    settings = render_settings_from(args)
    if videos and settings.backend == "gl":
        from photo3d.render.renderer import select_backend

        select_backend("gl")
    backend = get_inpainter(config.inpainter, **inpainter_options(args, config.inpainter))
    staging = stage_photo(args.out, overwrite=args.overwrite, inputs=inputs_of(args),
                          need_bytes=output_bytes(config, videos))
    with staging:  # removed on any error or interruption unless committed
        if callable(depth):
            image, depth, kind = depth()
            config = config.with_(depth_kind=kind)
        if not args.quiet:
            _say_if_upscaled(image.shape[:2], config)
        bar = StageBar(args.quiet)
        try:
            photo = make(image, depth=depth, config=config, inpainter=backend, progress=bar)
            bar("mesh", 0.0)
            t = time.perf_counter()
            photo.save(staging, ply=None if args.ply == "none" else args.ply,
                       glb=not args.no_glb, full_glb=args.full_glb,
                       viewer=not args.no_viewer, videos=videos,
                       render_settings=settings, progress=bar)
            photo.timings["save + video" if videos else "save"] = time.perf_counter() - t
            bar("video", 1.0)
        finally:
            bar.close()
    if not args.quiet:
        summary(photo, args.out)
    return 0


def _say_if_upscaled(shape: tuple[int, int], config: Config) -> None:
    """A small photo is enlarged to the working size (the parameters are tuned at 1024 px)."""
    from photo3d.stages.preprocess import working_shape

    if config.size is not None and max(shape) < config.size:
        h, w = working_shape(shape, config.size)
        print(f"photo3d: note: the photo is {shape[1]}x{shape[0]}; it is upscaled to a "
              f"{w}x{h} working size (--size 0 keeps its size)", file=sys.stderr)


def output_bytes(config: Config, videos: list) -> int:
    """A low estimate of the output's size (a full disk is refused before the work)."""
    side = config.size or 1024
    frames = sum(v.frames * (v.size[0] * v.size[1] if v.size else side * side * 0.75)
                 for v in videos)
    return int(60 * side * side + 0.02 * frames)


def inputs_of(args: argparse.Namespace) -> list[Path]:
    """The files a run reads (its output folder may not hold any of them)."""
    given = [getattr(args, n, None) for n in ("image", "depth", "right", "weights")]
    model = getattr(args, "depth_model", None)
    paths = [p for p in (args.paths or []) if Path(p).suffix.lower() in (".json", ".yaml",
                                                                         ".yml")]
    return [Path(p) for p in [*given, model, *paths] if p is not None and Path(p).exists()]


def summary(photo, out: Path) -> None:
    """Print what was made, where the time went and the files written."""
    w, h = photo.stats["working_size"]
    print(f"3D photo written to {out}/ ({w}x{h}, {photo.ldi.size:,} LDI pixels, "
          f"{photo.stats['passes']} inpainting pass(es), edges per pass {photo.stats['edges']})")
    total = sum(photo.timings.values())
    parts = ", ".join(f"{STAGE_LABELS.get(k, k)} {v:.2f}s" for k, v in photo.timings.items())
    print(f"time: {total:.2f}s ({parts})")
    list_files(out)
