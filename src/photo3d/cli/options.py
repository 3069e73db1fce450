"""Option groups shared by several subcommands, and their conversion to library objects.

``add_*`` functions register arguments on a parser; the others turn the parsed
``argparse.Namespace`` into what the library takes (a :class:`~photo3d.config.Config`,
video specs, render settings, inpainter options, and all of them together: the
:class:`~photo3d.folder.MakeOptions` of ``make``, ``demo`` and ``batch``, built in
:func:`make_options` only).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from photo3d.cli.progress import download_bar
from photo3d.config import EDGES, PRESETS, Config
from photo3d.errors import ConfigError, InputError
from photo3d.save_options import EXPORT_FORMATS, SPLAT_DENSITIES, SPZ_VERSIONS


def add_depth_sources(p: argparse.ArgumentParser) -> None:
    """``--depth`` / ``--right`` / ``--depth-model`` (one of) and ``--depth-kind``."""
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


AUTHORS = "authors"
"""The ``--weights`` value that means the authors' published weights."""
COMPACT = "compact"
"""The ``--weights`` value that means the small nets shipped with photo3d."""


def weights_arg(text: str) -> Path | str:
    """Parse ``--weights``: the literal ``authors`` (:data:`AUTHORS`, the authors'
    weights) or ``compact`` (:data:`COMPACT`), else a folder (``./authors`` is a
    folder named authors).

    >>> weights_arg("authors"), isinstance(weights_arg("./authors"), Path)
    ('authors', True)
    """
    return text if text in (AUTHORS, COMPACT) else Path(text)


def weights_folder(weights: Path | str | None, *, quiet: bool) -> Path | None:
    """``--weights`` (as :func:`weights_arg` parses it) as a folder: :data:`AUTHORS`
    becomes the authors' weights' folder in the cache, where they are downloaded
    first if needed, with a progress bar on stderr unless ``quiet``
    (:func:`photo3d.nets.authors.authors_weights`); :data:`COMPACT` the shipped
    compact nets' folder; a folder is returned as it is.

    Raises:
        InputError: the authors' weights are not in the cache and cannot be
            downloaded (offline), or a file there or a download is not theirs.

    >>> weights_folder(Path("w"), quiet=True).name
    'w'
    """
    if isinstance(weights, str) and weights == COMPACT:
        from photo3d.inpaint.learned import bundled_weights

        return bundled_weights()
    if not (isinstance(weights, str) and weights == AUTHORS):
        return weights
    from photo3d.nets.authors import authors_weights

    bars = _DownloadBars(quiet)
    try:
        return authors_weights(progress=bars)
    finally:
        bars.close()


class _DownloadBars:
    """``progress(name, done, total)`` of several downloads: one line saying what is
    downloaded from where, then a byte bar per file (``tqdm`` on stderr when it is a
    terminal); nothing when ``quiet``."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.name: str | None = None
        self.bar = None

    def __call__(self, name: str, done: int, total: int | None) -> None:
        if self.quiet:
            return
        if name != self.name:
            if self.name is None:
                from photo3d.nets.authors import authors_folder, authors_url

                print(f"downloading the authors' weights from {authors_url()} into "
                      f"{authors_folder()}", file=sys.stderr, flush=True)
            self.close()
            self.name = name
            self.bar = download_bar(False)(total=total, desc=name, unit="B",
                                           unit_scale=True, unit_divisor=1024)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def add_make_options(p: argparse.ArgumentParser, *, out_required: bool,
                     out_help: str = "output folder (must not exist or be empty)",
                     overwrite_help: str = "replace an existing output folder") -> None:
    """Everything ``make`` takes besides the photo and its depth (also ``demo``'s and
    ``batch``'s)."""
    p.add_argument("-o", "--out", type=Path, required=out_required, help=out_help)
    p.add_argument("--preset", choices=sorted(PRESETS), default="default",
                   help="named configuration (default: %(default)s)")
    p.add_argument("--size", type=int, help="longer side of the working image in pixels "
                   "(default 1024; 0 keeps the input size)")
    p.add_argument("--inpainter", help="inpainting backend: structured (default), diffusion "
                   "or learned")
    p.add_argument("--edges", choices=EDGES, default="soft",
                   help="where the depth edges go: soft (default) moves each depth step "
                        "onto the photo's colour edge within a few pixels (depth from "
                        "networks and stereo is fat or smooth at silhouettes) and gives "
                        "the mixed pixels along each silhouette a coverage (alpha); align "
                        "only moves the steps; exact keeps them where the depth map puts "
                        "them")
    p.add_argument("--weights", type=weights_arg, metavar="DIR|authors|compact",
                   help="weights of the learned inpainter: a folder with the authors' "
                        "edge-model.pth, depth-model.pth, color-model.pth or photo3d "
                        "*.safetensors; 'authors' (the default): the paper's nets, the "
                        "authors' published files, downloaded once into the cache; "
                        "'compact': the small nets shipped with photo3d (a folder named "
                        "authors or compact: ./authors)")
    p.add_argument("--fast-nets", action="store_true",
                   help="learned inpainter: pad the edge net's input to multiples of 8 "
                        "(not 128) and run the nets in bfloat16; about 3x faster on CPU, "
                        "slightly different results")
    p.add_argument("--ply", choices=["binary", "ascii", "none"], default="binary",
                   help="PLY mesh encoding (default: %(default)s)")
    p.add_argument("--no-glb", action="store_true", help="do not write mesh.glb")
    p.add_argument("--full-glb", action="store_true",
                   help="mesh.glb with every LDI pixel as a vertex-coloured vertex (large) "
                        "instead of the light textured mesh")
    p.add_argument("--no-viewer", action="store_true", help="do not write viewer.html")
    p.add_argument("--no-video", action="store_true",
                   help="do not render the four standard videos")
    p.add_argument("--export", dest="exports", action="append", choices=EXPORT_FORMATS,
                   metavar="FORMAT",
                   help="also write FORMAT into the folder, as photo3d export does "
                        "(repeatable): " + ", ".join(EXPORT_FORMATS))
    add_splat_options(p)
    p.add_argument("--overwrite", action="store_true", help=overwrite_help)
    add_video_options(p, command="make")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")


def add_splat_options(p: argparse.ArgumentParser) -> None:
    """``--splats`` and ``--spz-version``: how the splat exports are made (``export``,
    and ``make``, ``demo`` and ``batch`` with ``--export``)."""
    p.add_argument("--splats", choices=SPLAT_DENSITIES, default=SPLAT_DENSITIES[0],
                   help="splat exports: adaptive (the default: one splat per pixel where "
                        "there is texture and at depth edges, fewer and larger where the "
                        "photo is flat) or dense (one splat per LDI pixel)")
    p.add_argument("--spz-version", type=int, choices=SPZ_VERSIONS, default=SPZ_VERSIONS[0],
                   help="splats.spz: version 3 (the default: gzip; Spark 2, three.js, "
                        "SuperSplat) or 4 (zstd streams; three.js, SuperSplat, PlayCanvas; "
                        "needs photo3d[spz4])")
    p.add_argument("--splat-fit", action=argparse.BooleanOptionalAction, default=True,
                   help="splat exports: fit the splats' colours to photo3d's render "
                        "through a splat renderer's blend (Spark's), so that splat "
                        "viewers show the photo sharper (the default; --no-splat-fit: "
                        "each splat keeps its pixels' colour, about a second less)")


def check_photo_folder(photo: Path) -> None:
    """Refuse a file given where ``render``, ``export`` and ``view`` take a 3D photo
    folder (most often its ``photo3d.npz``), before anything is read or written; a
    missing folder is left to the command, which says there is no 3D photo there.

    Raises:
        InputError: ``photo`` is a file (or anything else that exists and is not a
            folder).

    Example:
        >>> import tempfile
        >>> npz = Path(tempfile.mkdtemp()) / "photo3d.npz"
        >>> _ = npz.write_bytes(b"")
        >>> check_photo_folder(npz)
        Traceback (most recent call last):
        ...
        photo3d.errors.InputError: .../photo3d.npz is a file: give the 3D photo's folder (...)
    """
    from photo3d.owned import LDI_FILE

    if os.path.exists(photo) and not os.path.isdir(photo):
        advice = f" ({photo.parent})" if photo.name == LDI_FILE else ", written by make"
        raise InputError(f"{photo} is a file: give the 3D photo's folder{advice}")


def video_size(text: str) -> tuple[int, int]:
    """Parse ``WxH``.

    >>> video_size("1280x720")
    (1280, 720)
    """
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 1280x720, got {text!r}") from None
    return w, h


def add_video_options(p: argparse.ArgumentParser, *, command: str) -> None:
    """The ``video`` group of ``make`` and ``render`` (``render`` also takes ``--size``)."""
    g = p.add_argument_group("video")
    g.add_argument("--path", dest="paths", action="append", default=None,
                   metavar="NAME|FILE",
                   help="camera path: dolly-zoom-in, zoom-in, circle, swing or a JSON/YAML "
                        "keyframe file (repeatable; make renders all four presets by default)")
    # `make` uses --size for the working size; `render` has no such option
    names = ["--video-size", "--resolution"] + (["--size"] if command == "render" else [])
    g.add_argument(*names, dest="video_size", type=video_size,
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


def config_from(args: argparse.Namespace, **changes) -> Config:
    """The :class:`Config` of ``--preset``, ``--size``, ``--inpainter`` and ``--edges``."""
    cfg = PRESETS[args.preset]
    if args.size is not None:
        changes["size"] = None if args.size == 0 else args.size
    if args.inpainter:
        changes["inpainter"] = args.inpainter
    if getattr(args, "edges", None):
        changes["edges"] = args.edges
    return cfg.with_(**changes)


def videos_from(args: argparse.Namespace) -> list:
    """One ``VideoSpec`` per ``--path`` (default: the four presets)."""
    from photo3d.render.animate import VideoSpec
    from photo3d.render.paths import STANDARD_PATHS

    paths = args.paths or list(STANDARD_PATHS)
    videos = [VideoSpec(path=p, size=args.video_size, fps=args.fps, frames=args.frames,
                        format=args.format, stereo=args.stereo,
                        eye_separation=args.eye_separation, eye_order=args.eye_order)
              for p in paths]
    if not getattr(args, "still", False):  # a still is a PNG: no encoder limit
        check_video_sizes([v for v in videos if v.size is not None])  # before any work
    return videos


def check_video_sizes(videos, photo_size: tuple[int, int] | None = None) -> None:
    """Refuse a video its encoder would not open (``--stereo sbs`` doubles the width),
    before any work. ``photo_size``: ``(width, height)`` of the photo, the size of
    videos without one (None: check only videos with a size).

    Raises:
        ConfigError: one line (:func:`photo3d.io.video.check_video_size`).
    """
    from photo3d.io.video import check_video_size

    for spec in videos:
        width, height = spec.size or photo_size
        if spec.stereo != "sbs":
            check_video_size((width, height), spec.format)
            continue
        try:
            check_video_size((2 * width, height), spec.format)
        except ConfigError as err:
            raise ConfigError(f"--stereo sbs doubles the width: {err}") from None


def render_settings_from(args: argparse.Namespace):
    """The ``RenderSettings`` of ``--ssaa``, ``--no-crop`` and ``--backend``."""
    from photo3d.render.renderer import video_settings

    return video_settings(crop=not args.no_crop, ssaa=args.ssaa, backend=args.backend)


def inpainter_options(args: argparse.Namespace, inpainter: str) -> dict:
    """Keyword arguments of the inpainter from ``--weights`` and ``--fast-nets``
    (``--weights authors``: the authors' weights' folder, downloaded first if needed:
    :func:`weights_folder`).

    Raises ConfigError when they are given for a backend that has no weights.
    """
    weights, fast = getattr(args, "weights", None), getattr(args, "fast_nets", False)
    flags = [f for f, on in (("--weights", weights is not None), ("--fast-nets", fast)) if on]
    if flags and inpainter != "learned":
        raise ConfigError(f"{' and '.join(flags)} only apply to --inpainter learned (this "
                          f"run uses {inpainter})")
    if inpainter == "learned" and weights is None:
        weights = AUTHORS  # the paper's nets, downloaded once (with a bar, unless -q)
    weights = weights_folder(weights, quiet=getattr(args, "quiet", False))
    options = {} if weights is None else {"weights": weights}
    return {**options, **(dict(edge_unit=8, precision="bf16") if fast else {})}


def make_options(args: argparse.Namespace):
    """The :class:`~photo3d.folder.MakeOptions` of ``make``, ``demo`` and ``batch``
    (the options :func:`add_make_options` registers, plus ``--depth-kind`` and
    ``--depth-model``): the one place they are read, so every command takes them alike.

    Raises:
        ConfigError: a bad option (video size, ``--weights`` without the learned
            inpainter, ...).

    Example:
        >>> from photo3d.cli import build_parser
        >>> args = build_parser().parse_args(["batch", "in", "-o", "o", "--full-glb",
        ...                                   "--no-video", "--size", "512",
        ...                                   "--export", "splats.spz"])
        >>> options = make_options(args)
        >>> options.save.full_glb, options.save.videos, options.config.size
        (True, (), 512)
        >>> options.save.exports, options.save.splats, options.save.spz_version
        (('splats.spz',), 'adaptive', 3)
    """
    from photo3d.folder import MakeOptions
    from photo3d.save_options import SaveOptions

    config = config_from(args)
    inpainter = inpainter_options(args, config.inpainter)
    return MakeOptions(config=config, inpainter_options=tuple(inpainter.items()),
                       depth_kind=getattr(args, "depth_kind", None),
                       depth_model=getattr(args, "depth_model", None),
                       save=SaveOptions(
                           ply=None if args.ply == "none" else args.ply, glb=not args.no_glb,
                           full_glb=args.full_glb, viewer=not args.no_viewer,
                           videos=() if args.no_video else tuple(videos_from(args)),
                           render_settings=render_settings_from(args),
                           exports=tuple(args.exports or ()),
                           splats=args.splats, spz_version=args.spz_version,
                           splat_fit=args.splat_fit),
                       overwrite=args.overwrite)


def depth_from_args(args: argparse.Namespace):
    """Resolve the depth of ``args.image`` from the depth options; say where it came
    from (``photo3d depth``; ``make`` resolves it in :func:`photo3d.folder.make_folder`)."""
    from photo3d.depth.sources import resolve_depth

    est = resolve_depth(args.image, depth=args.depth, right=args.right,
                        depth_model=args.depth_model, kind=args.depth_kind,
                        download_bar=download_bar(getattr(args, "quiet", False)))
    say_depth(est, quiet=getattr(args, "quiet", False))
    return est


def say_depth(est, *, quiet: bool, source: bool = True) -> None:
    """Print where a :class:`~photo3d.depth.sources.DepthEstimate` came from (unless
    ``quiet`` or not ``source``) and its warnings (always), on stderr."""
    if source and not quiet:
        print(f"depth: {est.source}", file=sys.stderr)
    for warning in est.warnings:
        print(f"photo3d: warning: {warning}", file=sys.stderr)


def list_files(out: Path) -> None:
    """Print every file under ``out`` with its size in MB."""
    for path in sorted(p for p in out.rglob("*") if p.is_file()):
        print(f"  {str(path.relative_to(out)):<24} {path.stat().st_size / 1e6:8.2f} MB")
