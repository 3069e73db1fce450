"""``make``: image + depth -> :class:`Photo3D`. Wires the stages, holds no algorithm."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from concurrent.futures import Future
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics, check_intrinsics
from photo3d.config import Config
from photo3d.depth.normalize import DepthInput, prepare_depth
from photo3d.depth.sources import describe_depth, read_photo
from photo3d.errors import ConfigError, InputError
from photo3d.inpaint import get_inpainter
from photo3d.inpaint.base import Inpainter
from photo3d.inpaint.frame import fill_frame
from photo3d.io.depth import read_depth
from photo3d.io.images import MIN_SIDE, image_shape
from photo3d.parallel import ahead, overlap
from photo3d.photo import Photo3D
from photo3d.progress import CountProgress, StageProgress
from photo3d.resources import check_memory
from photo3d.stages.border import fill_border
from photo3d.stages.merge import Merged, take
from photo3d.stages.passes import (
    PassInput,
    PassPlan,
    border_readers,
    merge_pass,
    pass_regions,
    patch_batches,
    plan_pass,
    start,
)
from photo3d.stages.patches import PatchJob
from photo3d.stages.preprocess import Preprocessed, preprocess
from photo3d.stages.silhouettes import paint_behind
from photo3d.structures.ldi import LDI
from photo3d.structures.patch import Patch


def make(
    image: np.ndarray | str | Path,
    *,
    depth: np.ndarray | str | Path | DepthInput,
    config: Config | None = None,
    intrinsics: Intrinsics | None = None,
    inpainter: Inpainter | None = None,
    progress: StageProgress | None = None,
) -> Photo3D:
    """Turn an RGB-D photo into a 3D photo.

    Args:
        image: path (JPEG, PNG, TIFF, WebP, or HEIF/HEIC with the ``heif`` extra:
            :func:`~photo3d.depth.sources.read_photo`, the command line's reader)
            or array (``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``; uint8, uint16 or
            float in [0, 1]).
        depth: path or ``(H, W)`` array of disparity (default) or depth
            (``config.depth_kind``); NaN/inf/negative values are filled. Or a
            :class:`~photo3d.depth.normalize.DepthInput` already prepared for that kind
            (:attr:`~photo3d.depth.sources.DepthEstimate.prepared`).
        config: :class:`Config` (defaults: 1024 px, structured inpainting, depth steps
            moved onto the photo's colour edges: ``edges="align"``). With
            ``config.metric`` (and ``depth_kind="depth"``) the geometry keeps the
            depth's own units instead of the authors' [1/3, 20] range.
        intrinsics: the camera of the input image (at the input's resolution; it is
            scaled to the working size; finite, ``fx, fy > 0``). Default: focal
            ``max(H, W)``, centred.
        inpainter: a backend instance overriding ``config.inpainter``.
        progress: optional ``progress(stage, fraction)`` callback.

    Returns:
        :class:`Photo3D`, with the backend's settings (:func:`inpainter_settings`) and
        a depth source naming the depth file or array.

    Example:
        >>> import photo3d
        >>> img = np.random.default_rng(0).random((64, 96, 3)).astype(np.float32)
        >>> disp = np.ones((64, 96), np.float32); disp[16:48, 32:64] = 3.0
        >>> photo = photo3d.make(img, depth=disp, config=photo3d.Config(size=None))
        >>> photo.stats["edges"][0] > 0, photo.ldi.size > 64 * 96
        (True, True)
    """
    from photo3d.kernel_cache import adopt

    config = Config() if config is None else config
    if not isinstance(config, Config):
        raise ConfigError(f"config must be a photo3d.Config, got a {type(config).__name__}")
    _check_arguments(inpainter, intrinsics, progress)
    backend = inpainter or get_inpainter(config.inpainter)
    report = progress or (lambda stage, fraction: None)
    adopt()  # the wheel's compiled kernels, if they fit (once per process)
    timings: dict[str, float] = {}
    t = time.perf_counter()

    def done(stage: str) -> None:
        nonlocal t
        now = time.perf_counter()
        timings[stage] = now - t
        t = now
        report(stage, 1.0)

    img, dep = _load(image, depth, config)
    if intrinsics is not None:
        _check_intrinsics(intrinsics, img.shape[:2])
    done("load")
    pre = preprocess(img, dep.disparity, config=config)
    done("preprocess")

    state = _first_pass_input(pre, img.shape[:2], config, intrinsics)
    h, w = pre.image.shape[:2]
    behind = state.behind  # the soft silhouettes' background, painted after the passes
    scale = max(w / img.shape[1], h / img.shape[0])
    reg = config.regions
    with overlap(name="frame") as side:
        frame = None  # the frame's colours, filled beside the first pass
        if reg.border_fill != "replicate":
            border = partial(fill_border, state.ldi,
                             _border_fill(reg.border_fill, backend, scale),
                             context=config.spatial(reg.border_context, pre.working_size))
            if getattr(backend, "patchwise", False) and state.edge_pixels.size:
                # the first pass fills the patches that do not read the frame meanwhile
                # (the same result; about 0.6 s less on 2 cores for the sample)
                frame = side.submit(border)
            else:
                state = replace(state, ldi=border())
        done("ldi")  # without the frame when it is filled meanwhile (it then counts
        # in "inpaint")
        edges_per_pass, added_per_pass = [], []
        for k in range(reg.max_passes):
            if state.edge_pixels.size == 0:
                break
            # a backend may want thinner contexts after the first pass (learned: the
            # authors'), or the paper's contexts only (learned: its nets were trained
            # on those)
            plan = plan_pass(config, pre.working_size, margin=backend.margin, scale=scale,
                             pass_index=k,
                             later_context=getattr(backend, "later_context", 1.0),
                             paper_context=getattr(backend, "paper_context", False))
            merged = fill_pass(state, plan, backend, pass_index=k,
                               frame=frame if k == 0 else None,
                               progress=lambda i, n, k=k: report(
                                   "inpaint", (k + i / max(n, 1)) / reg.max_passes))
            edges_per_pass.append(state.edges)
            added_per_pass.append(merged.added)
            state = PassInput(merged.ldi, merged.edge_ptr, merged.edge_pixels, merged.index)
    if behind is not None:
        state = replace(state, ldi=paint_behind(state.ldi, behind, index=state.index,
                                                threshold=config.preprocess.discontinuity))
    done("inpaint")

    return Photo3D(
        ldi=state.ldi,
        config=config,
        timings=timings,
        inpainter=inpainter_settings(backend),
        depth_source=describe_depth(depth, config.depth_kind),
        stats={
            "working_size": [pre.image.shape[1], pre.image.shape[0]],
            "edges": edges_per_pass,
            "pixels_added": added_per_pass,
            "passes": len(edges_per_pass),
            "unknown_depth_filled": int(dep.unknown.sum()),
            "disparity_range": list(pre.disparity_range),
        },
    )


def _load(image: np.ndarray | str | Path, depth: np.ndarray | str | Path | DepthInput,
          config: Config) -> tuple[np.ndarray, DepthInput]:
    """The photo and its prepared depth, the photo's size and the memory checked (for a
    file, from its header first: before a pixel is decoded)."""
    check_photo_memory(image, config)
    img = read_photo(image)
    if min(img.shape[:2]) < MIN_SIDE:
        raise InputError(f"image is {img.shape[1]}x{img.shape[0]} pixels; photo3d needs at "
                         f"least {MIN_SIDE}x{MIN_SIDE}")
    check_memory(img.shape[:2], config)
    if isinstance(depth, DepthInput) and depth.disparity.shape == img.shape[:2]:
        return img, depth  # already prepared (make_folder: by resolve_depth) for this kind
    raw = read_depth(depth) if isinstance(depth, str | Path) else np.asarray(depth)
    return img, prepare_depth(raw, img.shape[:2], kind=config.depth_kind)


def _check_arguments(inpainter: object, intrinsics: object, progress: object) -> None:
    """Refuse an ``inpainter`` that is no backend (a name belongs in ``config``),
    ``intrinsics`` that are not :class:`Intrinsics` and a ``progress`` that cannot be
    called, before the work."""
    if inpainter is not None and not (isinstance(getattr(inpainter, "name", None), str)
                                      and hasattr(inpainter, "margin")
                                      and callable(getattr(inpainter, "inpaint", None))):
        hint = (f"; for a backend by name use config=Config(inpainter={inpainter!r})"
                if isinstance(inpainter, str) else "")
        raise ConfigError(f"inpainter must be an inpainting backend "
                          f"(photo3d.inpaint.get_inpainter), got a "
                          f"{type(inpainter).__name__}{hint}")
    if intrinsics is not None and not isinstance(intrinsics, Intrinsics):
        raise InputError(f"intrinsics must be a photo3d.camera.Intrinsics, got a "
                         f"{type(intrinsics).__name__}")
    if progress is not None and not callable(progress):
        raise ConfigError(f"progress must be a callable progress(stage, fraction), got a "
                          f"{type(progress).__name__}")


def _check_intrinsics(intrinsics: Intrinsics, shape: tuple[int, int]) -> None:
    """Refuse a camera that is not the ``(H, W)`` image's, or is no camera (a focal
    length that is not finite and positive, a principal point that is not finite)."""
    if (intrinsics.width, intrinsics.height) != (shape[1], shape[0]):
        raise InputError(f"intrinsics are for {intrinsics.width}x{intrinsics.height} but "
                         f"the image is {shape[1]}x{shape[0]}")
    check_intrinsics(intrinsics)


def _first_pass_input(pre: Preprocessed, shape: tuple[int, int], config: Config,
                      intrinsics: Intrinsics | None) -> PassInput:
    """The first pass's input (:func:`~photo3d.stages.passes.start`) with the input
    camera scaled to the working size and, for metric depth, its depth mapping."""
    h, w = pre.image.shape[:2]
    if intrinsics is not None:
        intrinsics = intrinsics.scaled(w, h)
    mapping = None
    if config.metric:
        lo, hi = pre.disparity_range  # of 1 / z: normalised d maps back to z exactly
        mapping = DepthMapping.from_inverse_depth(lo, hi)
    return start(pre, config=config, intrinsics=intrinsics, mapping=mapping)


def check_photo_memory(image: np.ndarray | str | Path, config: Config) -> None:
    """:func:`photo3d.resources.check_memory` for a photo file's own size, read from its
    header (nothing for an array): a photo too large for ``config.size`` (``--size 0``
    keeps a 13000x13000 photo's size) is refused before it is decoded, not after.

    Example:
        >>> check_photo_memory(np.zeros((8, 8, 3)), Config())  # an array: nothing to do
    """
    shape = image_shape(image) if isinstance(image, str | os.PathLike) else None
    if shape is not None:
        check_memory(shape, config)


def fill_pass(state: PassInput, plan: PassPlan, backend: Inpainter, *, pass_index: int = 0,
              frame: Future[LDI] | None = None,
              progress: CountProgress | None = None) -> Merged:
    """One inpainting pass, scheduled: ``state``'s regions
    (:func:`~photo3d.stages.passes.pass_regions`), their patches filled by ``backend``
    and merged (:func:`~photo3d.stages.passes.merge_pass`).

    A backend that fills each patch on its own (``patchwise``) gets the patches in
    batches of about half the lattice's area (bounded memory), the next batch
    extracted on an :func:`~photo3d.parallel.overlap` thread while it fills this one.

    Args:
        state: the LDI and its edges.
        plan: the pass's plan (:func:`~photo3d.stages.passes.plan_pass`).
        backend: the inpainter.
        pass_index: handed to ``backend.inpaint``.
        frame: when ``state.ldi``'s frame colours are still being filled: the LDI with
            them (the same pixels and links). The patches whose context reads no
            frame pixel are filled first, meanwhile; the others are extracted from
            ``frame``'s LDI, which the pass is merged into. The result is the same
            as without (each patch is filled on its own; fills merge in edge order).
        progress: ``progress(done, total)`` over the pass's patches.

    Returns:
        :class:`~photo3d.stages.merge.Merged`: the LDI with the new pixels and the
        next pass's edges.

    Example:
        >>> from photo3d.stages.passes import plan_pass, start
        >>> from photo3d.stages.preprocess import Preprocessed, preprocess
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[16:48, 16:48] = 3.0
        >>> pre = preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg)
        >>> fill = get_inpainter("diffusion")
        >>> merged = fill_pass(start(pre, config=cfg), plan_pass(cfg, 64, margin=1), fill)
        >>> merged.added > 0
        True
    """
    index = state.index if state.index is not None else state.ldi.position_index()
    regions = pass_regions(state, plan.sizes, index=index)
    first, later = (border_readers(state.ldi, regions) if frame is not None
                    else (None, []))
    rows, cols = state.ldi.lattice_shape
    area = rows * cols // 2 if getattr(backend, "patchwise", False) else None

    def batches() -> Iterator[list[PatchJob]]:
        yield from patch_batches(state.ldi, regions, state.edge_pixels, plan, edges=first,
                                 area=area)
        if later:
            yield from patch_batches(frame.result(), regions, state.edge_pixels, plan,
                                     edges=later, area=area, first_area=area)

    fills, done = [], 0

    def report(i: int, n: int) -> None:
        if progress is not None:
            progress(min(done + i, regions.count), regions.count)

    for batch in ahead(batches(), name="patches") if area is not None else batches():
        results = backend.inpaint([job.patch for job in batch], progress=report,
                                  pass_index=pass_index)
        # take reads the LDI's positions only, the same in the frame's
        fills.extend((job.edge, take(state.ldi, job, res))
                     for job, res in zip(batch, results, strict=True))
        done += len(batch)
        del results  # not held while the next batch is filled (a batch's whole patches)
    return merge_pass(state, plan, fills, ldi=frame.result() if frame is not None else None,
                      index=index)


def _border_fill(name: str, backend: Inpainter, scale: float):
    """The :data:`~photo3d.stages.border.BorderFill` called ``name``: ``texture``
    (:func:`photo3d.inpaint.frame.fill_frame`) or an inpainting backend's (the
    pipeline's own when the names match) run on one patch, the frame."""
    if name == "texture":
        radius = max(2, round(1.5 * scale))
        return lambda color, disparity, context, synthesis: fill_frame(
            color, disparity, context, synthesis, radius=radius)
    fill = backend if name == backend.name else get_inpainter(name)

    def run(color, disparity, context, synthesis):
        edges = np.zeros(context.shape, np.float32)
        patch = Patch(color, disparity, edges, context, synthesis, (0, 0), scale)
        return fill.inpaint([patch])[0].color

    return run


def inpainter_settings(backend: Inpainter) -> dict[str, object]:
    """The settings a backend reports (its optional ``settings()``, JSON-able), else
    just its name; :func:`make` records them in the :class:`Photo3D` it returns.

    Example:
        >>> from photo3d.inpaint import get_inpainter
        >>> inpainter_settings(get_inpainter("diffusion"))["name"]
        'diffusion'
    """
    settings = getattr(backend, "settings", None)
    return dict(settings()) if callable(settings) else {"name": backend.name}
