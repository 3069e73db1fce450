"""Backend ``"structured"``: structure first, then each side, then texture.

The classical counterpart of the paper's edge-then-colour order. Per patch:

1. the context's colour and depth edges are continued into the synthesis region as
   straight lines (the structure map, :mod:`photo3d.inpaint.continuation`);
2. colour and disparity are diffused from the context without crossing those lines,
   so each side of a continued edge takes the colours of its own side and the
   boundary stays sharp; the line pixels themselves are filled last, from both sides;
3. texture: every synthesis pixel copies the centre of the context patch that best
   matches its neighbourhood, the step-2 colours included in the match so sources come
   from the matching side (:mod:`photo3d.inpaint.exemplar`, PatchMatch); a pixel takes
   that texture in proportion to the detail of the context next to it
   (:func:`texture_weight`): where the context is smooth (sky, walls, out-of-focus
   background) the truth is smooth too and the step-2 colours stay.

Disparity is the step-2 result (no texture is added to depth). The continued lines
are the result's ``edges``: where the disparity steps across one, the merge tears the
fill and the next pass fills behind it (:mod:`photo3d.stages.merge`). Every value read comes
from the patch's context: nothing from the foreground or outside the context.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace

import numpy as np

from photo3d.inpaint.continuation import continue_edges
from photo3d.inpaint.diffusion import diffuse_coarse, diffuse_in_place
from photo3d.inpaint.exemplar import exemplar_fill
from photo3d.parallel import map_completed
from photo3d.progress import CountProgress
from photo3d.structures.patch import InpaintResult, Patch


def piecewise_diffuse(values: np.ndarray, context: np.ndarray, synthesis: np.ndarray,
                      barriers: np.ndarray, *, iterations: int = 300,
                      tolerance: float = 1e-3) -> np.ndarray:
    """Harmonic fill of ``synthesis`` that does not cross ``barriers``.

    Args:
        values: ``(h, w, c) float32``; read under ``context`` only.
        context: ``(h, w) bool`` known pixels.
        synthesis: ``(h, w) bool`` pixels to fill.
        barriers: ``(h, w) bool`` synthesis pixels that separate the fill (filled
            last, from their neighbours on both sides).

    Returns:
        ``(h, w, c) float32``.

    Example:
        >>> v = np.zeros((3, 5, 1), np.float32); v[0] = 1.0          # top row white
        >>> ctx = np.zeros((3, 5), bool); ctx[0] = ctx[2] = True       # bottom row black
        >>> bar = np.zeros((3, 5), bool)
        >>> bar[1, 2] = True                  # a barrier pixel does not block the row
        >>> np.round(piecewise_diffuse(v, ctx, ~ctx, bar)[1, :, 0], 2).tolist()
        [0.5, 0.5, 0.5, 0.5, 0.5]
    """
    out = np.where(context[..., None], values, 0).astype(np.float32)
    if not synthesis.any():
        return out
    free = synthesis & ~barriers
    reached = diffuse_in_place(out, context, free, iterations, tolerance, 1.9)
    rest = synthesis & ~(reached & free)
    if rest.any():
        known = context | (free & reached)
        out[rest] = 0.0
        got = diffuse_in_place(out, known, rest, iterations, tolerance, 1.9)
        lost = rest & ~got
        if lost.any():
            out[lost] = out[context].mean(axis=0) if context.any() else 0.0
    return out


def texture_weight(color: np.ndarray, context: np.ndarray, synthesis: np.ndarray, *,
                   smooth: float, textured: float, radius: float = 2.0) -> np.ndarray:
    """How much texture each synthesis pixel wants, from the context next to it.

    The context's fine detail is measured as the local RMS of its high-pass grey
    level (grey minus its Gaussian blur of ``radius`` px, both normalised over the
    context only) and carried into the synthesis region by diffusion, so every hole
    pixel reads the detail of the context it continues. A smooth context (a clear sky,
    a wall, a defocused background) wants a smooth fill, which diffusion already
    gives; copied texture there only adds specks.

    Args:
        color: ``(h, w, 3) float32`` read under ``context`` only.
        context, synthesis: ``(h, w) bool``.
        smooth: detail (RMS, colour units) at and below which the weight is 0.
        textured: detail at and above which the weight is 1 (linear in between).
        radius: Gaussian sigma of the high-pass and of the local RMS, in pixels.

    Returns:
        ``(h, w) float32`` in [0, 1], meaningful under ``synthesis``.

    Example:
        >>> rng = np.random.default_rng(0)
        >>> ctx = np.ones((32, 32), bool); ctx[8:24, 8:24] = False
        >>> flat = np.full((32, 32, 3), 0.5, np.float32)
        >>> noisy = (flat + rng.normal(0, 0.1, (32, 32, 1))).astype(np.float32)
        >>> w = [texture_weight(c, ctx, ~ctx, smooth=0.01, textured=0.03)[16, 16]
        ...      for c in (flat, noisy)]
        >>> [round(float(v), 2) for v in w]
        [0.0, 1.0]
    """
    from scipy.ndimage import gaussian_filter

    # Only the context next to the synthesis region is carried into it, and its detail
    # reads the context within two Gaussian reaches: the rest of the patch is not read
    # (but for synthesis pixels no context reaches: the window's mean detail, not the
    # patch's).
    reach = 2 * int(4.0 * radius + 0.5) + 1  # gaussian_filter's truncate=4, twice, + 1
    rows, cols = np.flatnonzero(synthesis.any(axis=1)), np.flatnonzero(synthesis.any(axis=0))
    if rows.size == 0:
        return np.zeros(synthesis.shape, np.float32)
    y0, x0 = max(rows[0] - reach, 0), max(cols[0] - reach, 0)
    y1, x1 = rows[-1] + reach + 1, cols[-1] + reach + 1
    if (y0, x0) != (0, 0) or y1 < synthesis.shape[0] or x1 < synthesis.shape[1]:
        window = np.s_[y0:y1, x0:x1]
        inner = texture_weight(np.ascontiguousarray(color[window]),
                               np.ascontiguousarray(context[window]),
                               np.ascontiguousarray(synthesis[window]),
                               smooth=smooth, textured=textured, radius=radius)
        out = np.zeros(synthesis.shape, np.float32)
        out[window] = inner
        return out

    known = context.astype(np.float32)
    grey = np.where(context, color.mean(axis=2), 0.0).astype(np.float32)

    den = np.maximum(gaussian_filter(known, radius, mode="constant"), 1e-6)

    def local_mean(values: np.ndarray) -> np.ndarray:
        return gaussian_filter(values * known, radius, mode="constant") / den

    detail = np.sqrt(np.maximum(local_mean((grey - local_mean(grey)) ** 2), 0.0))
    carried = diffuse_coarse(detail.astype(np.float32), context, synthesis)
    span = max(textured - smooth, 1e-6)
    return np.clip((carried - smooth) / span, 0.0, 1.0).astype(np.float32)


@dataclass(frozen=True)
class StructuredOptions:
    """What changes the ``structured`` backend's output (``config.json`` records it).

    Attributes:
        iterations, tolerance: the diffusion's (:func:`photo3d.inpaint.diffusion.diffuse`).
        lines: step 1 (continued edges) on or off.
        texture: step 3's weight: 0 = no texture, 1 = its colours as they are.
        patch_radius: texture patch radius in pixels of the input photo (an enlarged
            small photo gets patches as large in its own pixels as a photo at the
            working size; at least 2 lattice pixels).
        pm_iterations, em_steps, guide_weight, copy: the exemplar fill's
            (:func:`~photo3d.inpaint.exemplar.exemplar_fill`; ``pm_iterations`` is its
            ``iterations``).
        support_factor, coherence: the edge continuation's
            (:func:`~photo3d.inpaint.continuation.continue_edges`).
        continuation: any other keyword of ``continue_edges``, as ``(name, value)``
            pairs (a mapping is turned into pairs).
        smooth, textured: :func:`texture_weight`'s: texture only where the context next
            to a pixel has detail, so a smooth context gets the smooth fill
            (``textured=0`` copies texture everywhere).

    Example:
        >>> StructuredOptions(continuation={"reach": 4}).continuation
        (('reach', 4),)
    """

    iterations: int = 300
    tolerance: float = 1e-3
    lines: bool = True
    texture: float = 1.0
    patch_radius: float = 1.5
    pm_iterations: int = 3
    em_steps: int = 1
    guide_weight: float = 0.5
    copy: bool = True
    support_factor: float = 1.0
    coherence: float = 0.8
    continuation: tuple[tuple[str, object], ...] = ()
    smooth: float = 0.003
    textured: float = 0.012

    def __post_init__(self) -> None:
        if isinstance(self.continuation, Mapping):
            object.__setattr__(self, "continuation", tuple(self.continuation.items()))


class StructuredInpainter:
    """Backend ``"structured"``: continued edges, piecewise diffusion, exemplar texture.

    Args:
        options: :class:`StructuredOptions` (default: its defaults).
        changes: fields of ``options`` to replace, e.g. ``texture=0.5``; a keyword that
            is not a field goes to the edge continuation (``continuation``).

    Example:
        >>> from photo3d.inpaint import get_inpainter
        >>> inp = get_inpainter("structured")
        >>> col = np.zeros((20, 30, 3), np.float32); col[10:] = 1.0
        >>> ctx = np.zeros((20, 30), bool); ctx[:, :10] = True
        >>> p = Patch(col * ctx[..., None], np.full((20, 30), 0.5, np.float32) * ctx,
        ...           np.zeros((20, 30), np.float32), ctx, ~ctx, (0, 0))
        >>> r = inp.inpaint([p])[0]
        >>> bool(r.color[:9, 25, 0].max() < 0.1 and r.color[11:, 25, 0].min() > 0.9)
        True
    """

    name = "structured"
    margin = 1
    later_context = 1.0
    """Later passes grow contexts as deep as the first (read by the pipeline)."""
    paper_context = False
    """Contexts take photo3d's rules too (read by the pipeline)."""
    patchwise = True
    """Each patch is filled on its own: the pipeline may give a pass's patches in batches."""

    def __init__(self, options: StructuredOptions | None = None, **changes) -> None:
        known = {f.name for f in fields(StructuredOptions)}
        extra = {k: changes.pop(k) for k in list(changes) if k not in known}
        options = replace(options or StructuredOptions(), **changes)
        if extra:
            options = replace(options, continuation=(*options.continuation, *extra.items()))
        self.options = options
        self.exemplar = dict(iterations=options.pm_iterations, em_steps=options.em_steps,
                             guide_weight=options.guide_weight, copy=options.copy)
        self.structure = dict(options.continuation, support_factor=options.support_factor,
                              coherence=options.coherence)

    def settings(self) -> dict[str, object]:
        """What changes this backend's output, JSON-able (``config.json`` records it).

        Example:
            >>> s = StructuredInpainter(texture=0.5).settings()
            >>> s["name"], s["texture"], s["pm_iterations"], s["coherence"]
            ('structured', 0.5, 3, 0.8)
        """
        record = {f.name: getattr(self.options, f.name) for f in fields(self.options)
                  if f.name != "continuation"}
        return {"name": self.name, **record, **dict(self.options.continuation)}

    def radius(self, scale: float) -> int:
        """Texture patch radius in lattice pixels for a patch of this ``scale``.

        Example:
            >>> inp = StructuredInpainter()
            >>> inp.radius(1.0), inp.radius(1.4), inp.radius(3.2)
            (2, 2, 5)
        """
        return max(2, round(self.options.patch_radius * scale))

    def fill(self, p: Patch) -> InpaintResult:
        """Fill one patch (see the module doc)."""
        context = p.context
        o = self.options
        if o.lines:
            lines = continue_edges(p.color, p.disparity, context, p.synthesis,
                                   **self.structure)
        else:
            lines = np.zeros(p.shape, bool)
        stacked = np.concatenate([p.color, p.disparity[..., None]], axis=2)
        out = piecewise_diffuse(stacked, context, p.synthesis, lines,
                                iterations=o.iterations, tolerance=o.tolerance)
        color = out[..., :3]
        if o.texture > 0:
            tex = exemplar_fill(color, context, p.synthesis, radius=self.radius(p.scale),
                                **self.exemplar)
            amount = np.float32(o.texture)
            # tex is color outside the synthesis region: blended in its bounding box
            rows = np.flatnonzero(p.synthesis.any(axis=1))
            cols = np.flatnonzero(p.synthesis.any(axis=0))
            box = np.s_[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1] if rows.size else np.s_[:0]
            if o.textured > 0:  # per pixel: texture only where the context has detail
                amount = amount * texture_weight(p.color, context, p.synthesis,
                                                 smooth=o.smooth,
                                                 textured=o.textured)[box][..., None]
            color[box] += amount * (tex[box] - color[box])
        return InpaintResult(color=np.clip(color, 0.0, 1.0), disparity=out[..., 3],
                             edges=lines.astype(np.float32))

    def inpaint(
        self, patches: Sequence[Patch], *, progress: CountProgress | None = None,
        pass_index: int = 0,
    ) -> list[InpaintResult]:
        """Fill every patch's synthesis region (every pass alike). The largest
        synthesis regions are started first, so no thread is left with a large patch
        at the end of the pass while the others wait; the results are in order."""
        order = sorted(range(len(patches)),
                       key=lambda i: -int(np.count_nonzero(patches[i].synthesis)))
        # the kernels release the GIL: patches run in the budget's threads (the output
        # does not depend on it)
        results: list[InpaintResult | None] = [None] * len(patches)
        jobs = map_completed(self.fill, [patches[i] for i in order], name="structured")
        for done, (j, result) in enumerate(jobs, 1):
            results[order[j]] = result
            if progress is not None:
                progress(done, len(patches))
        return results

