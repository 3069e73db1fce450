"""``photo3d render OUT``: videos or a still of a saved 3D photo, without recomputing it."""

from __future__ import annotations

import argparse
import contextlib
import os
import time
from pathlib import Path

from photo3d.cli.options import (
    add_video_options,
    check_photo_folder,
    check_video_sizes,
    render_settings_from,
    videos_from,
)
from photo3d.cli.progress import StageBar


def add_parser(sub) -> None:
    """Register ``render`` on the subparsers ``sub``."""
    rd = sub.add_parser("render", help="render videos of a saved 3D photo (no recomputing)")
    rd.add_argument("photo", type=Path, help="a 3D photo folder written by make")
    add_video_options(rd, command="render")
    rd.add_argument("--still", action="store_true",
                    help="write one image of the input view (stereo with --stereo) to "
                         "PHOTO/still[_MODE].png instead of videos")
    rd.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    rd.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d render``; returns the exit status."""
    from photo3d.output import write_videos
    from photo3d.photo import load

    check_photo_folder(args.photo)
    videos = videos_from(args)  # checks the videos with a size against their encoder
    photo = load(args.photo)
    _check_resources(args, photo, videos[:1] if args.still else videos)
    if args.still:
        return _still(args, photo, videos[0])
    check_video_sizes(videos, (photo.ldi.width // 2 * 2, photo.ldi.height // 2 * 2))
    folder = args.photo / "video"
    new_folder = not os.path.lexists(folder)
    bar = StageBar(args.quiet)
    t = time.perf_counter()
    try:
        written = write_videos(photo, None, args.photo, videos,
                               settings=render_settings_from(args), progress=bar)
    except BaseException:
        if new_folder:  # created by this render, which wrote nothing there
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    finally:
        bar.close()
    if not args.quiet:
        print(f"rendered {len(written)} video(s) in {time.perf_counter() - t:.2f}s:")
        for path in written:
            print(f"  {path}  {path.stat().st_size / 1e6:.2f} MB")
    return 0


def _check_resources(args: argparse.Namespace, photo, videos) -> None:
    """Refuse, before rendering, a size and ``--ssaa`` the memory cannot hold, and
    outputs the disk cannot hold (:func:`photo3d.resources.outputs.render_bytes`)."""
    from photo3d.resources import check_free_space, check_render_memory
    from photo3d.resources.outputs import render_bytes

    need = 0
    for spec in videos:
        size = spec.size or (photo.ldi.width // 2 * 2, photo.ldi.height // 2 * 2)
        check_render_memory(photo.ldi.size, size, ssaa=args.ssaa,
                            views=2 if spec.stereo else 1, video=not args.still)
        views = 2 if spec.stereo == "sbs" else 1  # side by side at full width each
        need += render_bytes(size[0] * size[1] * views, spec.frames, still=args.still)
    check_free_space(args.photo / ("still.png" if args.still else "video/a.mp4"), need,
                     what="this render")


def _still(args: argparse.Namespace, photo, spec) -> int:
    from photo3d.files.atomic import atomic_path, check_writable
    from photo3d.io.images import write_image
    from photo3d.owned import claim_files, recording
    from photo3d.render.animate import render_still
    from photo3d.render.renderer import Renderer

    name = f"still_{spec.stereo}.png" if spec.stereo else "still.png"
    path = args.photo / name
    claim_files(args.photo, [name])  # never a link, nor a file photo3d did not write
    check_writable(path, follow_symlinks=False)  # before rendering
    with Renderer(photo.mesh(), render_settings_from(args)) as renderer:
        image = render_still(renderer, photo.ldi, spec)
    with recording(args.photo), atomic_path(path, follow_symlinks=False) as tmp:
        write_image(tmp, image)  # recorded as it is moved into place
    if not args.quiet:
        print(f"wrote {path} ({image.shape[1]}x{image.shape[0]})")
    return 0
