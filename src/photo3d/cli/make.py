"""``photo3d make IMAGE -o OUT``: one photo (and its depth) to a 3D photo folder."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from photo3d.cli.options import (
    add_depth_sources,
    add_make_options,
    list_files,
    make_options,
    say_depth,
)
from photo3d.cli.progress import StageBar, download_bar
from photo3d.config import Config
from photo3d.folder import output_bytes
from photo3d.progress import STAGE_LABELS


def add_parser(sub) -> None:
    """Register ``make`` on the subparsers ``sub``."""
    mk = sub.add_parser("make", help="make a 3D photo from an image and a depth map")
    mk.add_argument("image", type=Path, help="JPEG, PNG, TIFF, WebP or HEIC photo")
    add_depth_sources(mk)
    add_make_options(mk, out_required=True)
    mk.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d make``; returns the exit status."""
    return run_make(args, args.image, depth=args.depth, right=args.right,
                    depth_model=args.depth_model)


def run_make(args: argparse.Namespace, image, *, say_source: bool = True, **sources) -> int:
    """Check every option first, then make ``image`` into ``args.out`` with a progress
    bar (:func:`photo3d.folder.make_folder`) and print a summary. Once the depth is
    known, numba's kernels are compiled (:func:`photo3d.kernels.compile_kernels`: the
    first run's "compiling, once" step; loaded from the cache afterwards); a kernel
    still compiled on first use (the renderer's) shows as "compiling, once" too.

    ``sources``: ``depth``, ``right`` or ``depth_model`` of the photo (none: its
    embedded map, else the depth model). ``say_source``: print where the depth came
    from (its warnings are printed anyway).
    """
    from photo3d.folder import make_folder, prepare
    from photo3d.kernels import compile_kernels, watch_compiles

    options = make_options(args)
    inpainter = prepare(options)
    bar = _LateBar(args.quiet)

    def on_depth(est, photo) -> None:
        say_depth(est, quiet=args.quiet, source=say_source)
        if not args.quiet:
            _say_if_upscaled(photo.shape[:2], options.config)
        compile_kernels(lambda fraction: bar("compile", fraction))

    try:
        with watch_compiles(lambda busy: bar.note(STAGE_LABELS["compile"] if busy else None)):
            photo = make_folder(image, args.out, options=options, inpainter=inpainter,
                                progress=bar, on_depth=on_depth,
                                download_bar=download_bar(args.quiet),
                                # by its name here, so a test can stand in another estimate
                                need_bytes=output_bytes(options.config, options.save),
                                **sources)
    finally:
        bar.close()
    if not args.quiet:
        summary(photo, args.out)
    return 0


class _LateBar:
    """A :class:`StageBar` started at the first progress report, so that what is
    printed while the depth is resolved comes before it."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bar: StageBar | None = None

    def __call__(self, stage: str, fraction: float) -> None:
        if self.bar is None:
            self.bar = StageBar(self.quiet)
        self.bar(stage, fraction)

    def note(self, label: str | None) -> None:
        if self.bar is not None:
            self.bar.note(label)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _say_if_upscaled(shape: tuple[int, int], config: Config) -> None:
    """A small photo is enlarged to the working size (the parameters are tuned at 1024 px)."""
    from photo3d.config import working_shape

    if config.size is not None and max(shape) < config.size:
        h, w = working_shape(shape, config.size)
        print(f"photo3d: note: the photo is {shape[1]}x{shape[0]}; it is upscaled to a "
              f"{w}x{h} working size (--size 0 keeps its size)", file=sys.stderr)


def summary(photo, out: Path) -> None:
    """Print what was made, where the time went and the files written."""
    w, h = photo.stats["working_size"]
    print(f"3D photo written to {out}/ ({w}x{h}, {photo.ldi.size:,} LDI pixels, "
          f"{photo.stats['passes']} inpainting pass(es), edges per pass {photo.stats['edges']})")
    total = sum(photo.timings.values())
    parts = ", ".join(f"{STAGE_LABELS.get(k, k)} {v:.2f}s" for k, v in photo.timings.items())
    print(f"time: {total:.2f}s ({parts})")
    list_files(out)
