"""What the held-out fill benchmark (:mod:`photo3d.eval.heldout`) is made of: the
context/synthesis region shapes of the pipeline's own first pass, where they go on a
photo, and the photos (paper, Sec. 3.3 and the supplement's dataset generation: real
region shapes from one image's depth, pasted onto *other* photos whose pixels under
the synthesis region are the ground truth).

The shapes are exactly what :func:`photo3d.make` hands a backend in its first pass,
made by the same code (:mod:`photo3d.stages.passes`: the LDI cut along the edges with
its extrapolated border, so an edge that reaches the frame keeps its whole shape, and
the first pass's region sizes scaled to the working size), with the paper's context
rule (``paper_context``: comparable with the paper's construction and with earlier
results); the dilation band joins the synthesis region. Each pair is cropped to the
bounding box of its two masks. Sources: the Middlebury motorcycle's ground-truth
disparity and the synthetic scenes' depth (:mod:`photo3d.eval.synthetic`, seeds 0-4:
the evaluation scenes), both at 640 px. Only the depth of a source is used, never its pixels.

Pairs whose synthesis region has fewer than :data:`MIN_SYNTHESIS` pixels, or whose
context has fewer than :data:`MIN_CONTEXT`, are left out (see there why).

:func:`place` lays pairs over a photo at random places seeded by the photo's name;
:func:`photo_files` and :func:`load_photo` give a folder's photos at 640 px;
:func:`known_patch` and :func:`border_masks` are what a fill is given.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from photo3d.config import Config
from photo3d.depth.normalize import prepare_depth
from photo3d.errors import InputError
from photo3d.files.folders import PHOTO_SUFFIXES
from photo3d.stages.passes import pass_patches, start
from photo3d.stages.preprocess import preprocess
from photo3d.structures.patch import Patch

MIN_SYNTHESIS = 256
"""Smallest synthesis region kept, in pixels (a 16 x 16 square). LPIPS's first layer
looks at the image in 11 px windows every 4 px and its deeper layers every 8-16 px:
a region below this covers only a handful of feature cells, so its masked LPIPS is
mostly the surrounding truth's, and its PSNR rests on a few dozen pixels. It drops the
short edges' slivers (at 640 px the first pass's regions of the motorcycle have a
median synthesis area of several thousand pixels)."""
MIN_CONTEXT = 256
"""Smallest context kept, in pixels: a fill needs something to fill from."""
SIZE = 640
"""Longer side of the photos (and of the region sources), in pixels."""
SEED = 27
"""Fixed part of every photo's placement seed (issue 27)."""
COUNT = 4
"""Region pairs per photo."""
FLAT_DISPARITY = 0.5
"""Normalised disparity of the context in the patches (the photos have no depth)."""
SCENES = (0, 1, 2, 3, 4)
"""Seeds of the synthetic scenes whose depth gives region shapes (the evaluation scenes)."""


@dataclass(frozen=True)
class RegionShape:
    """One context/synthesis pair of a first pass, cropped to its bounding box.

    Attributes:
        context: ``(h, w) bool`` the pixels a fill may read.
        synthesis: ``(h, w) bool`` the pixels it creates (disjoint from ``context``;
            includes the dilation band).
        source: where the shape comes from, e.g. ``"motorcycle"`` or ``"synthetic3"``.
    """

    context: np.ndarray
    synthesis: np.ndarray
    source: str

    @property
    def shape(self) -> tuple[int, int]:
        return self.context.shape


def first_pass_shapes(disparity: np.ndarray, *, source: str, config: Config | None = None,
                      min_synthesis: int = MIN_SYNTHESIS, min_context: int = MIN_CONTEXT,
                      paper_context: bool = True) -> list[RegionShape]:
    """The region pairs :func:`photo3d.make`'s first pass finds on ``disparity``.

    Args:
        disparity: ``(H, W)`` disparity (larger = nearer, any positive scale; NaN or inf
            where unknown, filled as ``make`` fills it).
        source: recorded in every pair.
        config: pipeline configuration (working size, region sizes, thresholds);
            default ``Config(size=640)``.
        min_synthesis, min_context: smallest regions kept, in pixels.
        paper_context: the paper's context rule (the benchmark's); ``False``: the
            classical fills' rule, what ``make`` gives them.

    Returns:
        The pairs in the pipeline's edge order.

    Example:
        >>> d = np.ones((96, 128), np.float32); d[24:72, 40:88] = 3.0  # a near square
        >>> shapes = first_pass_shapes(d, source="square", config=Config(size=None))
        >>> len(shapes), bool((shapes[0].context & shapes[0].synthesis).any())
        (1, False)
    """
    config = config or Config(size=640)
    disp = prepare_depth(np.asarray(disparity, np.float32), disparity.shape,
                         kind="disparity").disparity
    pre = preprocess(np.zeros((*disp.shape, 3), np.float32), disp, config=config)
    first = start(pre, config=config)
    if first.edge_pixels.size == 0:
        return []
    shapes = []
    for job in pass_patches(first, config=config, working_size=pre.working_size, margin=0,
                            paper_context=paper_context):
        ctx = job.patch.context
        syn = job.patch.synthesis & ~ctx
        if syn.sum() >= min_synthesis and ctx.sum() >= min_context:
            shapes.append(RegionShape(ctx.copy(), syn.copy(), source))
    return shapes


@lru_cache(maxsize=4)
def region_bank(size: int = 640, scenes: tuple[int, ...] = SCENES) -> tuple[RegionShape, ...]:
    """Every usable first-pass pair of the motorcycle's ground-truth disparity and of
    the synthetic scenes ``scenes`` (depth only, ``4:3`` at ``size`` px), with the
    default configuration at working size ``size``. Deterministic; kept in memory.

    Returns:
        The pairs, motorcycle first, then the scenes in order.

    Example:
        >>> bank = region_bank(160, scenes=(0,))
        >>> sorted({s.source for s in bank}), all(s.synthesis.sum() >= 256 for s in bank)
        (['motorcycle', 'synthetic0'], True)
    """
    from photo3d.camera import Intrinsics
    from photo3d.eval.synthetic import cast, random_scene
    from photo3d.sample import motorcycle

    config = Config(size=size)
    shapes = first_pass_shapes(np.asarray(motorcycle().disparity), source="motorcycle",
                               config=config)
    w, h = size, round(size * 3 / 4)
    for seed in scenes:
        _, z = cast(random_scene(seed), Intrinsics.default(w, h), 0.0, samples=1)
        shapes += first_pass_shapes((1.0 / z).astype(np.float32), source=f"synthetic{seed}",
                                    config=config)
    return tuple(shapes)


@dataclass(frozen=True)
class Placement:
    """Region pair ``shape`` of the bank with its top-left corner at ``(y, x)``."""

    shape: int
    y: int
    x: int


def place(shape: tuple[int, int], bank: Sequence[RegionShape], name: str, *,
          count: int = COUNT, seed: int = SEED) -> list[Placement]:
    """``count`` different pairs of ``bank`` that fit a photo of ``shape`` ``(H, W)``,
    at uniform random places inside it; the same for the same ``name`` and ``seed``.

    Example:
        >>> m = np.ones((20, 30), bool)
        >>> bank = [RegionShape(m, ~m, "a"), RegionShape(m[:5], ~m[:5], "b")]
        >>> place((40, 40), bank, "x.png") == place((40, 40), bank, "x.png")
        True
    """
    key = zlib.crc32(name.encode("utf-8", "surrogateescape"))
    rng = np.random.default_rng([seed, key])
    fits = [i for i, s in enumerate(bank) if s.shape[0] <= shape[0] and s.shape[1] <= shape[1]]
    chosen = rng.choice(len(fits), size=min(count, len(fits)), replace=False)
    out = []
    for c in chosen:
        h, w = bank[fits[c]].shape
        out.append(Placement(fits[c], int(rng.integers(shape[0] - h + 1)),
                             int(rng.integers(shape[1] - w + 1))))
    return out


def photo_files(folder: str | Path) -> list[Path]:
    """The photos of ``folder`` (not its subfolders), sorted.

    Raises:
        InputError: one line: the folder is missing, not a folder, or holds no photo.
    """
    from photo3d.files.folders import files_in

    folder = Path(folder)
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        raise InputError(f"held-out folder {folder} {what}")
    found = files_in(folder, PHOTO_SUFFIXES)
    if not found:
        raise InputError(f"no photos in {folder} (looked for {', '.join(PHOTO_SUFFIXES)})")
    return found


def load_photo(path: str | Path | np.ndarray, size: int = SIZE) -> np.ndarray:
    """A photo as ``(H, W, 3) float32`` with its longer side resized to ``size`` (a
    file more than twice as large is decoded at about twice ``size`` first:
    :func:`~photo3d.depth.sources.read_photo`).

    Example:
        >>> load_photo(np.zeros((48, 64, 3), np.uint8), size=32).shape
        (24, 32, 3)
    """
    from photo3d.config import working_shape
    from photo3d.depth.sources import read_photo
    from photo3d.stages.preprocess import resize

    image = read_photo(path, working_size=size)
    return np.clip(resize(image, working_shape(image.shape[:2], size)), 0.0, 1.0)


def known_patch(image: np.ndarray, context: np.ndarray, synthesis: np.ndarray,
                origin: tuple[int, int], *, margin: int = 0) -> Patch:
    """The patch a fill gets: the window of ``image`` at ``origin`` under ``context``
    only (zeros elsewhere), flat disparity, no edges, ``margin`` empty pixels around.

    Args:
        image: ``(H, W, 3) float32`` the photo.
        context, synthesis: ``(h, w) bool`` the pasted masks.
        origin: ``(y, x)`` of the masks' top-left pixel in the photo.
        margin: the backend's :attr:`~photo3d.inpaint.base.Inpainter.margin`.

    Returns:
        A :class:`Patch` of ``(h + 2 margin, w + 2 margin)``, origin in photo pixels.
    """
    h, w = context.shape
    y, x = origin
    m = margin
    ctx = np.pad(context, m)
    color = np.zeros((*ctx.shape, 3), np.float32)
    color[m:m + h, m:m + w][context] = image[y:y + h, x:x + w][context]
    return Patch(color, np.where(ctx, FLAT_DISPARITY, 0).astype(np.float32),
                 np.zeros(ctx.shape, np.float32), ctx, np.pad(synthesis, m), (y - m, x - m))


def border_masks(shape: tuple[int, int], border: int, depth: int) -> tuple[np.ndarray, np.ndarray]:
    """``(context, ring)`` of the border test: the outer ``border`` px (ring) and the
    ``depth`` px band inside it (context), ``(H, W) bool`` each.

    Example:
        >>> ctx, ring = border_masks((8, 8), 2, 1)
        >>> int(ring.sum()), int(ctx.sum())
        (48, 12)
    """
    h, w = shape
    inner = np.zeros(shape, bool)
    inner[border:h - border, border:w - border] = True
    core = np.zeros(shape, bool)
    d = border + depth
    core[d:h - d, d:w - d] = True
    return inner & ~core, ~inner
