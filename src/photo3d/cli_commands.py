"""Runners of the ``photo3d`` subcommands other than ``make`` (see :mod:`photo3d.cli`).

Each takes the parsed arguments, prints its summary and returns the exit status.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from photo3d.errors import Photo3DError


def _resolve_depth(args: argparse.Namespace):
    from photo3d.depth.sources import resolve_depth

    est = resolve_depth(args.image, depth=args.depth, right=args.right,
                        depth_model=args.depth_model, kind=args.depth_kind)
    if not getattr(args, "quiet", False):
        print(f"depth: {est.source}", file=sys.stderr)
    for warning in est.warnings:
        print(f"photo3d: warning: {warning}", file=sys.stderr)
    return est


def _run_depth(args: argparse.Namespace) -> int:
    from photo3d.depth.export import export_depth

    est = _resolve_depth(args)
    png, preview = export_depth(est, args.out)
    print(f"wrote {png} (16-bit normalised disparity, near = bright) and {preview}")
    return 0


def _eval_methods() -> tuple[str, ...]:
    from photo3d.eval.evaluate import METHODS

    return METHODS


def _run_eval(args: argparse.Namespace) -> int:
    from functools import partial

    from photo3d.eval.report import run
    from photo3d.eval.stereo_pair import load_pair, motorcycle_pair
    from photo3d.eval.synthetic import synthetic_pair

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = sorted(set(methods) - set(_eval_methods()))
    if unknown:
        raise Photo3DError(f"unknown method(s) {', '.join(unknown)}; "
                           f"methods: {', '.join(_eval_methods())}")
    if args.pair:
        pairs = {Path(args.pair[0]).stem: partial(load_pair, *args.pair)}
    elif args.synthetic:
        pairs = {f"synthetic{i}": partial(synthetic_pair, i) for i in range(args.synthetic)}
    else:
        pairs = {"motorcycle": motorcycle_pair}

    def say(msg: str) -> None:
        if not args.quiet:
            print(f"  {msg}", file=sys.stderr)

    record = run(pairs, args.out, methods=methods, weights=args.weights,
                 lpips=not args.no_lpips, progress=say)
    if not args.quiet:
        print((args.out / "results.md").read_text())
        print(f"written: {args.out}/results.json, results.md, "
              f"{', '.join(f'grid_{p}.png' for p in record['pairs'])}")
    return 0


def _run_render(args: argparse.Namespace) -> int:
    from photo3d.cli import _Bar, _render_settings, _videos
    from photo3d.output import load_photo, write_videos

    photo = load_photo(args.photo)
    videos = _videos(args)
    if args.still:
        return _run_still(args, photo, videos[0])
    bar = _Bar(args.quiet)
    t = time.perf_counter()
    try:
        written = write_videos(photo, None, args.photo, videos,
                               settings=_render_settings(args), progress=bar)
    finally:
        bar.close()
    if not args.quiet:
        print(f"rendered {len(written)} video(s) in {time.perf_counter() - t:.2f}s:")
        for path in written:
            print(f"  {path}  {path.stat().st_size / 1e6:.2f} MB")
    return 0


def _run_still(args: argparse.Namespace, photo, spec) -> int:
    from photo3d.cli import _render_settings
    from photo3d.io.images import write_image
    from photo3d.render.animate import render_still
    from photo3d.render.renderer import Renderer

    with Renderer(photo.mesh(), _render_settings(args)) as renderer:
        image = render_still(renderer, photo.ldi, spec)
    path = args.photo / (f"still_{spec.stereo}.png" if spec.stereo else "still.png")
    write_image(path, image)
    if not args.quiet:
        print(f"wrote {path} ({image.shape[1]}x{image.shape[0]})")
    return 0


def _run_view(args: argparse.Namespace) -> int:
    from photo3d.output import load_photo
    from photo3d.viewer import VIEWER_FILE, serve, write_viewer

    page = args.photo / VIEWER_FILE
    if not page.is_file():  # made with --no-viewer: write it now
        write_viewer(load_photo(args.photo).mesh(), page, title=args.photo.name)

    def ready(url: str, opened: bool) -> None:
        print(f"serving {args.photo}/ at {url}" + ("" if opened else "  (open it in a browser)"),
              flush=True)
        print("press Ctrl-C to stop", flush=True)

    serve(args.photo, port=args.port, open_browser=not args.no_browser, on_ready=ready)
    return 0


def _list_files(out: Path) -> None:
    for path in sorted(p for p in out.rglob("*") if p.is_file()):
        print(f"  {str(path.relative_to(out)):<24} {path.stat().st_size / 1e6:8.2f} MB")
