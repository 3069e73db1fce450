"""Context/synthesis region pairs from an image's depth (paper, Sec. 3.3, "Training
data generation").

The pipeline's own first pass finds them (:mod:`photo3d.stages.passes`, the code
``make`` runs), so training regions have exactly the shapes inference produces, with the
paper's context rule (the learned backend's) and the learned backend's 20 px margin.
No border is extrapolated: it would only add shapes that hug the image frame. At most
``max_pairs`` pairs per image are kept (paper: 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d.config import Config
from photo3d.inpaint.learned import LearnedInpainter
from photo3d.stages.passes import pass_patches, start
from photo3d.stages.preprocess import Preprocessed


@dataclass(frozen=True)
class RegionPair:
    """The shape of one inference patch.

    Attributes:
        context: ``(h, w) bool`` the patch's context mask.
        synthesis: ``(h, w) bool`` its synthesis mask (disjoint from ``context``;
            includes the dilation band).
        source: index of the image whose depth produced it.
    """

    context: np.ndarray
    synthesis: np.ndarray
    source: int


def extract_region_pairs(pre: Preprocessed, *, config: Config, source: int = 0,
                         max_pairs: int = 3, min_pixels: int = 64,
                         rng: np.random.Generator | None = None) -> list[RegionPair]:
    """Region pairs of the first inpainting pass of ``pre``, at most ``max_pairs``.

    Args:
        pre: the preprocessed image (only its disparity and depth edges are used).
        config: pipeline configuration (region sizes, discontinuity threshold).
        source: recorded in every pair.
        max_pairs: pairs kept (chosen at random among the usable ones).
        min_pixels: a pair is usable if both its regions have at least this many pixels.
        rng: random generator of the choice (default: seeded with ``source``).

    Returns:
        Up to ``max_pairs`` :class:`RegionPair`, in the pipeline's edge order.

    Example:
        >>> from photo3d.stages.preprocess import preprocess
        >>> cfg = Config(size=None)
        >>> d = np.ones((64, 64), np.float32); d[16:48, 16:48] = 3.0  # a near square
        >>> pre = preprocess(np.zeros((64, 64, 3), np.float32), d, config=cfg)
        >>> pairs = extract_region_pairs(pre, config=cfg, min_pixels=16)
        >>> len(pairs), bool((pairs[0].context & pairs[0].synthesis).any())
        (1, False)
    """
    rng = rng if rng is not None else np.random.default_rng(source)
    first = start(pre, config=config, border=False)
    if first.edge_pixels.size == 0:
        return []
    jobs = pass_patches(first, config=config, working_size=pre.working_size,
                        margin=LearnedInpainter.margin, paper_context=True)
    usable = [j.patch for j in jobs if j.patch.context.sum() >= min_pixels
              and j.patch.synthesis.sum() >= min_pixels]
    keep = sorted(rng.choice(len(usable), size=min(max_pairs, len(usable)), replace=False))
    return [RegionPair(usable[i].context.copy(), usable[i].synthesis & ~usable[i].context,
                       source) for i in keep]
