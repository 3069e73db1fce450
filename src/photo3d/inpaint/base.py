"""The inpainter interface: a patch in, colour, depth and edges out.

A :class:`Patch` is a local image-like window of one LDI layer around one depth edge
(paper, Sec. 3.2-3.3). Only pixels under ``context`` carry information; colour and
disparity are zero under ``synthesis`` and everywhere else, so a backend cannot draw
from the foreground or from anything outside the context even by mistake.
Backends implement :class:`Inpainter`; :mod:`photo3d.inpaint` finds them by name, so
the pipeline never needs to know which one runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from photo3d.progress import CountProgress


@dataclass(frozen=True)
class Patch:
    """Inputs of one inpainting job.

    Attributes:
        color: ``(h, w, 3) float32`` sRGB in [0, 1], zero outside ``context``.
        disparity: ``(h, w) float32`` normalised disparity, zero outside ``context``.
        edges: ``(h, w) float32`` 1 on depth-edge pixels inside the context, else 0.
        context: ``(h, w) bool`` known pixels (one connected LDI layer).
        synthesis: ``(h, w) bool`` pixels to generate (disjoint from ``context``).
        origin: ``(y0, x0)`` lattice position of the patch's top-left pixel.
        scale: lattice pixels per pixel of the input photo (above 1 when a small
            photo was enlarged to the working size); lets a backend size its
            neighbourhoods in the photo's own pixels.
    """

    color: np.ndarray
    disparity: np.ndarray
    edges: np.ndarray
    context: np.ndarray
    synthesis: np.ndarray
    origin: tuple[int, int]
    scale: float = 1.0

    @property
    def shape(self) -> tuple[int, int]:
        return self.context.shape


@dataclass(frozen=True)
class InpaintResult:
    """Outputs of one job; only values under the patch's ``synthesis`` are used.

    Attributes:
        color: ``(h, w, 3) float32`` in [0, 1].
        disparity: ``(h, w) float32`` normalised disparity.
        edges: ``(h, w) float32`` inpainted depth edges in [0, 1] (zeros if the
            backend does not predict edges). Inside one result's synthesis region
            the merge tears the new surface only along these (where its disparity
            steps), see :mod:`photo3d.stages.merge`.
    """

    color: np.ndarray
    disparity: np.ndarray
    edges: np.ndarray


class Inpainter(Protocol):
    """What a backend provides."""

    name: str
    margin: int
    """Pixels of context-free margin the backend wants around each patch."""
    # Optional: ``later_context`` (float), the context depth after the first pass as a
    # fraction of the first pass's (the pipeline reads it with getattr; default 1).

    def inpaint(
        self, patches: Sequence[Patch], *, progress: CountProgress | None = None,
        pass_index: int = 0,
    ) -> list[InpaintResult]:
        """Fill every patch's synthesis region; one result per patch, same order.

        ``pass_index`` is the pipeline's inpainting pass (0 = regions of the input
        image's depth edges, 1+ = edges the previous pass created); a backend may
        treat passes differently (the learned backend runs its edge net in pass 0
        only, as the authors do).
        """
        ...
