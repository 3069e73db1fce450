"""``photo3d eval``: score novel views against a real second view, or fills on held-out
photos (``--heldout DIR``, :mod:`photo3d.eval.heldout`)."""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path

from photo3d.cli.options import weights_arg, weights_folder
from photo3d.errors import Photo3DError


def _methods() -> tuple[str, ...]:
    from photo3d.eval.evaluate import METHODS

    return METHODS


def add_parser(sub) -> None:
    """Register ``eval`` on the subparsers ``sub``."""
    ev = sub.add_parser("eval", help="score novel views against a real second view, or "
                        "fills on held-out photos")
    src = ev.add_mutually_exclusive_group()
    src.add_argument("--pair", nargs=4, metavar=("LEFT", "RIGHT", "DISP", "CALIB"),
                     help="a rectified pair: images, left disparity (PFM: inf = unknown, or "
                          "PNG: 0 = unknown) and a Middlebury calib.txt")
    src.add_argument("--synthetic", type=int, metavar="N",
                     help="N synthetic layered scenes with exact ground truth (seeds 0..N-1)")
    src.add_argument("--heldout", type=Path, metavar="DIR",
                     help="fill benchmark on the photos of DIR: first-pass region shapes "
                          "pasted at seeded random places, and the border ring (keep these "
                          "photos out of every training set)")
    ev.add_argument("--methods",
                    help="comma-separated methods (default: all; with --heldout the fills "
                         "diffusion, structured, learned, replicate)")
    ev.add_argument("--per-photo", type=int, default=4, metavar="K",
                    help="--heldout: region pairs per photo (default 4)")
    ev.add_argument("--weights", type=weights_arg, metavar="DIR|authors|random",
                    help="learned inpainter weights folder (default: the compact nets "
                    "shipped with photo3d; 'authors': the authors' published files, "
                    "downloaded once; 'random': the authors' architectures with random "
                    "weights)")
    ev.add_argument("--no-lpips", action="store_true", help="skip LPIPS (needs torch)")
    ev.add_argument("-o", "--out", type=Path,
                    help="results folder (must not exist or be empty; default: a new one, "
                         "the first free one of out/eval, out/eval-2, ...)")
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

    if args.heldout is not None:
        return _heldout(args)
    methods = _chosen(args.methods, _methods())
    if args.synthetic is not None and not 1 <= args.synthetic <= 1000:
        raise Photo3DError(f"--synthetic must be between 1 and 1000, got {args.synthetic}")
    if args.out is not None:
        check_results_folder(args.out, overwrite=args.overwrite)
    weights = weights_folder(args.weights, quiet=args.quiet)  # 'authors': downloaded once
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

    missing = _claim_out(args)
    try:
        record = run_eval(pairs, args.out, methods=methods, weights=weights,
                          overwrite=args.overwrite,
                          lpips=not args.no_lpips, progress=say)
    except BaseException:
        if missing:  # a failed or interrupted eval leaves no folder behind
            shutil.rmtree(missing[-1], ignore_errors=True)
        raise
    if not args.quiet:
        print((args.out / "results.md").read_text())
        written = ["results.json", "results.md", *(f"grid_{p}.png" for p in record["pairs"])]
        print(f"written: {args.out}/{', '.join(written)}")
        _say_kept(args.out, written)
    return 0


def _chosen(given: str | None, known: Sequence[str]) -> list[str]:
    """The methods of ``--methods`` (all of ``known`` when not given), checked."""
    if given is None:
        return list(known)
    methods = [m.strip() for m in given.split(",") if m.strip()]
    unknown = sorted(set(methods) - set(known))
    if unknown:
        raise Photo3DError(f"unknown method(s) {', '.join(unknown)}; "
                           f"methods: {', '.join(known)}")
    if not methods:
        raise Photo3DError(f"--methods is empty; methods: {', '.join(known)}")
    return methods


def _heldout(args: argparse.Namespace) -> int:
    """``photo3d eval --heldout DIR``: regions, border ring and ``make``'s border."""
    from photo3d.config import Config
    from photo3d.errors import OutputError
    from photo3d.eval.heldout import evaluate_heldout, table
    from photo3d.eval.heldout_data import photo_files
    from photo3d.eval.report import check_results_folder
    from photo3d.files.atomic import check_writable, write_json, write_text
    from photo3d.inpaint import available

    methods = _chosen(args.methods, [*available(), "replicate"])
    if not 1 <= args.per_photo <= 100:
        raise Photo3DError(f"--per-photo must be between 1 and 100, got {args.per_photo}")
    if args.out is not None:
        check_results_folder(args.out, overwrite=args.overwrite)
    weights = weights_folder(args.weights, quiet=args.quiet)  # 'authors': downloaded once
    photos = photo_files(args.heldout)
    missing = _claim_out(args)
    try:
        try:
            args.out.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise OutputError(f"cannot create the folder {args.out}: "
                              f"{err.strerror or err}") from None
        check_writable(args.out / "results.json")
        result = evaluate_heldout(
            photos, methods=methods, weights=weights, count=args.per_photo,
            make_config=Config(), lpips=not args.no_lpips,
            progress=None if args.quiet else lambda m: print(f"  {m}", file=sys.stderr))
        record = result.to_dict()
        write_json(args.out / "results.json", record)
        write_text(args.out / "results.md", table(record))
    except BaseException:
        if missing:  # a failed or interrupted eval leaves no folder behind
            shutil.rmtree(missing[-1], ignore_errors=True)
        raise
    if not args.quiet:
        print((args.out / "results.md").read_text())
        print(f"written: {args.out}/results.json, results.md")
        _say_kept(args.out, ["results.json", "results.md"])
    return 0


def _claim_out(args: argparse.Namespace) -> list[Path]:
    """Without ``-o``: create the run's own results folder (out/eval, out/eval-2, ...)
    and say which. Returns the folders this run creates, the outermost last, which a
    failed run removes."""
    if args.out is not None:
        return [p for p in (args.out, *args.out.parents) if not p.exists()]
    from photo3d.eval.report import new_results_folder

    args.out, outermost = new_results_folder()
    if not args.quiet:
        print(f"results folder: {args.out}", file=sys.stderr)
    return [args.out, outermost]


def _say_kept(out: Path, written: Sequence[str]) -> None:
    """Name the files of ``out`` this run left alone (``--overwrite`` keeps them)."""
    kept = sorted(p.name for p in out.iterdir() if p.name not in written)
    if kept:
        shown = ", ".join(kept[:5]) + (f" and {len(kept) - 5} more" if len(kept) > 5 else "")
        print(f"left as they were: {shown}")
