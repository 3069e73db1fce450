"""``photo3d demo``: ``make`` on the bundled Middlebury sample."""

from __future__ import annotations

import argparse
from pathlib import Path

from photo3d.cli.make import run_make
from photo3d.cli.options import add_make_options


def add_parser(sub) -> None:
    """Register ``demo`` on the subparsers ``sub``."""
    demo = sub.add_parser("demo", help="make a 3D photo of the bundled Middlebury sample")
    add_make_options(demo, out_required=False)
    demo.set_defaults(out=Path("out/demo"), run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d demo``; returns the exit status."""
    import numpy as np

    from photo3d.sample import motorcycle

    sample = motorcycle()
    if not args.quiet:
        print("sample: Middlebury 2014 'Motorcycle' left view with its ground-truth "
              "disparity (unknown pixels filled with the farther row neighbour)")
    return run_make(args, sample.left, depth=np.asarray(sample.disparity), say_source=False)
