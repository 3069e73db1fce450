"""``photo3d view OUT``: serve a 3D photo folder on 127.0.0.1 and open its viewer."""

from __future__ import annotations

import argparse
from pathlib import Path

from photo3d.cli.options import check_photo_folder


def add_parser(sub) -> None:
    """Register ``view`` on the subparsers ``sub``."""
    vw = sub.add_parser("view", help="serve a 3D photo folder on 127.0.0.1 and open its viewer")
    vw.add_argument("photo", type=Path, help="a 3D photo folder written by make")
    vw.add_argument("--port", type=int, default=0, help="port (default: any free one)")
    vw.add_argument("--no-browser", action="store_true", help="only print the URL")
    vw.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d view`` until Ctrl-C or a termination signal (the command line then
    exits with 130, or 128 + the signal's number); returns the exit status."""
    from photo3d.files.atomic import atomic_path, refuse_symlink
    from photo3d.photo import load
    from photo3d.viewer import VIEWER_FILE, serve, write_viewer
    from photo3d.viewer.serve import check_port

    check_photo_folder(args.photo)
    check_port(args.port)  # before viewer.html is written
    page = refuse_symlink(args.photo / VIEWER_FILE)  # never written through, never served
    if not page.is_file():  # made with --no-viewer: write it now
        photo = load(args.photo)
        with atomic_path(page, follow_symlinks=False) as tmp:  # checked before the mesh
            write_viewer(photo.mesh(), tmp, title=args.photo.name)

    def ready(url: str, opened: bool) -> None:
        print(f"serving {args.photo}/ at {url}" + ("" if opened else "  (open it in a browser)"),
              flush=True)
        print("press Ctrl-C to stop", flush=True)

    serve(args.photo, port=args.port, open_browser=not args.no_browser, on_ready=ready)
    return 0
