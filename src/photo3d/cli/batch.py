"""``photo3d batch IN_DIR -o OUT_DIR``: every photo of a folder, resumable, local or on Ray."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from photo3d.cli.options import add_make_options, make_options
from photo3d.cli.progress import PhotoBar, download_bar


def add_parser(sub) -> None:
    """Register ``batch`` on the subparsers ``sub``."""
    bt = sub.add_parser(
        "batch", help="make a 3D photo of every photo in a folder (resumable; local or Ray)",
        description="Make OUT_DIR/<name>/ for every photo of IN_DIR, exactly what make "
                    "writes. Running the same command again skips finished photos and "
                    "retries failed ones; OUT_DIR/batch.jsonl records every photo; one "
                    "batch at a time per OUT_DIR (OUT_DIR/batch.lock).")
    bt.add_argument("input", type=Path, metavar="IN_DIR", help="folder of photos")
    bt.add_argument("--recursive", action="store_true", help="also take photos in subfolders "
                    "(output folders keep the subfolder names)")
    g = bt.add_argument_group("depth (per photo: a map in --depth, else the photo's embedded "
                              "map, else a depth model)")
    g.add_argument("--depth", type=Path, metavar="DEPTH_DIR",
                   help="depth maps named like the photos (a.jpg <-> a.png/.npy/.pfm/.tif)")
    g.add_argument("--depth-kind", choices=["disparity", "depth"],
                   help="what the maps in --depth hold (default disparity: near = large)")
    g.add_argument("--depth-model", metavar="NAME_OR_PATH",
                   help="monocular model for photos without a map (default: Depth Anything "
                        "V2 Small through transformers, extra photo3d[depth])")
    run = bt.add_argument_group("workers")
    run.add_argument("--engine", choices=["local", "ray"], default="local",
                     help="local: a process pool on this machine (default); ray: Ray actors "
                          "(extra photo3d[ray])")
    run.add_argument("--workers", type=int, metavar="N",
                     help="processes or Ray actors (default: the thread budget, "
                          "--threads, or the Ray cluster's CPUs)")
    run.add_argument("--ray-address", metavar="ADDRESS",
                     help="Ray cluster to use (default: RAY_ADDRESS, else a local Ray)")
    add_make_options(bt, out_required=True, out_help="output folder: one folder per photo "
                     "plus batch.jsonl", overwrite_help="redo photos that are already finished")
    bt.set_defaults(run=run_batch_command)


def _model_to_fetch(jobs, out: Path, options) -> str | None:
    """The depth model to download before the workers may need it (for photos to make
    that have no depth map; those with an embedded map will not use it), or None.

    Raises:
        InputError: the model names nothing (a missing folder, a name the hub refuses);
            checked before the output folder is created.
    """
    from photo3d.batch import is_complete
    from photo3d.batch.jobs import output_problem
    from photo3d.depth.fetch import default_depth_model, needs_download

    model = options.depth_model or default_depth_model()
    todo = [j for j in jobs if output_problem(j.name) is None
            and (options.overwrite or not is_complete(out / j.name))]
    if all(j.depth is not None for j in todo) or not needs_download(model):
        return None
    return str(model)


def _prefetch(model: str | None, quiet: bool) -> None:
    """Download ``model`` once, here (nothing for None)."""
    from photo3d.depth.fetch import fetch_model
    from photo3d.errors import InputError

    if model is None:
        return
    try:
        fetch_model(model, bar=download_bar(quiet))
    except InputError:
        pass  # photos without embedded depth then fail, each with the reason


def run_batch_command(args: argparse.Namespace) -> int:
    """Run ``photo3d batch``; exit status 1 if any photo failed."""
    from photo3d.batch import find_photos, run_batch
    from photo3d.batch.run import check_out_dir
    from photo3d.errors import ConfigError
    from photo3d.folder import prepare

    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    if args.ray_address and args.engine != "ray":
        raise ConfigError("--ray-address only applies to --engine ray")
    if args.engine == "ray":
        from photo3d.batch.ray_engine import require_ray

        require_ray()  # without Ray: one line, before OUT is created
    options = make_options(args)  # the same options as make, read in the same place
    prepare(options)  # bad names, weights, memory or OpenGL: refused before any work
    jobs = find_photos(args.input, depth=args.depth, recursive=args.recursive, skip=args.out)
    if args.engine == "local":  # every worker makes a photo at once; no more workers
        from photo3d.parallel import threads  # than photos start (run_batch)
        from photo3d.resources.make import check_batch_memory

        workers = max(1, min(args.workers or threads(), len(jobs)))
        check_batch_memory(options.config, workers=workers,
                           exports=options.save.exports, splat_fit=options.save.splat_fit)
    model = _model_to_fetch(jobs, args.out, options)  # a bad name: before creating --out
    check_out_dir(args.out)
    _prefetch(model, args.quiet)
    bar = PhotoBar(len(jobs), quiet=args.quiet)
    try:  # SIGTERM and SIGHUP arrive as KeyboardInterrupt too (photo3d.files.signals, main)
        summary = run_batch(jobs, args.out, options, engine=args.engine, workers=args.workers,
                            ray_address=args.ray_address, progress=bar)
    finally:
        bar.close()
    for note in summary.notes:  # bad manifest lines: their photos were made again
        print(f"photo3d: warning: {note}", file=sys.stderr)
    if not args.quiet:
        rate = (summary.ok + summary.failed) / max(summary.seconds, 1e-9)
        print(f"batch: {summary.ok} ok, {summary.failed} failed, {summary.skipped} skipped "
              f"in {summary.seconds:.1f}s ({rate:.2f} photos/s); manifest {summary.manifest}")
    return 1 if summary.failed else 0

