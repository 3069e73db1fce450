"""``photo3d train {edge,depth,color}``: train one of the learned inpainter's nets."""

from __future__ import annotations

import argparse
import errno
from pathlib import Path

from photo3d.cli.progress import count_bar
from photo3d.errors import ConfigError, OutputError, require


def add_parser(sub) -> None:
    """Register ``train`` on the subparsers ``sub``."""
    tr = sub.add_parser(
        "train", help="train one of the learned inpainter's nets on photos with depth",
        description="Train the edge, depth or colour net (paper Sec. 3.3): region pairs "
                    "from photos with depth are pasted onto other photos. Running again "
                    "with the same --out resumes from the last checkpoint.")
    tr.add_argument("kind", choices=["edge", "depth", "color"], help="which net")
    data = tr.add_argument_group("data")
    data.add_argument("--images", required=True, metavar="DIR|builtin",
                      help="folder of photos, or 'builtin' (scikit-image photos and "
                           "synthetic scenes with exact depth, written to RUN_DIR/builtin)")
    data.add_argument("--depth", type=Path, metavar="DIR",
                      help="depth maps named like the photos (PNG, NPY, PFM, TIFF)")
    data.add_argument("--shapes", type=Path, metavar="DIR",
                      help="depth maps used for region shapes only, never as training pixels")
    data.add_argument("--depth-kind", choices=["disparity", "depth"],
                      help="what the depth maps hold (default disparity: near = large)")
    data.add_argument("--region-size", type=int, metavar="PX",
                      help="working size (longer side) of region growth (default 4 x --size)")
    data.add_argument("--builtin-scenes", type=int, default=48, metavar="N",
                      help="synthetic scenes in --images builtin (default 48)")
    data.add_argument("--swap", type=float, metavar="P",
                      help="probability of swapping a region pair's context and synthesis "
                           "(default 0.5, the paper's)")
    data.add_argument("--shape-scenes", type=int, metavar="N",
                      help="photos without any depth map: region shapes from N synthetic "
                           "scenes (default 12)")
    tr.add_argument("-o", "--out", type=Path, required=True, metavar="RUN_DIR",
                    help="run folder: checkpoints, losses.csv, samples/, <kind>.safetensors")
    tr.add_argument("--steps", type=int, help="optimisation steps in total (default 1000)")
    tr.add_argument("--batch", type=int, help="samples per step (default 8, the paper's)")
    tr.add_argument("--size", type=int, help="crop side in pixels (default 256)")
    net = tr.add_argument_group("architecture (compact variants)")
    net.add_argument("--arch", choices=["partialconv", "refine"],
                     help="colour net: the paper's partial-convolution U-Net (default) or "
                          "refine, a residual over the diffusion fill")
    net.add_argument("--width", type=float, help="channel multiplier (default 1.0 = authors')")
    net.add_argument("--channels", type=int,
                     help="refine net: channels at its finest level (default 16)")
    net.add_argument("--levels", type=int,
                     help="U-Net levels, depth/color (default 7; refine 4)")
    net.add_argument("--blocks", type=int,
                     help="residual blocks, edge (default 8) or refine (default 4)")
    net.add_argument("--no-edges", dest="edges", action="store_false", default=None,
                     help="refine net: ignore the edge channel (photos without depth "
                          "never show it one)")
    opt = tr.add_argument_group("optimisation")
    opt.add_argument("--lr", type=float, help="Adam learning rate (default 1e-4)")
    opt.add_argument("--seed", type=int, help="random seed (default 0)")
    opt.add_argument("--gan", choices=["nsgan", "hinge"],
                     help="edge net adversarial loss (default nsgan)")
    opt.add_argument("--adversarial", type=float, metavar="W",
                     help="refine net: weight of a PatchGAN hinge loss (default 0: none; "
                          "may be turned on when resuming)")
    opt.add_argument("--checkpoint-every", type=int, metavar="K",
                     help="checkpoint every K steps (default 500)")
    opt.add_argument("--sample-every", type=int, metavar="K",
                     help="sample grid every K steps (default 500)")
    held = tr.add_argument_group("held-out score (colour net)")
    held.add_argument("--heldout", type=Path, metavar="DIR",
                      help="photos never trained on: the net is scored on them (LPIPS, "
                           "PSNR, SSIM inside pasted regions, as photo3d eval --heldout) "
                           "into RUN_DIR/heldout.csv")
    held.add_argument("--heldout-photos", type=int, default=24, metavar="N",
                      help="score the first N photos of --heldout (default 24)")
    held.add_argument("--heldout-every", type=int, metavar="K",
                      help="score every K steps (default 250)")
    tr.add_argument("--device", help="torch device, e.g. cpu or cuda (default: CUDA if any)")
    tr.add_argument("--threads", type=int, metavar="N",
                    help="CPU threads of torch and photo3d (default: the cores this process "
                         "may use, or PHOTO3D_THREADS; 1 is much faster for compact nets "
                         "when another process keeps the other cores busy)")
    tr.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    tr.set_defaults(run=run)


_TRAIN_OPTIONS = ("arch", "width", "channels", "levels", "blocks", "edges", "size", "batch",
                  "steps", "lr", "seed", "region_size", "depth_kind", "gan", "swap",
                  "adversarial",
                  "checkpoint_every", "sample_every", "heldout_every")


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d train``; returns the exit status.

    Raises:
        OutputError: the disk filled up or is read-only (one line naming the run
            folder; what was written so far is a run the next invocation resumes).
    """
    try:
        return _run(args)
    except OSError as err:
        if err.errno not in _DISK_ERRORS:
            raise
        raise OutputError(f"cannot write in the run folder {args.out}: "
                          f"{err.strerror or err}") from None


_DISK_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS)
"""Write errors of the disk itself (any other OSError is not turned into one line here)."""


def _run(args: argparse.Namespace) -> int:
    torch = require("torch", "learned", purpose="photo3d train", package="PyTorch")
    from photo3d.train import (
        TrainConfig,
        find_training_files,
        parameter_count,
        prepare_data,
        train,
        write_builtin,
    )
    from photo3d.train.bounds import check_request
    from photo3d.train.run_folder import check_checkpoints, check_run, checkpoints, open_run

    options = {k: getattr(args, k) for k in _TRAIN_OPTIONS if getattr(args, k) is not None}
    config = TrainConfig(args.kind, **options)
    try:
        device = torch.device(args.device) if args.device else None
    except RuntimeError:
        raise ConfigError(f"unknown torch device {args.device!r} (try cpu or cuda)") from None
    if device is not None and device.type == "cuda" and not torch.cuda.is_available():
        raise ConfigError("--device cuda: no CUDA device is available")
    if args.shape_scenes is not None and args.shape_scenes < 0:
        raise ConfigError(f"--shape-scenes must be at least 0, got {args.shape_scenes}")
    if args.builtin_scenes < 0:
        raise ConfigError(f"--builtin-scenes must be at least 0, got {args.builtin_scenes}")
    run = args.out
    check_run(run, config)  # refuses a folder that is not a photo3d run; writes nothing
    saved = checkpoints(run)
    check_checkpoints(run, config, start=saved[-1][0] if saved else 0)
    say = (lambda msg: None) if args.quiet else (lambda msg: print(msg, flush=True))

    def bar(total: int, desc: str, initial: int = 0):
        return count_bar(total, desc, quiet=args.quiet, initial=initial)

    if args.images == "builtin":
        if args.depth is not None or args.shapes is not None:
            raise ConfigError("--images builtin brings its own depth: drop --depth/--shapes")
        check_request(config, run, scenes=args.builtin_scenes)  # memory and disk, first
        open_run(run, config)
        folder = run / "builtin"
        if not (folder / "shapes" / "motorcycle.pfm").is_file():  # written last: complete
            side = config.working_size
            with bar(100, "builtin data") as b:
                write_builtin(folder, scenes=args.builtin_scenes, width=side,
                              height=side * 3 // 4,
                              progress=lambda _, f: b.update(round(100 * f) - b.n))
        files = find_training_files(folder / "images", depth=folder / "depth",
                                    shapes=folder / "shapes")
    else:
        files = find_training_files(Path(args.images), depth=args.depth, shapes=args.shapes)
        check_request(config, run, files=files, shape_scenes=args.shape_scenes)
        open_run(run, config)  # marks the folder as a run before the data is prepared
    with bar(100, "prepare") as b:
        shapes = {} if args.shape_scenes is None else {"builtin_shapes": args.shape_scenes}
        data = prepare_data(files, crop=config.size, region_size=config.working_size,
                            depth_kind=config.depth_kind, seed=config.seed,
                            cache=run / "data", **shapes,
                            progress=lambda _, f: b.update(round(100 * f) - b.n))
    data.check(config.kind)
    heldout = None
    if args.heldout is not None:
        if config.kind != "color":
            raise ConfigError("--heldout scores the colour net only")
        if args.heldout_photos < 1:
            raise ConfigError(f"--heldout-photos must be at least 1, got {args.heldout_photos}")
        from photo3d.train.heldout import HeldoutSet

        heldout = HeldoutSet.from_folder(args.heldout, photos=args.heldout_photos)
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

        result = train(data, run, config, device=device, progress=progress, heldout=heldout)
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
    if heldout is not None:
        say(f"held-out scores: {run / 'heldout.csv'}")
    return 0
