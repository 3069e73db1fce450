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


_TRAIN_OPTIONS = ("width", "levels", "blocks", "size", "batch", "steps", "lr", "seed",
                  "region_size", "depth_kind", "gan", "checkpoint_every", "sample_every")


def _run_train(args: argparse.Namespace) -> int:
    try:
        import torch
    except ImportError:
        raise Photo3DError("photo3d train needs PyTorch: pip install 'photo3d[learned]'") from None
    from tqdm import tqdm

    from photo3d.errors import ConfigError
    from photo3d.train import (
        TrainConfig,
        find_training_files,
        parameter_count,
        prepare_data,
        train,
        write_builtin,
    )
    from photo3d.train.run import check_resumable, checkpoints

    options = {k: getattr(args, k) for k in _TRAIN_OPTIONS if getattr(args, k) is not None}
    config = TrainConfig(args.kind, **options)
    try:
        device = torch.device(args.device) if args.device else None
    except RuntimeError:
        raise ConfigError(f"unknown torch device {args.device!r} (try cpu or cuda)") from None
    if device is not None and device.type == "cuda" and not torch.cuda.is_available():
        raise ConfigError("--device cuda: no CUDA device is available")
    if args.threads is not None:
        if args.threads < 1:
            raise ConfigError(f"--threads must be at least 1, got {args.threads}")
        torch.set_num_threads(args.threads)
    run = args.out
    if run.exists() and not run.is_dir():
        raise ConfigError(f"--out {run} exists and is not a folder")
    check_resumable(run, config)
    say = (lambda msg: None) if args.quiet else (lambda msg: print(msg, flush=True))

    def bar(total: int, desc: str, initial: int = 0):
        return tqdm(total=total, initial=initial, desc=desc, file=sys.stderr, leave=False,
                    disable=True if args.quiet else None, dynamic_ncols=True)

    if args.images == "builtin":
        if args.depth is not None or args.shapes is not None:
            raise ConfigError("--images builtin brings its own depth: drop --depth/--shapes")
        folder = run / "builtin"
        if not (folder / "images").is_dir():
            side = config.working_size
            with bar(100, "builtin data") as b:
                write_builtin(folder, scenes=args.builtin_scenes, width=side,
                              height=side * 3 // 4,
                              progress=lambda _, f: b.update(round(100 * f) - b.n))
        images, depth, shapes = folder / "images", folder / "depth", folder / "shapes"
    else:
        images, depth, shapes = Path(args.images), args.depth, args.shapes
    files = find_training_files(images, depth=depth, shapes=shapes)
    with bar(100, "prepare") as b:
        data = prepare_data(files, crop=config.size, region_size=config.working_size,
                            depth_kind=config.depth_kind, seed=config.seed,
                            cache=run / "data",
                            progress=lambda _, f: b.update(round(100 * f) - b.n))
    data.check(config.kind)
    sources = len({p.source for p in data.pool})
    say(f"data: {len(data)} photos ({int(data.has_depth.sum())} with depth), "
        f"{len(data.pool)} region pairs from {sources} depth maps")
    saved = checkpoints(run)
    start = saved[-1][0] if saved else 0
    from photo3d.nets import build_net

    params = parameter_count(build_net(config.kind, **config.net_config()))
    arch = ", ".join(f"{k} {v}" for k, v in config.net_config().items())
    say(f"net: {config.kind} ({arch}), {params / 1e6:.2f} M parameters; crop {config.size}, "
        f"batch {config.batch}, steps {start} -> {config.steps}"
        + (f" (resuming from {saved[-1][1].name})" if saved else ""))
    with bar(config.steps, "train", initial=min(start, config.steps)) as b:
        def progress(step: int, total: int, losses: dict) -> None:
            b.set_postfix_str(f"loss {losses['total']:.4g}", refresh=False)
            b.update(step - b.n)

        result = train(data, run, config, device=device, progress=progress)
    steps_run = result.step - result.start_step
    if steps_run:
        terms = ", ".join(f"{k} {v:.4g}" for k, v in result.losses.items())
        say(f"trained {steps_run} steps in {result.seconds:.1f}s "
            f"({result.seconds / steps_run:.2f} s/step); step {result.step}: {terms}")
    else:
        say(f"nothing to do: {run} is already at step {result.step}")
    size = result.weights.stat().st_size / 1e6
    say(f"weights: {result.weights} ({size:.2f} MB); log: {run / 'losses.csv'}; "
        f"samples: {run / 'samples'}/")
    return 0
