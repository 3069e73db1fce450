"""``photo3d depth IMAGE -o OUT.png``: write the depth map the pipeline would use."""

from __future__ import annotations

import argparse
from pathlib import Path

from photo3d.cli.options import add_depth_sources, depth_from_args


def add_parser(sub) -> None:
    """Register ``depth`` on the subparsers ``sub``."""
    dp = sub.add_parser("depth", help="write the depth map the pipeline would use "
                        "(16-bit PNG + colour preview) to inspect or edit")
    dp.add_argument("image", type=Path, help="JPEG, PNG, TIFF, WebP or HEIC photo")
    add_depth_sources(dp)
    dp.add_argument("-o", "--out", type=Path, required=True, help="output PNG (16-bit)")
    dp.add_argument("--overwrite", action="store_true",
                    help="replace OUT.png and OUT_preview.png if they exist")
    dp.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d depth``; returns the exit status."""
    from photo3d.depth.export import check_depth_output, depth_outputs, export_depth
    from photo3d.errors import OutputError
    from photo3d.files.atomic import check_writable

    inputs = [p for p in (args.image, args.depth, args.right, args.depth_model) if p]
    check_depth_output(args.out, inputs=inputs)  # before a possibly slow depth estimate
    for out in depth_outputs(args.out):
        if (out.exists() or out.is_symlink()) and not args.overwrite:
            raise OutputError(f"depth output {out} exists; pass --overwrite to replace it")
        check_writable(out, follow_symlinks=False)
    _check_resources(args)  # from the photo's header, before a pixel is decoded
    est = depth_from_args(args)
    png, preview = export_depth(est, args.out, inputs=inputs)
    print(f"wrote {png} (16-bit normalised disparity, near = bright) and {preview}")
    return 0


def _check_resources(args: argparse.Namespace) -> None:
    """Refuse, from the photo's header, a photo whose depth map needs more memory than
    is available (:func:`photo3d.resources.check_depth_memory`: the map is made at the
    photo's size), or more disk than is free."""
    from photo3d.io.images import image_shape
    from photo3d.resources import check_depth_memory, check_free_space
    from photo3d.resources.outputs import render_bytes

    shape = image_shape(args.image)
    if shape is not None:  # else the reader says what is wrong with the file
        # no map nor right view: a model may run (not for an embedded map: counted anyway)
        check_depth_memory(shape, model=args.depth is None and args.right is None)
        # the 16-bit map and its preview
        check_free_space(args.out, 2 * render_bytes(shape[0] * shape[1], 1, still=True),
                         what="this depth map (and its preview)")
