"""``photo3d export OUT FORMAT [FORMAT ...]``: a saved 3D photo as Gaussian splats
(PLY, SPZ, glTF), a USDZ for AR Quick Look or a Looking Glass quilt."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from photo3d.cli.options import add_splat_options, check_photo_folder
from photo3d.cli.progress import count_bar
from photo3d.save_options import EXPORT_FORMATS


def add_parser(sub) -> None:
    """Register ``export`` on the subparsers ``sub``."""
    ex = sub.add_parser(
        "export", help="write a saved 3D photo as splats, USDZ or a Looking Glass quilt",
        description="Write a saved 3D photo in other formats, into its folder (recorded "
                    "in config.json, so make --overwrite and later exports replace them) "
                    "or, with -o, one format to FILE. Formats: splats.ply (3DGS PLY), "
                    "splats.spz (Niantic SPZ), splats.glb (glTF KHR_gaussian_splatting), "
                    "mesh.usdz (AR Quick Look), quilt (Looking Glass).")
    ex.add_argument("photo", type=Path, help="a 3D photo folder written by make")
    ex.add_argument("formats", nargs="+", metavar="FORMAT", choices=EXPORT_FORMATS,
                    help="one or more of: " + ", ".join(EXPORT_FORMATS))
    ex.add_argument("-o", "--output", type=Path, metavar="FILE",
                    help="write the one FORMAT given to FILE instead of into the folder "
                         "(a suffix, if any, the format's: .ply, .spz, .glb, .usdz, quilt .png)")
    ex.add_argument("--overwrite", action="store_true",
                    help="with -o: replace FILE if it exists")
    add_splat_options(ex)
    ex.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    ex.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d export``; returns the exit status."""
    from photo3d.export import export_folder
    from photo3d.export.splats import splat_count

    check_photo_folder(args.photo)
    if not args.quiet:
        _say_memory(args)
    bar = count_bar(len(set(args.formats)), "export", quiet=args.quiet)
    t = time.perf_counter()
    try:
        written = export_folder(args.photo, args.formats, output=args.output,
                                overwrite=args.overwrite, density=args.splats,
                                spz_version=args.spz_version, splat_fit=args.splat_fit,
                                progress=lambda stage, fraction: bar.update(
                                    round(fraction * bar.total) - bar.n))
    finally:
        bar.close()
    if not args.quiet:
        print(f"exported {len(written)} file(s) in {time.perf_counter() - t:.2f}s:")
        for path in written:
            count = splat_count(path)
            what = f"  {count:,} splats" if count is not None else ""
            print(f"  {path}  {path.stat().st_size / 1e6:.2f} MB{what}")
    return 0


def _say_memory(args: argparse.Namespace) -> None:
    """Say, before the work, how much memory the export will take at most (what
    :func:`photo3d.resources.check_export_memory` checks); nothing when the folder
    has no readable 3D photo (export_folder says why)."""
    from photo3d.errors import InputError
    from photo3d.io.limits import format_bytes
    from photo3d.io.npz import ldi_pixels
    from photo3d.owned import LDI_FILE
    from photo3d.resources import export_memory_estimate

    try:
        pixels = ldi_pixels(args.photo / LDI_FILE)
    except InputError:
        return
    need = export_memory_estimate(pixels, list(dict.fromkeys(args.formats)),
                                  splat_fit=args.splat_fit)
    fitted = ", colours fitted" if args.splat_fit else ""
    print(f"export: {pixels:,} LDI pixels, {args.splats} splats{fitted}, at most about "
          f"{format_bytes(need)} of memory", flush=True)
