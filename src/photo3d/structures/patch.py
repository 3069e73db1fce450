"""What crosses the inpainting boundary: a :class:`Patch` in, an :class:`InpaintResult`
out.

A :class:`Patch` is a local image-like window of one LDI layer around one depth edge
(paper, Sec. 3.2-3.3), cut by :mod:`photo3d.stages.patches`. Only pixels under
``context`` carry information; colour and disparity are zero under ``synthesis`` and
everywhere else, so a backend cannot draw from the foreground or from anything outside
the context even by mistake. The backends (:mod:`photo3d.inpaint`) fill them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
