"""``photo3d eval``: score novel views against a real second view."""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from photo3d.errors import Photo3DError


def _methods() -> tuple[str, ...]:
    from photo3d.eval.evaluate import METHODS

    return METHODS


def add_parser(sub) -> None:
    """Register ``eval`` on the subparsers ``sub``."""
    ev = sub.add_parser("eval", help="score novel views against a real second view")
    src = ev.add_mutually_exclusive_group()
    src.add_argument("--pair", nargs=4, metavar=("LEFT", "RIGHT", "DISP", "CALIB"),
                     help="a rectified pair: images, left disparity (PFM: inf = unknown, or "
                          "PNG: 0 = unknown) and a Middlebury calib.txt")
    src.add_argument("--synthetic", type=int, metavar="N",
                     help="N synthetic layered scenes with exact ground truth (seeds 0..N-1)")
    ev.add_argument("--methods", default=",".join(_methods()),
                    help="comma-separated methods (default: all)")
    ev.add_argument("--weights", type=Path, help="learned inpainter weights folder "
                    "(default: the compact nets shipped with photo3d; 'random': the "
                    "authors' architectures with random weights)")
    ev.add_argument("--no-lpips", action="store_true", help="skip LPIPS (needs torch)")
    ev.add_argument("-o", "--out", type=Path, default=Path("out/eval"),
                    help="results folder (default out/eval; must not exist or be empty)")
    ev.add_argument("--overwrite", action="store_true",
                    help="replace the results eval wrote in an existing --out folder "
                         "(other files there are left alone)")
    ev.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    ev.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d eval``; returns the exit status."""
    from functools import partial

    from photo3d.eval.report import check_results_folder
    from photo3d.eval.report import run as run_eval
    from photo3d.eval.stereo_pair import load_pair, motorcycle_pair
    from photo3d.eval.synthetic import synthetic_pair

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = sorted(set(methods) - set(_methods()))
    if unknown:
        raise Photo3DError(f"unknown method(s) {', '.join(unknown)}; "
                           f"methods: {', '.join(_methods())}")
    if not methods:
        raise Photo3DError(f"--methods is empty; methods: {', '.join(_methods())}")
    if args.synthetic is not None and not 1 <= args.synthetic <= 1000:
        raise Photo3DError(f"--synthetic must be between 1 and 1000, got {args.synthetic}")
    check_results_folder(args.out, overwrite=args.overwrite)
    if args.pair:
        for given in args.pair:
            if not Path(given).is_file():
                raise Photo3DError(f"--pair: file not found: {given}")
        pairs = {Path(args.pair[0]).stem: partial(load_pair, *args.pair)}
    elif args.synthetic is not None:
        pairs = {f"synthetic{i}": partial(synthetic_pair, i) for i in range(args.synthetic)}
    else:
        pairs = {"motorcycle": motorcycle_pair}

    def say(msg: str) -> None:
        if not args.quiet:
            print(f"  {msg}", file=sys.stderr)

    missing = [p for p in (args.out, *args.out.parents) if not p.exists()]
    try:
        record = run_eval(pairs, args.out, methods=methods, weights=args.weights,
                          lpips=not args.no_lpips, progress=say)
    except BaseException:
        if missing:  # a failed or interrupted eval leaves no folder behind
            shutil.rmtree(missing[-1], ignore_errors=True)
        raise
    if not args.quiet:
        print((args.out / "results.md").read_text())
        print(f"written: {args.out}/results.json, results.md, "
              f"{', '.join(f'grid_{p}.png' for p in record['pairs'])}")
    return 0
