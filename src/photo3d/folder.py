"""One photo to a 3D photo folder: what ``photo3d make`` does, and ``photo3d batch``
for every photo.

:class:`MakeOptions` holds everything ``make`` takes besides the photo, its depth
and the output folder (the command line builds it in one place for both commands,
:func:`photo3d.cli.options.make_options`); :func:`prepare` checks what can be
checked before any photo is read and builds the inpainter once;
:func:`make_folder` stages the output folder, reads the photo and its depth
(:mod:`photo3d.depth.sources`), runs :func:`photo3d.make` and saves everything
(:func:`photo3d.output.save_photo`), so a failure leaves nothing behind.

This module imports only the configuration at import time (the command line
imports it before its heavy modules).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from photo3d.config import Config
from photo3d.errors import ConfigError
from photo3d.progress import StageProgress
from photo3d.save_options import SaveOptions

if TYPE_CHECKING:
    import numpy as np

    from photo3d.depth.sources import DepthEstimate
    from photo3d.inpaint.base import Inpainter
    from photo3d.photo import Photo3D

PathLike = str | os.PathLike[str]
OnDepth = Callable[["DepthEstimate", "np.ndarray"], None]
"""``on_depth(estimate, image)`` once the depth and the ``(H, W, 3) float32`` photo
to make are known (before the pipeline runs)."""


@dataclass(frozen=True)
class MakeOptions:
    """Everything ``photo3d make`` takes besides the photo, its depth and the output
    folder; ``photo3d batch`` takes the same for every photo.

    Attributes:
        config: the pipeline configuration (``config.depth_kind`` is replaced per
            photo by what its depth source holds).
        inpainter_options: keyword arguments of the inpainter backend, as
            ``(name, value)`` pairs (a mapping is turned into pairs).
        depth_kind: what a photo's depth map (or chosen model) holds:
            ``"disparity"``, ``"depth"`` or None (a map: disparity; a model: its own
            kind); see :func:`~photo3d.depth.sources.resolve_depth`'s ``kind``.
        depth_model: the monocular model for a photo with no depth source and no
            embedded map (None: the default, see
            :func:`photo3d.depth.fetch.default_depth_model`).
        save: the files of the folder and how they are made
            (:class:`~photo3d.save_options.SaveOptions`), passed whole to
            :meth:`photo3d.Photo3D.save`.
        overwrite: replace a finished output folder (``batch``: redo finished photos).

    Example:
        >>> options = MakeOptions(config=Config(size=512), inpainter_options={"tolerance": 1e-2},
        ...                       save=SaveOptions(glb=False))
        >>> options.inpainter_options, options.save.glb, options.save.full_glb
        ((('tolerance', 0.01),), False, False)
    """

    config: Config = field(default_factory=Config)
    inpainter_options: tuple[tuple[str, object], ...] = ()
    depth_kind: str | None = None
    depth_model: str | None = None
    save: SaveOptions = field(default_factory=SaveOptions)
    overwrite: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.inpainter_options, Mapping):
            object.__setattr__(self, "inpainter_options", tuple(self.inpainter_options.items()))
        if self.depth_kind not in (None, "disparity", "depth"):
            raise ConfigError(f"depth_kind must be 'disparity', 'depth' or None, got "
                              f"{self.depth_kind!r}")

    def inpainter(self) -> Inpainter:
        """A new inpainter of ``config.inpainter`` with ``inpainter_options``.

        Raises:
            ConfigError: unknown backend or bad options (the learned one: bad weights).

        Example:
            >>> MakeOptions(inpainter_options={"iterations": 10}).inpainter().options.iterations
            10
        """
        from photo3d.inpaint import get_inpainter

        return get_inpainter(self.config.inpainter, **dict(self.inpainter_options))

    def weights(self) -> Path | None:
        """The inpainter's weights folder when one is given, else None.

        Example:
            >>> MakeOptions(inpainter_options={"weights": "w"}).weights().name
            'w'
        """
        weights = dict(self.inpainter_options).get("weights")
        return None if weights is None else Path(weights)


EXPORT_BYTES = {"splats.ply": 55, "splats.spz": 6, "splats.glb": 60, "mesh.usdz": 2,
                "quilt": 12}
"""Bytes per squared working size each export adds at least (the bundled sample at
1024 px: 81.4, 9.6, 87.2, 2.7 and 19.0 MB; a square photo has more pixels, a
fragmented LDI more splats, so these round down)."""


def output_bytes(config: Config, save: SaveOptions | None = None) -> int:
    """A low estimate of an output folder's size in bytes (a full disk is refused
    before the work): the LDI and meshes, and ``save``'s videos and exports.

    Example:
        >>> output_bytes(Config(size=1000)) / 1e6
        60.0
        >>> output_bytes(Config(size=1000), SaveOptions(exports=("splats.spz",))) / 1e6
        66.0
    """
    save = save or SaveOptions()
    side = config.size or 1024
    frames = sum(v.frames * (v.size[0] * v.size[1] if v.size else side * side * 0.75)
                 for v in save.videos)
    exports = sum(EXPORT_BYTES[name] for name in save.exports)
    return int((60 + exports) * side * side + 0.02 * frames)


def prepare(options: MakeOptions) -> Inpainter:
    """Check what can be checked before any photo is read, and build the inpainter
    (build it once and pass it to every :func:`make_folder`).

    Checks that memory suffices for a 16:9 photo at ``config.size`` and that its
    ``splats.spz`` cannot pass SPZ's limit (:func:`check_photo_limits`), that the
    packages the exports need are installed and that the OpenGL backend works if
    videos ask for it.

    Raises:
        ConfigError: not enough memory, too many splats for SPZ, no OpenGL, bad
            inpainter or its options.
        ImportError: a missing extra (named in the message).

    Example:
        >>> prepare(MakeOptions(config=Config(size=256))).name
        'structured'
    """
    save = options.save
    check_photo_limits((9, 16), options, at_least=True)
    if save.exports:  # a missing package (usd-core) now, not after the photo is made
        from photo3d.export import require_extras

        require_extras(save.exports, spz_version=save.spz_version)
    if save.videos and save.render_settings and save.render_settings.backend == "gl":
        from photo3d.render.renderer import select_backend

        select_backend("gl")
    return options.inpainter()


def check_photo_limits(shape: tuple[int, int], options: MakeOptions, *,
                       at_least: bool = False) -> None:
    """Refuse, before the work, a photo of ``shape`` ``(H, W)`` whose make with
    ``options`` would fail later: more memory than is available
    (:func:`photo3d.resources.check_memory`, exports included; a video of a given
    size: :func:`photo3d.resources.check_render_memory` of the largest LDI), or
    ``splats.spz``
    with more splats than SPZ holds (the most LDI pixels the working size allows,
    :func:`photo3d.resources.ldi_bound`, docs/outputs.md). ``at_least``: ``shape`` is
    only an aspect ratio (:func:`prepare`'s 16:9).

    Raises:
        ConfigError: one line naming the estimate and what to change.

    Example:
        >>> check_photo_limits((768, 1024), MakeOptions(save=SaveOptions(exports=("splats.spz",))))
        >>> from photo3d.resources import SPZ_LIMIT, ldi_bound
        >>> ldi_bound((9, 16), Config(size=2600)) > SPZ_LIMIT  # refused at --size 2600
        True
    """
    from photo3d.config import working_shape
    from photo3d.resources import (
        SPZ_LIMIT,
        check_memory,
        check_render_memory,
        check_spz_limit,
        ldi_bound,
    )

    config, save = options.config, options.save
    check_memory(shape, config, at_least=at_least, exports=save.exports,
                 splat_fit=save.splat_fit)
    ssaa = save.render_settings.ssaa if save.render_settings is not None else 2
    for spec in save.videos:  # a video larger than the photo: its frames, not the pipeline
        if spec.size is not None:
            check_render_memory(ldi_bound(shape, config), spec.size, ssaa=ssaa,
                                views=2 if spec.stereo else 1, video=True)
    if "splats.spz" not in save.exports:
        return
    h, w = working_shape(shape, config.size)
    size = (f"--size {config.size}" if at_least else f"a {w}x{h} working size")
    bound = ldi_bound(shape, config)
    fits = config.size or max(h, w)
    while fits > 64 and ldi_bound(shape, config.with_(size=fits)) > SPZ_LIMIT:
        fits -= 16
    check_spz_limit(bound, what=f"splats.spz of {size}",
                    advice=f"use --size {fits} or less, or leave splats.spz out and run "
                           "photo3d export afterwards (it counts the splats exactly)")


def make_folder(image: np.ndarray | PathLike, out: PathLike, *,
                options: MakeOptions | None = None,
                depth: np.ndarray | PathLike | None = None, right: PathLike | None = None,
                depth_model: str | PathLike | None = None,
                inpainter: Inpainter | None = None, progress: StageProgress | None = None,
                on_depth: OnDepth | None = None, download_bar=None,
                need_bytes: int | None = None) -> Photo3D:
    """Make one photo into the 3D photo folder ``out``, atomically.

    The output is checked and staged first (:func:`photo3d.output.stage_photo`),
    then the depth is resolved (:func:`photo3d.depth.sources.resolve_depth`:
    ``depth``, ``right`` or ``depth_model`` if one is given, else the photo's
    embedded map, else ``options.depth_model``), the photo read
    (:func:`~photo3d.depth.sources.read_photo`, or the better image the depth
    source carries; a photo more than twice ``options.config.size`` is decoded at
    about twice that size), :func:`photo3d.make` run and the folder written with
    ``options``; nothing appears at ``out`` unless all of it succeeds.

    Args:
        image: the photo, a path or an ``(H, W, 3)`` array.
        out: the output folder (must not exist or be empty unless
            ``options.overwrite``).
        options: :class:`MakeOptions` (default: ``photo3d make``'s defaults).
        depth: a depth file or ``(H, W)`` array (``options.depth_kind``, default
            disparity).
        right: the right view of a rectified stereo pair whose left view is ``image``.
        depth_model: a monocular model to run on the photo (over an embedded map).
        inpainter: a backend built by :func:`prepare` (default: built here).
        progress: ``progress(stage, fraction)``.
        on_depth: ``on_depth(estimate, image)`` once the depth is known, before the
            pipeline runs (the command line prints the source and warnings).
        download_bar: a ``tqdm`` class showing a depth model's download.
        need_bytes: free bytes the output's file system must have (None:
            :func:`output_bytes`).

    Returns:
        The :class:`~photo3d.Photo3D` saved, its ``depth_source`` the estimate's and
        its ``timings`` including ``save`` (or ``save + video``).

    Raises:
        Photo3DError: bad input, output or options (one line; nothing is left at ``out``).

    Example:
        >>> import numpy as np, tempfile
        >>> disp = np.ones((32, 32), np.float32); disp[:, 16:] = 2.0
        >>> out = Path(tempfile.mkdtemp()) / "out"
        >>> photo = make_folder(np.full((32, 32, 3), 0.5), out, depth=disp,
        ...                     options=MakeOptions(config=Config(size=None),
        ...                                         save=SaveOptions(glb=False)))
        >>> photo.depth_source, sorted(p.name for p in out.iterdir())
        ('depth array (disparity)', ['config.json', 'mesh.ply', 'photo3d.npz', 'viewer.html'])
    """
    from photo3d import pipeline
    from photo3d.depth.sources import read_photo, resolve_depth
    from photo3d.io.images import image_shape
    from photo3d.output import stage_photo

    options = options or MakeOptions()
    shape = image_shape(image) if isinstance(image, str | os.PathLike) else None
    if shape is not None:  # from the header, before any decoding
        check_photo_limits(shape, options)
    report = progress or (lambda stage, fraction: None)
    backend = inpainter or options.inpainter()
    inputs = _inputs(image, depth, right, depth_model, options)
    need = (output_bytes(options.config, options.save) if need_bytes is None
            else need_bytes)
    with stage_photo(out, overwrite=options.overwrite, inputs=inputs,
                     need_bytes=need) as staging:  # removed on any error unless committed
        est = resolve_depth(image, depth=depth, right=right, depth_model=depth_model,
                            kind=options.depth_kind,
                            fallback_model=options.depth_model or "default",
                            download_bar=download_bar, working_size=options.config.size)
        photo_image = next((p for p in (est.image, est.photo) if p is not None), None)
        if photo_image is None:
            photo_image = read_photo(image, working_size=options.config.size)
        check_photo_limits(photo_image.shape[:2], options)  # an array, or no header
        if on_depth is not None:
            on_depth(est, photo_image)
        config = options.config.with_(depth_kind=est.kind)
        prepared = est.prepared  # decoded and prepared once, by resolve_depth
        depth_in = est.depth if prepared is None or (
            prepared.disparity.shape != photo_image.shape[:2]) else prepared
        photo = pipeline.make(photo_image, depth=depth_in, config=config, inpainter=backend,
                              progress=progress)
        photo = dataclasses.replace(photo, depth_source=est.source)
        report("mesh", 0.0)
        start = time.perf_counter()
        photo.save(staging, options.save, progress=progress)
        photo.timings["save + video" if options.save.videos else "save"] = (
            time.perf_counter() - start)
        report("video", 1.0)
    return photo


def _inputs(image, depth, right, depth_model, options: MakeOptions) -> list[Path]:
    """The files a run reads (its output folder may not hold any of them)."""
    keyframes = [v.path for v in options.save.videos
                 if Path(v.path).suffix.lower() in (".json", ".yaml", ".yml")]
    given = [image, depth, right, depth_model, options.depth_model, options.weights(),
             *keyframes]
    return [Path(p) for p in given if isinstance(p, str | os.PathLike) and _exists(p)]


def _exists(path: PathLike) -> bool:
    """``Path(path).exists()``, False for a name the file system cannot hold."""
    try:
        return Path(path).exists()
    except (OSError, ValueError):  # too long, NUL byte
        return False
