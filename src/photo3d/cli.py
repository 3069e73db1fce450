"""Command line: ``photo3d make``, ``depth``, ``demo``, ``render``, ``view``, ``eval``, ``train``.

Thin layer over the library: parses arguments, shows a progress bar and a timing
summary, and turns :class:`~photo3d.errors.Photo3DError` into a one-line message
with exit status 2.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from photo3d.cli_commands import (
    _eval_methods,
    _list_files,
    _resolve_depth,
    _run_depth,
    _run_eval,
    _run_render,
    _run_train,
    _run_view,
)
from photo3d.config import PRESETS, Config
from photo3d.errors import ConfigError, Photo3DError

STAGE_LABELS = {
    "load": "load",
    "preprocess": "preprocess",
    "ldi": "LDI",
    "inpaint": "inpaint",
    "mesh": "mesh",
    "save": "save",
}


def _add_depth_sources(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("depth (one of; default: the depth map embedded in the photo)")
    src = g.add_mutually_exclusive_group()
    src.add_argument("--depth", type=Path,
                     help="depth map: PNG (8/16-bit), .npy, .pfm or float TIFF")
    src.add_argument("--right", type=Path,
                     help="right image of a rectified stereo pair (disparity by OpenCV SGM)")
    src.add_argument("--depth-model", metavar="NAME_OR_PATH",
                     help="monocular depth model: a Hugging Face name (e.g. "
                          "depth-anything/Depth-Anything-V2-Small-hf), a local folder or "
                          "an .onnx file")
    g.add_argument("--depth-kind", choices=["disparity", "depth"],
                   help="what --depth holds: disparity (near = large, the default for "
                        "files) or depth (near = small); models and stereo know their kind")


def _add_make_options(p: argparse.ArgumentParser, *, out_required: bool) -> None:
    p.add_argument("-o", "--out", type=Path, required=out_required,
                   help="output folder (must not exist or be empty)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="default",
                   help="named configuration (default: %(default)s)")
    p.add_argument("--size", type=int, help="longer side of the working image in pixels "
                   "(default 1024; 0 keeps the input size)")
    p.add_argument("--inpainter", help="inpainting backend: diffusion (default) or learned")
    p.add_argument("--weights", type=Path, metavar="DIR",
                   help="weights of the learned inpainter: the authors' edge-model.pth, "
                        "depth-model.pth, color-model.pth or photo3d *.safetensors "
                        "(default: the compact nets shipped with photo3d)")
    p.add_argument("--fast-nets", action="store_true",
                   help="learned inpainter: pad the edge net's input to multiples of 8 "
                        "(not 128) and run the nets in bfloat16; about 3x faster on CPU, "
                        "slightly different results")
    p.add_argument("--ply", choices=["binary", "ascii", "none"], default="binary",
                   help="PLY mesh encoding (default: %(default)s)")
    p.add_argument("--no-glb", action="store_true", help="do not write mesh.glb")
    p.add_argument("--no-viewer", action="store_true", help="do not write viewer.html")
    p.add_argument("--no-video", action="store_true",
                   help="do not render the four standard videos")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    _add_video_options(p, command="make")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 1280x720, got {text!r}") from None
    return w, h


def _add_video_options(p: argparse.ArgumentParser, *, command: str) -> None:
    g = p.add_argument_group("video")
    g.add_argument("--path", dest="paths", action="append", default=None,
                   metavar="NAME|FILE",
                   help="camera path: dolly-zoom-in, zoom-in, circle, swing or a JSON/YAML "
                        "keyframe file (repeatable; make renders all four presets by default)")
    # `make` uses --size for the working size; `render` has no such option
    names = ["--video-size", "--resolution"] + (["--size"] if command == "render" else [])
    g.add_argument(*names, dest="video_size", type=_size,
                   metavar="WxH", help="video size, even numbers (default: the photo's size)")
    g.add_argument("--fps", type=float, default=40.0, help="frames per second (default 40)")
    g.add_argument("--frames", type=int, default=240, help="frames per video (default 240)")
    g.add_argument("--format", choices=["mp4", "webm", "gif"], default="mp4",
                   help="video format (default mp4: H.264, yuv420p)")
    g.add_argument("--ssaa", type=int, default=2, help="supersampling factor (default 2)")
    g.add_argument("--no-crop", action="store_true",
                   help="do not crop the frame border like the authors' videos")
    g.add_argument("--backend", choices=["auto", "numba", "gl"], default="auto",
                   help="rasterizer (default auto: OpenGL on a GPU, else numba on the CPU)")
    g.add_argument("--stereo", choices=["sbs", "sbs-half", "anaglyph"],
                   help="render stereo videos: side by side (full or half width) or "
                        "red-cyan anaglyph")
    g.add_argument("--eye-separation", type=float, default=0.01,
                   help="stereo eye distance in depth units (default 0.01)")
    g.add_argument("--eye-order", choices=["lr", "rl"], default="lr",
                   help="side-by-side order: lr (parallel) or rl (cross-eyed)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="photo3d",
        description="Turn a photo and its depth into a 3D photo (layered depth image, "
                    "inpainted occlusions, meshes).",
    )
    from photo3d import __version__

    parser.add_argument("--version", action="version", version=f"photo3d {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    mk = sub.add_parser("make", help="make a 3D photo from an image and a depth map")
    mk.add_argument("image", type=Path, help="JPEG, PNG, TIFF, WebP or HEIC photo")
    _add_depth_sources(mk)
    _add_make_options(mk, out_required=True)
    dp = sub.add_parser("depth", help="write the depth map the pipeline would use "
                        "(16-bit PNG + colour preview) to inspect or edit")
    dp.add_argument("image", type=Path, help="JPEG, PNG, TIFF, WebP or HEIC photo")
    _add_depth_sources(dp)
    dp.add_argument("-o", "--out", type=Path, required=True, help="output PNG (16-bit)")
    demo = sub.add_parser("demo", help="make a 3D photo of the bundled Middlebury sample")
    _add_make_options(demo, out_required=False)
    demo.set_defaults(out=Path("out/demo"))
    rd = sub.add_parser("render", help="render videos of a saved 3D photo (no recomputing)")
    rd.add_argument("photo", type=Path, help="a 3D photo folder written by make")
    _add_video_options(rd, command="render")
    vw = sub.add_parser("view", help="serve a 3D photo folder on 127.0.0.1 and open its viewer")
    vw.add_argument("photo", type=Path, help="a 3D photo folder written by make")
    vw.add_argument("--port", type=int, default=0, help="port (default: any free one)")
    vw.add_argument("--no-browser", action="store_true", help="only print the URL")
    ev = sub.add_parser("eval", help="score novel views against a real second view")
    src = ev.add_mutually_exclusive_group()
    src.add_argument("--pair", nargs=4, metavar=("LEFT", "RIGHT", "DISP", "CALIB"),
                     help="a rectified pair: images, left disparity (PFM: inf = unknown, or "
                          "PNG: 0 = unknown) and a Middlebury calib.txt")
    src.add_argument("--synthetic", type=int, metavar="N",
                     help="N synthetic layered scenes with exact ground truth (seeds 0..N-1)")
    ev.add_argument("--methods", default=",".join(_eval_methods()),
                    help="comma-separated methods (default: all)")
    ev.add_argument("--weights", type=Path, help="learned inpainter weights folder "
                    "(default: the compact nets shipped with photo3d; 'random': the "
                    "authors' architectures with random weights)")
    ev.add_argument("--no-lpips", action="store_true", help="skip LPIPS (needs torch)")
    ev.add_argument("-o", "--out", type=Path, default=Path("out/eval"),
                    help="results folder (default out/eval)")
    ev.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    rd.add_argument("--still", action="store_true",
                    help="write one image of the input view (stereo with --stereo) to "
                         "PHOTO/still[_MODE].png instead of videos")
    rd.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    _add_train_parser(sub)
    return parser


def _add_train_parser(sub) -> None:
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
    tr.add_argument("-o", "--out", type=Path, required=True, metavar="RUN_DIR",
                    help="run folder: checkpoints, losses.csv, samples/, <kind>.safetensors")
    tr.add_argument("--steps", type=int, help="optimisation steps in total (default 1000)")
    tr.add_argument("--batch", type=int, help="samples per step (default 8, the paper's)")
    tr.add_argument("--size", type=int, help="crop side in pixels (default 256)")
    net = tr.add_argument_group("architecture (compact variants)")
    net.add_argument("--width", type=float, help="channel multiplier (default 1.0 = authors')")
    net.add_argument("--levels", type=int, help="U-Net levels, depth/color (default 7)")
    net.add_argument("--blocks", type=int, help="residual blocks, edge (default 8)")
    opt = tr.add_argument_group("optimisation")
    opt.add_argument("--lr", type=float, help="Adam learning rate (default 1e-4)")
    opt.add_argument("--seed", type=int, help="random seed (default 0)")
    opt.add_argument("--gan", choices=["nsgan", "hinge"],
                     help="edge net adversarial loss (default nsgan)")
    opt.add_argument("--checkpoint-every", type=int, metavar="K",
                     help="checkpoint every K steps (default 500)")
    opt.add_argument("--sample-every", type=int, metavar="K",
                     help="sample grid every K steps (default 500)")
    tr.add_argument("--device", help="torch device, e.g. cpu or cuda (default: CUDA if any)")
    tr.add_argument("--threads", type=int, metavar="N",
                    help="CPU threads of torch (default: torch's choice; 1 is much faster for "
                         "compact nets when another process keeps the other cores busy)")
    tr.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")


def _config(args: argparse.Namespace, **changes) -> Config:
    cfg = PRESETS[args.preset]
    if args.size is not None:
        changes["size"] = None if args.size == 0 else args.size
    if args.inpainter:
        changes["inpainter"] = args.inpainter
    return cfg.with_(**changes)


def _videos(args: argparse.Namespace) -> list:
    from photo3d.render.animate import VideoSpec
    from photo3d.render.paths import PRESETS

    paths = args.paths or list(PRESETS)
    return [VideoSpec(path=p, size=args.video_size, fps=args.fps, frames=args.frames,
                      format=args.format, stereo=args.stereo,
                      eye_separation=args.eye_separation, eye_order=args.eye_order)
            for p in paths]


def _render_settings(args: argparse.Namespace):
    from photo3d.render.renderer import AUTHORS_CROP, RenderSettings

    return RenderSettings(ssaa=args.ssaa, crop=(0.0,) * 4 if args.no_crop else AUTHORS_CROP,
                          backend=args.backend)


class _Bar:
    """Stage-aware progress bar (tqdm on stderr)."""

    def __init__(self, quiet: bool) -> None:
        self.bar = None
        if not quiet:
            from tqdm import tqdm

            self.bar = tqdm(total=100, bar_format="{desc:<12}{bar}| {percentage:3.0f}% "
                            "[{elapsed}]", file=sys.stderr, leave=False,
                            disable=None)  # no bar when stderr is not a terminal
        self.weights = {"load": 1, "preprocess": 4, "ldi": 1, "inpaint": 20, "mesh": 1,
                        "save": 3, "video": 70}
        self.stage = None

    def __call__(self, stage: str, fraction: float) -> None:
        if self.bar is None:
            return
        order = list(self.weights)
        base = sum(self.weights[s] for s in order[: order.index(stage)])
        value = base + self.weights[stage] * fraction
        if stage != self.stage:
            self.stage = stage
            self.bar.set_description_str(STAGE_LABELS.get(stage, stage), refresh=False)
        self.bar.update(max(0.0, value - self.bar.n))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _run_make(args: argparse.Namespace, image, depth, config: Config) -> int:
    """Validate everything cheap first, then resolve depth (if a callable), make, save.

    ``depth`` may be a callable returning ``(image, depth, depth_kind)``: it runs
    only after the options are known to be valid (it can be slow: stereo, models).
    """
    from photo3d.inpaint import get_inpainter
    from photo3d.output import check_output
    from photo3d.pipeline import make

    check_output(args.out, overwrite=args.overwrite)
    videos = [] if args.no_video else _videos(args)
    settings = _render_settings(args)
    backend = get_inpainter(config.inpainter, **_inpainter_options(args, config.inpainter))
    if callable(depth):
        image, depth, kind = depth()
        config = config.with_(depth_kind=kind)
    bar = _Bar(args.quiet)
    try:
        photo = make(image, depth=depth, config=config, inpainter=backend, progress=bar)
        bar("mesh", 0.0)
        t = time.perf_counter()
        photo.save(args.out, overwrite=args.overwrite,
                   ply=None if args.ply == "none" else args.ply, glb=not args.no_glb,
                   viewer=not args.no_viewer, videos=videos, render_settings=settings,
                   progress=bar)
        photo.timings["save + video" if videos else "save"] = time.perf_counter() - t
        bar("video", 1.0)
    finally:
        bar.close()
    if not args.quiet:
        _summary(photo, args.out)
    return 0


def _inpainter_options(args: argparse.Namespace, inpainter: str) -> dict:
    weights, fast = getattr(args, "weights", None), getattr(args, "fast_nets", False)
    flags = [f for f, on in (("--weights", weights is not None), ("--fast-nets", fast)) if on]
    if flags and inpainter != "learned":
        raise ConfigError(f"{' and '.join(flags)} only apply to --inpainter learned (this "
                          f"run uses {inpainter})")
    options = {} if weights is None else {"weights": weights}
    return {**options, **(dict(edge_unit=8, precision="bf16") if fast else {})}


def _summary(photo, out: Path) -> None:
    w, h = photo.stats["working_size"]
    print(f"3D photo written to {out}/ ({w}x{h}, {photo.ldi.size:,} LDI pixels, "
          f"{photo.stats['passes']} inpainting pass(es), edges per pass {photo.stats['edges']})")
    total = sum(photo.timings.values())
    parts = ", ".join(f"{STAGE_LABELS.get(k, k)} {v:.2f}s" for k, v in photo.timings.items())
    print(f"time: {total:.2f}s ({parts})")
    _list_files(out)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``photo3d`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"photo3d: warning: {message}", file=sys.stderr)

    warnings.showwarning = show
    try:
        if args.command == "make":
            from photo3d.depth.sources import load_photo

            def depth():
                est = _resolve_depth(args)
                image = est.image if est.image is not None else load_photo(args.image)
                return image, est.depth, est.kind

            return _run_make(args, None, depth, _config(args))
        if args.command == "depth":
            return _run_depth(args)
        if args.command == "render":
            return _run_render(args)
        if args.command == "eval":
            return _run_eval(args)
        if args.command == "view":
            return _run_view(args)
        if args.command == "train":
            return _run_train(args)
        if args.command == "demo":
            from photo3d.data import motorcycle

            sample = motorcycle()
            if not args.quiet:
                print("sample: Middlebury 2014 'Motorcycle' left view with its ground-truth "
                      "disparity (unknown pixels filled with the farther row neighbour)")
            return _run_make(args, sample.left, np.asarray(sample.disparity), _config(args))
    except Photo3DError as err:
        print(f"photo3d: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("photo3d: interrupted", file=sys.stderr)
        return 130
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
