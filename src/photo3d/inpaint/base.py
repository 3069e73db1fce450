"""The inpainter interface: a :class:`~photo3d.structures.patch.Patch` in, an
:class:`~photo3d.structures.patch.InpaintResult` (colour, depth and edges) out.

Backends implement :class:`Inpainter`; :mod:`photo3d.inpaint` finds them by name, so
the pipeline never needs to know which one runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from photo3d.progress import CountProgress
from photo3d.structures.patch import InpaintResult, Patch


class Inpainter(Protocol):
    """What a backend provides: every attribute the pipeline reads.

    ``later_context``, ``paper_context``, ``patchwise`` and ``settings`` are optional for
    a backend of your own (:func:`photo3d.inpaint.register`); the pipeline then takes
    1.0, ``False``, ``False`` and ``{"name": name}``. The built-in backends define all of them.

    Attributes:
        name: the backend's registered name (:func:`photo3d.inpaint.available`).
        margin: pixels of context-free margin the backend wants around each patch.
        later_context: the context's depth after the first pass, as a fraction of the
            first pass's (the learned backend: the authors' thinner later contexts;
            the classical ones: 1.0).
        paper_context: ``True`` if the backend wants the paper's contexts only (the side
            the hidden area was seen from), without photo3d's
            :attr:`~photo3d.config.RegionConfig.context_around` and
            :attr:`~photo3d.config.RegionConfig.thin_context` (the learned nets were
            trained on the paper's).
        patchwise: ``True`` if each patch is filled on its own, so the pipeline may hand
            a pass's patches over in batches and hold two batches at a time (bounded
            memory: one being filled, the next being extracted); ``False``: all of a
            pass's patches in one call.
    """

    name: str
    margin: int
    later_context: float
    paper_context: bool
    patchwise: bool

    def settings(self) -> dict[str, object]:
        """JSON-able settings recorded in ``config.json`` (at least ``name``)."""
        ...

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
