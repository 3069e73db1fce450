"""What a training run needs, checked before the work (as ``make`` does:
:mod:`photo3d.resources`).

A run holds, at its peak, the interpreter and torch (:data:`BASE_BYTES`), the region
pairs of every depth map (:data:`POOL_BYTES_PER_PIXEL` of working area per source,
kept for the whole run), and the larger of

* the preparation of one photo at its working size (the pipeline's preprocessing and
  region growth: :data:`photo3d.resources.BYTES_PER_PIXEL` per working pixel), and
* an optimisation step: the nets' weights, gradients and Adam moments
  (:data:`BYTES_PER_PARAMETER`), the activations of the step's forward passes
  (generator and discriminator: :data:`ACTIVATION_FACTOR`; VGG-16 for the colour
  losses: :data:`VGG_FACTOR`), whose outputs are counted by running them on torch's
  ``meta`` device (shapes only, no memory), and the batch itself
  (:data:`BATCH_BYTES_PER_PIXEL`).

It writes the built-in scenes (``--images builtin``), the prepared data cache and
:data:`~photo3d.train.run.KEEP` + 1 checkpoints (:func:`disk_estimate`).

The constants round up a least-squares fit to the peak resident memory (``VmHWM``)
of two optimisation steps on the CPU of 16 runs: each net (edge, depth, colour,
refine, refine with the adversarial term) at widths 0.25 and 1.0, crops 128 and 256,
batches 2 and 4 (peaks 0.58-2.1 GB; the estimate is 5-25 % above every one).

Example:
    >>> from photo3d.train.trainer import TrainConfig
    >>> round(step_bytes(TrainConfig("color")) / 1e9, 1)  # the authors' net, crop 256, batch 8
    3.0
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from torch.overrides import TorchFunctionMode

from photo3d.errors import OutputError
from photo3d.resources import BYTES_PER_PIXEL, Estimate, check
from photo3d.train.dataset import TrainingFile, target_shape
from photo3d.train.trainer import REFINE_D_WIDTH, TrainConfig

BASE_BYTES = 600e6
"""Interpreter, numpy, numba, torch and its allocator, resident before any net
(measured 560 MB)."""
BYTES_PER_PARAMETER = 24
"""Weights, gradients and Adam's two moments (16 bytes) plus the allocator's slack
(measured 22)."""
ACTIVATION_FACTOR = 0.5
"""Peak bytes of a step per byte (float32) of one forward pass of the generator and
its discriminator (measured 0.38 and 0.28)."""
VGG_FACTOR = 1.0
"""The same for the colour losses' VGG-16 (measured 0.78)."""
BATCH_BYTES_PER_PIXEL = 1000
"""Peak bytes of a step per crop pixel of the batch besides the nets' activations:
inputs, targets, masks and the loss terms' maps (measured 940)."""
POOL_BYTES_PER_PIXEL = 6
"""Region pairs of one depth map: 3 pairs of two ``bool`` masks, each at most about
the working area (measured: 0.4-0.6 of it on average, up to 1.4)."""
CACHE_BYTES_PER_PIXEL = 8
"""Prepared data on disk per working pixel: colour (3 bytes), disparity (4), edges (1)."""
SCENE_BYTES_PER_PIXEL = 7
"""A built-in scene on disk: its PNG (at most 3 bytes per pixel) and PFM disparity (4)."""
_INPUTS = {"edge": 7, "depth": 4, "color": 6}
_VGG = (64, 64, 128, 128, 256, 256, 256)  # VGG-16's first three blocks (pool1..pool3)


class _CountOutputs(TorchFunctionMode):
    """Adds up the elements of every image-like tensor the torch functions return."""

    def __init__(self) -> None:
        super().__init__()
        self.elements = 0

    def __torch_function__(self, func, types, args=(), kwargs=None):
        out = func(*args, **(kwargs or {}))
        for t in out if isinstance(out, (tuple, list)) else (out,):
            if isinstance(t, torch.Tensor) and t.dim() >= 3:
                self.elements += t.numel()
        return out


def _forward_elements(build, channels: int, side: int, *,
                      build_on_cpu: bool = False) -> tuple[int, float]:
    """``(parameters, forward output elements per input pixel)`` of ``build()``'s
    module on a ``(1, channels, side, side)`` input, run on the meta device.

    ``build_on_cpu``: build the module on the CPU first (the edge nets: setting up a
    spectral norm on the meta device takes seconds; on the CPU, milliseconds).
    """
    if build_on_cpu:
        with torch.no_grad():
            module = build().to("meta")
    else:
        with torch.device("meta"):
            module = build()
    parameters = sum(p.numel() for p in module.parameters())
    counter = _CountOutputs()
    with torch.device("meta"), counter:
        module(torch.zeros(1, channels, side, side))
    return parameters, counter.elements / side**2


def _vgg_elements(side: int) -> float:
    """Forward output elements per pixel of the colour losses' VGG-16 (pool1..pool3)."""
    from photo3d.nets.vgg import vgg16_features

    convs, cin = [], 3
    with torch.device("meta"):
        for cout in _VGG:
            convs.append((torch.zeros(cout, cin, 3, 3), torch.zeros(cout)))
            cin = cout
        counter = _CountOutputs()
        with counter:
            vgg16_features(torch.zeros(1, 3, side, side), convs)
    return counter.elements / side**2


def step_counts(config: TrainConfig) -> tuple[int, float, float]:
    """``(parameters, net elements, VGG elements)`` of one step of ``config``: the
    parameters of the nets it trains, and the elements per crop pixel of one forward
    pass of the generator plus its discriminator (if any), and of the colour losses'
    VGG-16 (0 for the edge and depth nets).

    Nets wider than ``width`` 1 (refine: ``channels`` 32), or with more than
    :data:`_BLOCKS` blocks, are counted at that width (and at half those blocks) and
    extrapolated: parameters grow at most with the square of the width and elements
    with the width, both linearly with the blocks, so the extrapolation errs high.
    (The edge nets are built on the CPU, at most 57 MB; the others on the meta device,
    where a net 1000 times as wide costs nothing.)

    Example:
        >>> p, nets, vgg = step_counts(TrainConfig("depth", levels=3, width=0.125, size=32))
        >>> p > 0 and nets > 0 and vgg == 0
        True
        >>> p1, e1, _ = step_counts(TrainConfig("edge", width=1.0, blocks=1))
        >>> p4, e4, _ = step_counts(TrainConfig("edge", width=4.0, blocks=1))
        >>> p4 == 16 * p1 and e4 == 4 * e1
        True
    """
    import dataclasses

    refine = config.arch == "refine"
    if refine:
        counted = dataclasses.replace(config, channels=min(config.channels, 32))
        scale = config.channels / counted.channels
    else:
        counted = dataclasses.replace(config, width=min(config.width, 1.0))
        scale = config.width / counted.width
    has_blocks = config.kind == "edge" or refine
    if has_blocks and config.blocks > _BLOCKS:
        counted = dataclasses.replace(counted, blocks=_BLOCKS)
    params, nets, vgg = _step_counts(counted)
    if counted.blocks < config.blocks:  # linear in the blocks
        fewer, less, _ = _step_counts(dataclasses.replace(counted, blocks=_BLOCKS // 2))
        more = (config.blocks - _BLOCKS) / (_BLOCKS - _BLOCKS // 2)
        params, nets = params + more * (params - fewer), nets + more * (nets - less)
    return int(params * scale**2), nets * scale, vgg


_BLOCKS = 8
"""Most residual blocks counted on the net itself (see :func:`step_counts`)."""


def _step_counts(config: TrainConfig) -> tuple[int, float, float]:
    """:func:`step_counts`, counted on the net itself."""
    from photo3d.nets import build_net
    from photo3d.nets.edge import EdgeDiscriminator

    unit = 4 if config.kind == "edge" else 2**config.levels
    side = unit * max(1, -(-64 // unit))  # per pixel, the count hardly depends on the side
    edge = config.kind == "edge"
    params, elements = _forward_elements(
        lambda: build_net(config.kind, **config.net_config()).eval(),
        _INPUTS[config.kind], side, build_on_cpu=edge)
    if edge or config.adversarial > 0:
        d_params, d_elements = _forward_elements(
            lambda: EdgeDiscriminator(2 if edge else 4,
                                      width=config.width if edge else REFINE_D_WIDTH).eval(),
            2 if edge else 4, side, build_on_cpu=True)
        params += d_params
        elements += d_elements
    return params, elements, _vgg_elements(side) if config.kind == "color" else 0.0


def step_bytes(config: TrainConfig) -> int:
    """Peak bytes of the optimisation steps of ``config`` (the nets, their optimiser
    and one batch's activations; :data:`BASE_BYTES` not included)."""
    params, nets, vgg = step_counts(config)
    per_pixel = 4 * (ACTIVATION_FACTOR * nets + VGG_FACTOR * vgg) + BATCH_BYTES_PER_PIXEL
    return int(BYTES_PER_PARAMETER * params + per_pixel * config.batch * config.size**2)


def memory_parts(config: TrainConfig, shapes: Sequence[tuple[int, int]],
                 sources: int) -> dict[str, int]:
    """The memory a run needs, by what the user can change (bytes; see the module doc).

    Args:
        config: the run's configuration.
        shapes: ``(H, W)`` of the photos and depth maps to prepare (any order; only the
            largest working size matters for the preparation).
        sources: depth maps that give region pairs.

    Example:
        >>> parts = memory_parts(TrainConfig("depth", levels=3, width=0.125, size=32),
        ...                      [(480, 640)], sources=1)
        >>> sorted(parts)
        ['a training step', 'preparing a photo', 'region pairs']
    """
    areas = [_area(shape, config) for shape in shapes] or [_area((3, 4), config)]
    return {"preparing a photo": int(BYTES_PER_PIXEL * max(areas)),
            "a training step": step_bytes(config),
            "region pairs": int(POOL_BYTES_PER_PIXEL * sources * max(areas))}


def check_memory(config: TrainConfig, shapes: Sequence[tuple[int, int]], *, sources: int,
                 what: str) -> None:
    """Raise :class:`ConfigError` (one line) if the run would need more memory than is
    available (``what``: the data, for the message: ``"48 built-in scenes"``).

    Example:
        >>> check_memory(TrainConfig("depth", levels=3, width=0.125, size=32),
        ...              [(48, 64)], sources=1, what="1 photo")
    """
    estimate = train_estimate(config, shapes, sources=sources)
    worst = estimate.largest[0]
    hint = {"preparing a photo": "a smaller --region-size (or --size, which sets its "
                                 "default and the least working size)",
            "a training step": "a smaller --batch, --size or --width",
            "region pairs": "fewer photos or --builtin-scenes, or a smaller --region-size",
            "base": "a machine with more memory"}
    check(estimate, what=f"training the {config.kind} net (--size {config.size}, --batch "
                         f"{config.batch}, --width {config.width:g}, region size "
                         f"{config.working_size}) on {what}", advice=f"use {hint[worst]}")


def train_estimate(config: TrainConfig, shapes: Sequence[tuple[int, int]], *,
                   sources: int) -> Estimate:
    """``photo3d train``'s peak (:class:`photo3d.resources.Estimate`): the base, the
    region pairs and the larger of preparing a photo and a training step
    (:func:`memory_parts`).

    Example:
        >>> est = train_estimate(TrainConfig("depth", levels=3, width=0.125, size=32),
        ...                      [(48, 64)], sources=1)
        >>> est.command, [name for name, _ in est.terms]
        ('train', ['base', 'region pairs', 'preparing a photo'])
    """
    parts = memory_parts(config, shapes, sources)
    larger = max(("preparing a photo", "a training step"), key=parts.get)
    return Estimate("train", (("base", int(BASE_BYTES)), ("region pairs", parts["region pairs"]),
                              (larger, parts[larger])))


def disk_estimate(config: TrainConfig, shapes: Sequence[tuple[int, int]], *,
                  scenes: int = 0, cache: bool = True) -> int:
    """Bytes a run writes: ``scenes`` built-in scenes (at the working size), the data
    cache of the photos of ``shapes`` (unless ``cache`` is False: already prepared), and
    the checkpoints and final weights.

    Example:
        >>> disk_estimate(TrainConfig("depth", levels=3, width=0.125, size=32), [(48, 64)]) > 0
        True
    """
    from photo3d.train.run import KEEP

    side = config.working_size
    need = SCENE_BYTES_PER_PIXEL * scenes * side * (side * 3 // 4)
    if cache:
        need += CACHE_BYTES_PER_PIXEL * sum(_area(shape, config) for shape in shapes)
    params, _, _ = step_counts(config)
    need += 4 * params * (3 * (KEEP + 1) + 1)  # weights and Adam's moments; the export
    return int(need)


def check_disk(run_dir: str | Path, need: int, *, what: str) -> None:
    """Raise :class:`OutputError` (one line) if the file system of ``run_dir`` has less
    free space than ``need`` bytes (``what``: what is written, for the message).

    Example:
        >>> import tempfile
        >>> check_disk(tempfile.mkdtemp(), 1000, what="checkpoints")
    """
    from photo3d.resources.outputs import free_space

    known = free_space(run_dir)
    if known is None:
        return
    folder, free = known
    if need > free:
        raise OutputError(f"this run writes about {_size(need)} ({what}) but only "
                          f"{_size(free)} are free in {folder}: free some space or use "
                          "fewer --builtin-scenes or a smaller --region-size")


def check_request(config: TrainConfig, run_dir: str | Path, *,
                  files: Sequence[TrainingFile] | None = None, scenes: int | None = None,
                  shape_scenes: int | None = None) -> None:
    """Check a run's memory and disk before the work (one line if it does not fit).

    Args:
        config: the run's configuration.
        run_dir: its folder (existing or not).
        files: the photos and maps of a training folder (their sizes are read from
            the file headers); or
        scenes: the built-in data's synthetic scenes (``--images builtin``).
        shape_scenes: synthetic scenes giving the region shapes of a folder without
            depth (None: the default).

    Raises:
        ConfigError: not enough memory (:func:`check_memory`).
        OutputError: not enough free disk space (:func:`check_disk`).

    Example:
        >>> import tempfile
        >>> check_request(TrainConfig("depth", levels=3, width=0.125, size=32),
        ...               tempfile.mkdtemp(), scenes=2)
    """
    from photo3d.train.builtin import PHOTOS
    from photo3d.train.dataset import BUILTIN_SHAPES

    run_dir = Path(run_dir)
    side = config.working_size
    if files is None:
        count = scenes or 0
        shapes = [(side * 3 // 4, side)] * min(count, 1) + [(1, 1)] * min(len(PHOTOS), 1)
        sources, targets = count + 1, [(side * 3 // 4, side)] * count + [(1, 1)] * len(PHOTOS)
        what = f"{count} built-in scenes and {len(PHOTOS)} photos"
        done = (run_dir / "builtin" / "shapes" / "motorcycle.pfm").is_file()
        written = 0 if done else count
    else:
        targets = [_shape_of(f.image) for f in files if f.image is not None]
        shapes = sorted(set(targets + [_shape_of(f.depth) for f in files if f.image is None]))
        sources = sum(f.depth is not None for f in files)
        if not sources:
            sources = BUILTIN_SHAPES if shape_scenes is None else shape_scenes
        what = f"{len(targets)} photos ({sources} region sources)"
        written = 0
    check_memory(config, shapes, sources=sources, what=what)
    cached = (run_dir / "data" / "index.json").is_file()
    need = disk_estimate(config, targets, scenes=written, cache=not cached)
    check_disk(run_dir, need, what="scenes, prepared data and checkpoints")


def _shape_of(path: Path | None) -> tuple[int, int]:
    """``(H, W)`` of an image or depth map from its header; ``(3, 4)`` if unknown."""
    from PIL import Image

    if path is None:
        return (3, 4)
    try:
        if path.suffix.lower() == ".npy":
            shape = np.load(path, mmap_mode="r", allow_pickle=False).shape
            return (int(shape[0]), int(shape[1])) if len(shape) >= 2 else (3, 4)
        with warnings.catch_warnings():  # a huge photo: refused below if it does not fit
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                return im.height, im.width
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError):
        return (3, 4)  # not read here: preparing it says what is wrong


def _area(shape: tuple[int, int], config: TrainConfig) -> int:
    h, w = target_shape(shape, region_size=config.working_size, crop=config.size)
    return h * w


def _size(count: float) -> str:
    return f"{count / 1e6:.0f} MB" if count < 1e9 else f"{count / 1e9:.1f} GB"
