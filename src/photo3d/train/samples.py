"""Training samples: a region pair pasted onto a *different* image (paper, Sec. 3.3).

One sample: pick a target photo, pick a region pair from another image's pool,
resize the pair by a random factor in [1.0, 1.3] (nearest neighbour), flip it at
random (left-right, up-down), swap its context and synthesis with probability 1/2
(the paper's augmentation), and place it in a ``size x size`` window around a random
synthesis pixel. The target is cropped at random (and flipped left-right at random).
Under the pasted context the target's pixels are known; under the synthesis region
they are the ground truth of the simulated occlusion. For the colour net the crop's
colour channels are also put in a random order (photo3d's addition: a small photo set
has a colour cast, orange-brown and grey for the built-in one, that a briefly trained
net otherwise learns as the colour of every hole; docs/learned.md).

Net inputs are built by the learned backend's own code
(:class:`photo3d.inpaint.learned.NetInputs` on a :class:`~photo3d.structures.patch.Patch`
whose colour, disparity and edges are zero outside the context), so they match
inference exactly: zeros under synthesis, disparity / max for the edge net,
zero-mean log depth for the depth net, the :func:`~photo3d.inpaint.learned.close_gaps`
hole channel for the depth and colour nets. The depth and colour nets' edge channel
holds the target's edges under context and synthesis (at inference: the context
edges plus the inpainted ones), as EdgeConnect trains its inpainting stage with
ground-truth edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d.camera import DepthMapping
from photo3d.errors import InputError
from photo3d.inpaint.learned import NetInputs
from photo3d.structures.patch import Patch
from photo3d.train.dataset import TrainingData
from photo3d.train.pairs import RegionPair

SCALE_RANGE = (1.0, 1.3)
"""Random resize of a region pair (paper: a factor in [1.0, 1.3])."""
MIN_PIXELS = 16
"""A placed pair needs at least this many context and synthesis pixels in the window."""
_MAPPING = DepthMapping()


@dataclass(frozen=True)
class Sample:
    """One training example for one net.

    Attributes:
        inputs: ``(C, S, S) float32`` the net input (edge 7, depth 4, colour 6 channels).
        target: ``(C', S, S) float32``: edge ``(1,)`` target edges under context and
            synthesis (0/1); depth ``(1,)`` zero-mean log depth (mean over the
            context, as the input); colour ``(3,)`` the target crop in [0, 1].
        context: ``(S, S) bool``.
        synthesis: ``(S, S) bool`` the pasted synthesis region (the edge net's channel).
        hole: ``(S, S) bool`` the depth and colour nets' synthesis channel
            (``synthesis`` plus the gaps :func:`close_gaps` fills).
        gray: ``(S, S) float32`` grey target crop (the edge discriminator's condition).
        target_index: the photo the pixels come from.
        source_index: the image whose depth gave the region shapes (never the target).
        swapped: context and synthesis were swapped.
    """

    inputs: np.ndarray
    target: np.ndarray
    context: np.ndarray
    synthesis: np.ndarray
    hole: np.ndarray
    gray: np.ndarray
    target_index: int
    source_index: int
    swapped: bool


def _rescale(mask: np.ndarray, factor: float) -> np.ndarray:
    h, w = mask.shape
    ys = np.minimum((np.arange(max(1, round(h * factor))) / factor).astype(np.int64), h - 1)
    xs = np.minimum((np.arange(max(1, round(w * factor))) / factor).astype(np.int64), w - 1)
    return mask[ys][:, xs]


def _window_start(anchor: int, extent: int, size: int, rng: np.random.Generator) -> int:
    """Start of a ``size`` window containing ``anchor``, inside ``[0, extent)`` when the
    canvas is larger than the window, containing the canvas when it is smaller."""
    lo = max(anchor - size + 1, min(0, extent - size))
    hi = min(anchor, max(0, extent - size))
    return int(rng.integers(lo, hi + 1))


def _crop(mask: np.ndarray, y0: int, x0: int, size: int) -> np.ndarray:
    out = np.zeros((size, size), bool)
    h, w = mask.shape
    ys, xs = max(0, y0), max(0, x0)
    ye, xe = min(h, y0 + size), min(w, x0 + size)
    if ye > ys and xe > xs:
        out[ys - y0:ye - y0, xs - x0:xe - x0] = mask[ys:ye, xs:xe]
    return out


def place_pair(pair: RegionPair, size: int, rng: np.random.Generator, *,
               swap: bool | None = None,
               swap_probability: float = 0.5) -> tuple[np.ndarray, np.ndarray, bool]:
    """Resize, flip, maybe swap and window one region pair.

    Args:
        pair: the region shapes.
        size: window side in pixels.
        rng: random generator.
        swap: force (True/False) or draw (None) the context/synthesis swap.
        swap_probability: the chance of a drawn swap (paper: 1/2).

    Returns:
        ``(context, synthesis, swapped)``: two disjoint ``(size, size) bool`` masks;
        the window always holds at least one synthesis pixel.

    Example:
        >>> ctx = np.zeros((20, 30), bool); ctx[:, :10] = True
        >>> syn = np.zeros((20, 30), bool); syn[:, 12:] = True
        >>> c, s, swapped = place_pair(RegionPair(ctx, syn, 0), 16, np.random.default_rng(0))
        >>> c.shape, bool(s.any()), bool((c & s).any())
        ((16, 16), True, False)
    """
    ctx, syn = pair.context, pair.synthesis
    factor = rng.uniform(*SCALE_RANGE)
    ctx, syn = _rescale(ctx, factor), _rescale(syn, factor)
    if rng.random() < 0.5:
        ctx, syn = ctx[:, ::-1], syn[:, ::-1]
    if rng.random() < 0.5:
        ctx, syn = ctx[::-1], syn[::-1]
    swapped = bool(rng.random() < swap_probability) if swap is None else bool(swap)
    if swapped:
        ctx, syn = syn, ctx
    ys, xs = np.nonzero(syn)
    k = int(rng.integers(ys.size))
    y0 = _window_start(int(ys[k]), syn.shape[0], size, rng)
    x0 = _window_start(int(xs[k]), syn.shape[1], size, rng)
    return _crop(ctx, y0, x0, size), _crop(syn, y0, x0, size), swapped


def make_sample(data: TrainingData, kind: str, *, size: int, rng: np.random.Generator,
                tries: int = 20, refine: bool = False, swap: float = 0.5) -> Sample:
    """One random :class:`Sample` for the ``kind`` net (``"edge"``, ``"depth"``, ``"color"``).

    Args:
        data: prepared targets and pool (``data.check(kind)`` must pass).
        kind: which net's inputs and target to build.
        size: crop side in pixels (a multiple of the net's input unit).
        rng: random generator (all choices are drawn from it).
        tries: placements drawn until the window holds ``MIN_PIXELS`` of both regions.
        refine: colour net only: the RGB input holds the diffusion fill under the hole
            (the refine net's input, :meth:`~photo3d.inpaint.netinputs.NetInputs.filled_rgb`).
        swap: probability of swapping context and synthesis (paper: 1/2).

    Example:
        >>> from photo3d.train.dataset import Target
        >>> rng = np.random.default_rng(0)
        >>> ctx = np.zeros((24, 24), bool); ctx[:, :10] = True
        >>> pair = RegionPair(ctx, ~ctx, source=1)
        >>> photo = Target(rng.random((40, 40, 3)).astype(np.float32), None, None)
        >>> data = TrainingData(["a"], np.array([False]), [pair], [photo])
        >>> s = make_sample(data, "color", size=32, rng=rng)
        >>> s.inputs.shape, s.target.shape, bool(s.inputs[:3][:, s.synthesis].any())
        ((6, 32, 32), (3, 32, 32), False)
    """
    t = int(rng.choice(data.eligible(kind)))
    target = data.target(t)
    for _ in range(tries):
        pair = data.random_pair(t, rng)
        ctx, syn, swapped = place_pair(pair, size, rng, swap_probability=swap)
        if ctx.sum() >= MIN_PIXELS and syn.sum() >= MIN_PIXELS:
            break
    h, w = target.image.shape[:2]
    if min(h, w) < size:
        raise InputError(f"target {data.names[t]} is {w}x{h}, smaller than the {size} px crop: "
                         "prepare the data with a crop of at least the training size")
    y0, x0 = int(rng.integers(h - size + 1)), int(rng.integers(w - size + 1))
    window = (slice(y0, y0 + size), slice(x0, x0 + size))
    flip = (slice(None), slice(None, None, -1)) if rng.random() < 0.5 else (slice(None),) * 2
    image = np.ascontiguousarray(target.image[window][flip], np.float32)
    if kind == "color":
        image = np.ascontiguousarray(image[..., rng.permutation(3)])
    if target.disparity is not None:
        disparity = np.ascontiguousarray(target.disparity[window][flip], np.float32)
        edges = np.ascontiguousarray(target.edges[window][flip], bool)
    else:
        disparity = np.zeros((size, size), np.float32)
        edges = np.zeros((size, size), bool)
    patch = Patch(image * ctx[..., None], disparity * ctx, (edges & ctx).astype(np.float32),
                  ctx, syn, (0, 0))
    it = NetInputs(patch, _MAPPING)
    known_edges = (edges & (ctx | syn)).astype(np.float32)
    if kind == "edge":
        inputs = it.edge_input(it.edges)
        out = known_edges[None]
    elif kind == "depth":
        inputs = np.stack([it.log_depth, known_edges, it.ctx, it.hole])
        log_depth = np.log(_MAPPING.depth(disparity) + 1e-8) - it.log_mean
        out = log_depth[None].astype(np.float32)
    else:
        rgb = it.filled_rgb() if refine else it.rgb
        inputs = np.concatenate([rgb, np.stack([known_edges, it.ctx, it.hole])])
        out = np.moveaxis(image, 2, 0)
    gray = image @ np.array([0.299, 0.587, 0.114], np.float32)
    return Sample(inputs.astype(np.float32), np.ascontiguousarray(out, np.float32), ctx, syn,
                  it.hole > 0, gray.astype(np.float32), t, pair.source, swapped)


def make_batch(data: TrainingData, kind: str, *, size: int, batch: int, seed: int,
               step: int, refine: bool = False, swap: float = 0.5) -> list[Sample]:
    """The ``batch`` samples of optimisation step ``step``: sample ``i`` draws from
    ``numpy.random.default_rng([seed, step, i])``, so a resumed run sees the same data
    (``refine``, ``swap``: as :func:`make_sample`).

    Example:
        >>> from photo3d.train.dataset import Target
        >>> ctx = np.zeros((24, 24), bool); ctx[:, :10] = True
        >>> photo = Target(np.full((32, 32, 3), 0.5, np.float32), None, None)
        >>> data = TrainingData(["a"], np.array([False]), [RegionPair(ctx, ~ctx, 1)], [photo])
        >>> len(make_batch(data, "color", size=32, batch=2, seed=0, step=7))
        2
    """
    return [make_sample(data, kind, size=size, rng=np.random.default_rng([seed, step, i]),
                        refine=refine, swap=swap) for i in range(batch)]
