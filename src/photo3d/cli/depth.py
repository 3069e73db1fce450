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
    dp.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d depth``; returns the exit status."""
    from photo3d.depth.export import export_depth
    from photo3d.files.atomic import check_writable

    check_writable(args.out)  # before a possibly slow depth estimate
    est = depth_from_args(args)
    png, preview = export_depth(est, args.out)
    print(f"wrote {png} (16-bit normalised disparity, near = bright) and {preview}")
    return 0
