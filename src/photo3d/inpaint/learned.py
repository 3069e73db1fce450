"""Backend ``"learned"``: the paper's edge, depth and colour inpainting nets.

Per patch, as the authors' inference does (their margin of 20 px is this backend's
``margin``, so the pipeline's patch is already the union bounding box + 20 px):

1. **Inputs** are read under ``context`` only (everything else is zeroed, so the
   nets cannot see the foreground or anything outside the context); each net input is
   zero-padded, centred, to a multiple of 128 for nets with the authors'
   architectures (their ``unit_length``), or of the smallest size the net accepts for
   other nets (:func:`net_unit`: 4 for an edge net, ``2**levels`` for a U-Net; photo3d's
   own nets are trained on unpadded crops, and padding is up to half their work).
2. **Edges** (only in the first ``edge_passes`` inpainting passes, authors: the
   first only, and only if a context edge touches the synthesis region, dilated by
   one pixel): the edge net sees (rgb, inverse depth / its maximum over the context,
   edges, context, synthesis); new edges = output > 0.002 inside the synthesis
   region. If any appear, the net runs up to ``edge_repeats`` more times (authors: 2)
   with them added to its edge input, each time only where the previous run changed
   them (within ``edge_halo``), and stops after a run that changed nothing (the next
   would see the same input). Edges out = context edges + new edges.
3. **Depth**: the patch's normalised disparity ``d`` becomes camera depth
   ``z = DepthMapping().depth(d)`` (``1 / max(3 d, 0.05)``, DESIGN section 3); the
   net sees (log z minus its mean over the context, edges, context, synthesis) and
   predicts the zero-mean log depth; ``z' = exp(out + mean)`` maps back to
   ``d' = clip(1 / (3 z'), 0, 1)``, the inverse of that mapping.
   Its synthesis channel (and the colour net's) is the synthesis region plus the
   gaps a 41x41 closing of context | synthesis fills (:func:`close_gaps`, the
   authors' ``open_small_mask``).
4. **Colour**: the net sees (rgb, edges, context, synthesis). A patch with
   ``sqrt(h w)`` well above 512 is first shrunk (area averaging; factor chosen like
   the authors' so the longer side becomes a multiple of 128; masks re-thresholded;
   the edge channel zeroed, as the authors' code does) and the result is resized
   back bicubically.

The patches of a pass share work (docs/learned.md; ``share=False`` turns it off): the edge
net runs over all of them together, on crops of their joint canvas that cover every
synthesis pixel with ``edge_halo`` pixels of surroundings (:mod:`photo3d.inpaint.crops`;
each at most about ``joint_pixels``), the depth net on clusters and the colour net on
groups of patches that do not conflict (:mod:`photo3d.inpaint.canvas`); after the
first pass contexts are half as deep (``later_context``, the authors' 140 then 70 px).
The depth and colour nets see each canvas (or patch) without the part of its empty
margin (the 20 px around the bounding box) that alone would grow its padded size
(:func:`~photo3d.inpaint.canvas.trim`).

The edges a result reports (what the merge tears a fill along) are the new edges as
one-pixel paths that continue a context edge (:func:`~photo3d.inpaint.edgepaths.edge_paths`,
``paths``): a poorly trained edge net fires in blobs, and every step its depth net
then leaves around a blob would become an edge of the next pass. The nets themselves
see the edge net's output as the authors' inference gives it to them. The authors'
graph-based tracing of one path per context edge end and their depth smoothing between
context and synthesis are not part of this backend. Patches of the same
padded shape run as one batch (at most ``batch_size`` patches and about
``batch_pixels`` pixels), under ``torch.inference_mode()``, on CUDA when available.

Two opt-in speed-ups trade exactness for time (both off by default, so the authors'
nets see what the authors' inference gives them): ``edge_unit=8`` pads the edge net's
input to multiples of 8 instead of 128 (the edge net only needs multiples of 4; its
instance normalisation then sees less zero padding, so outputs change slightly),
and ``precision="bf16"`` runs the convolutions in bfloat16 (about twice as fast on
CPUs with AVX-512 BF16 or AMX; edge probabilities move by up to ~0.01).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from photo3d.camera import DepthMapping
from photo3d.errors import ConfigError, InputError
from photo3d.inpaint.canvas import edges_in, joint_patch, share_canvases, trim, window
from photo3d.inpaint.crops import Box, cover, grow
from photo3d.inpaint.edgepaths import reported_edges
from photo3d.inpaint.netinputs import NetInputs, close_gaps
from photo3d.inpaint.netrun import (  # noqa: F401  (re-exported)
    PRECISIONS,
    UNIT,
    color_scale,
    net_unit,
    padded_shape,
    release_memory,
    run_batched,
)
from photo3d.progress import CountProgress
from photo3d.structures.patch import InpaintResult, Patch

if TYPE_CHECKING:  # torch is imported lazily: photo3d works without it
    import torch

    from photo3d.nets.weights import InpaintingNets


def is_refine(net) -> bool:
    """``net`` is a refine colour net (:mod:`photo3d.nets.refine`): its RGB input holds
    the diffusion fill under the hole, and it returns the fill plus a residual there.

    Example:
        >>> from photo3d.nets import build_net
        >>> is_refine(build_net("color", arch="refine")), is_refine(build_net("color"))
        (True, False)
    """
    config = getattr(net, "config", None)
    return isinstance(config, dict) and config.get("arch") == "refine"


def bundled_weights() -> Path:
    """The folder of the compact nets trained for and shipped with photo3d (small and
    offline, far below the paper's nets in quality; ``--weights compact``; see
    docs/learned.md for how they were trained and how they score).

    Example:
        >>> sorted(p.name for p in bundled_weights().glob("*.safetensors"))
        ['color.safetensors', 'depth.safetensors', 'edge.safetensors']
    """
    return Path(__file__).resolve().parents[1] / "nets" / "compact"


def default_weights(*, progress=None) -> Path:
    """The weights ``learned`` runs when none are given: the paper's nets, i.e. the
    authors' published files (:func:`photo3d.nets.authors.authors_weights`: downloaded
    once into ``~/.cache/photo3d/authors``, checked by SHA-256; no network once there).

    Args:
        progress: ``progress(file name, bytes done, total or None)`` while
            downloading (the command line shows a bar).

    Raises:
        MissingExtra: PyTorch is not installed (checked before any download).
        InputError: not in the cache and not downloadable (one line saying where to
            put the files and that ``--weights compact`` runs the shipped nets).

    Example:
        >>> default_weights().name  # doctest: +SKIP
        'authors'
    """
    from photo3d.nets.authors import authors_weights  # needs PyTorch: checked first

    return authors_weights(progress=progress)


@dataclass(frozen=True)
class LearnedOptions:
    """What changes the ``learned`` backend's output besides its weights (``config.json``
    records it with them).

    Attributes:
        edge_threshold: edge probability above which a synthesis pixel is an edge.
        edge_repeats: extra edge-net runs with the new edges fed back.
        edge_passes: inpainting passes in which the edge net runs (authors: 1, the
            first; later passes use the context's edges as they are).
        edge_unit: the edge net's input is padded to multiples of this (any
            multiple of 4; None: :func:`net_unit`: 128 for the authors'
            architecture, 4 for other edge nets; 8 is the opt-in speed-up for the
            authors' net, see the module docstring).
        precision: ``"fp32"`` or ``"bf16"`` (autocast, opt-in speed-up).
        color_size: target ``sqrt(area)`` of the colour net's input (shrinking only).
        batch_size, batch_pixels: batch limits (patches, padded pixels).
        share: fill the patches of a pass on shared canvases
            (:func:`~photo3d.inpaint.canvas.share_canvases`; False: one net run per
            patch).
        joint_pixels: at most about this many padded pixels per joint edge-net run
            (its memory: the authors' edge net needs about 1.5 GB per Mpx).
        edge_halo: the joint edge-net runs cover the synthesis pixels with crops that
            add this many pixels of the joint canvas on every side
            (:func:`~photo3d.inpaint.crops.cover`); None: the whole joint canvas, in
            horizontal bands of about ``joint_pixels``. With the authors' edge net
            (random weights) on the sample's first pass, edge probabilities inside
            the synthesis differ from one run over the whole canvas by 0.020 on
            average at 48 px (0.018 at 64 px, 0.061 for the bands), for 26 % fewer
            pixels than 64 px.
        paths: report new edges as one-pixel paths continuing context edges (see the
            module docstring; False: every pixel the edge net marks).

    Example:
        >>> LearnedOptions(precision="bf16").precision
        'bf16'
        >>> LearnedOptions(edge_unit=6)
        Traceback (most recent call last):
        ...
        photo3d.errors.ConfigError: edge_unit must be a positive multiple of 4, not 6
    """

    edge_threshold: float = 0.002
    edge_repeats: int = 2
    edge_passes: int = 1
    edge_unit: int | None = None
    precision: str = "fp32"
    color_size: int = 512
    batch_size: int = 8
    batch_pixels: int = 8 * 256 * 256
    share: bool = True
    joint_pixels: int = 600_000
    edge_halo: int | None = 48
    paths: bool = True

    def __post_init__(self) -> None:
        if self.edge_unit is not None and (self.edge_unit <= 0 or self.edge_unit % 4):
            raise ConfigError(f"edge_unit must be a positive multiple of 4, not "
                              f"{self.edge_unit}")
        if self.precision not in PRECISIONS:
            raise ConfigError(f"precision must be one of {', '.join(PRECISIONS)}, "
                              f"not {self.precision!r}")


class LearnedInpainter:
    """Backend ``"learned"``: edge, depth and colour nets (see the module docstring).

    Args:
        weights: folder with the authors' ``*-model.pth`` or our ``*.safetensors``
            (see :func:`photo3d.nets.load_inpainting_nets`); default: the paper's nets
            (:func:`default_weights`, downloaded once); the compact nets shipped with
            photo3d are :func:`bundled_weights`.
        device: torch device (default CUDA when available, else CPU).
        nets: :class:`photo3d.nets.InpaintingNets` already in memory (instead of
            ``weights``).
        options: :class:`LearnedOptions` (default: its defaults).
        changes: fields of ``options`` to replace, e.g. ``precision="bf16"``.

    Attributes:
        units: per net (``"edge"``, ``"depth"``, ``"color"``), the multiple its
            input is padded to.
        timings: seconds spent in each net since construction.
        edge_runs: the windows ``(y0, x0, y1, x1)`` of each joint edge-net run (one
            list of crops per run, joint-canvas pixels) since construction.

    Example:
        >>> from photo3d.nets import InpaintingNets, build_net
        >>> small = dict(levels=3, width=0.125)
        >>> nets = InpaintingNets(build_net("edge", width=0.125, blocks=1).eval(),
        ...                       build_net("depth", **small).eval(),
        ...                       build_net("color", **small).eval(), "cpu", {})
        >>> ctx = np.zeros((20, 24), bool); ctx[:, :12] = True
        >>> p = Patch(np.full((20, 24, 3), 0.5, np.float32) * ctx[..., None],
        ...           np.full((20, 24), 0.3, np.float32) * ctx, np.zeros((20, 24), np.float32),
        ...           ctx, ~ctx, (0, 0))
        >>> r = LearnedInpainter(nets=nets).inpaint([p])[0]
        >>> r.color.shape, r.disparity.shape, r.edges.dtype
        ((20, 24, 3), (20, 24), dtype('float32'))
    """

    name = "learned"
    margin = 20
    later_context = 0.5
    """Context depth after the first pass, as a fraction of the first pass's (read by the
    pipeline; the authors' code: 140 px, then 70 px)."""
    paper_context = True
    """The nets see the paper's context regions only (read by the pipeline): they were
    trained on those, not on :attr:`~photo3d.config.RegionConfig.context_around` or
    ``thin_context``'s larger ones."""
    patchwise = False
    """A pass's patches come in one call (read by the pipeline): the nets fill them in
    batches of their own."""

    def __init__(self, options: LearnedOptions | None = None, *,
                 weights: str | Path | None = None, device: str | torch.device | None = None,
                 nets: InpaintingNets | None = None, **changes) -> None:
        options = replace(options or LearnedOptions(), **changes)
        if nets is None:
            weights = default_weights() if weights is None else weights
            from photo3d.nets.weights import load_inpainting_nets

            nets = load_inpainting_nets(weights, device=device)
        self.nets = nets
        self.options = options
        self.units = {kind: net_unit(getattr(nets, kind)) for kind in ("edge", "depth", "color")}
        if options.edge_unit is not None:
            self.units["edge"] = options.edge_unit
        # the weights folder, for settings() (None: ``nets`` were given in memory)
        self.weights = None if weights is None else Path(weights)
        self._sha256: dict[str, str] | None = None  # of the weights files, once
        # Windows of the joint edge-net runs, one list per run over the pass's crops.
        self.edge_runs: list[list[Box]] = []
        self.batch = dict(batch_size=options.batch_size, batch_pixels=options.batch_pixels)
        self.mapping = DepthMapping()
        # Seconds spent in each net since construction (read by the benchmark).
        self.timings: dict[str, float] = {"edge": 0.0, "depth": 0.0, "color": 0.0}

    def settings(self) -> dict[str, object]:
        """What changes this backend's output, JSON-able (``config.json`` records it).

        ``weights`` is ``"bundled compact"`` (:func:`bundled_weights`), the weights
        folder, or ``"nets given in memory"``; ``sha256`` maps each weights file in
        it to its SHA-256 (the authors' are
        :data:`photo3d.nets.weights.OFFICIAL_SHA256`), computed once.

        Example:
            >>> s = LearnedInpainter(weights=bundled_weights(), precision="bf16").settings()
            >>> s["weights"], s["precision"], sorted(s["sha256"])[0]
            ('bundled compact', 'bf16', 'color.safetensors')
        """
        if self._sha256 is None:
            from photo3d.files.download import sha256_of
            from photo3d.nets.weights import KINDS

            names = {f"{k}-model.pth" for k in KINDS} | {f"{k}.safetensors" for k in KINDS}
            self._sha256 = {} if self.weights is None else {
                p.name: sha256_of(p) for p in sorted(self.weights.iterdir()) if p.name in names}
        if self.weights is None:
            weights = "nets given in memory"
        elif self.weights.resolve() == bundled_weights():
            weights = "bundled compact"
        else:
            weights = str(self.weights.resolve())
        return {"name": self.name, "weights": weights, "sha256": dict(self._sha256),
                "nets": dict(self.nets.sources), "device": str(self.nets.device),
                **asdict(self.options), "units": dict(self.units),
                "later_context": self.later_context, "paper_context": self.paper_context}

    def _run(self, kind: str, inputs: list[np.ndarray]) -> list[np.ndarray]:
        if not inputs:
            return []
        import torch

        t = time.perf_counter()
        out = run_batched(getattr(self.nets, kind), inputs, device=self.nets.device,
                          unit=self.units[kind],
                          autocast=torch.bfloat16 if self.options.precision == "bf16" else None,
                          **self.batch)
        release_memory()
        self.timings[kind] += time.perf_counter() - t
        if not all(np.isfinite(o).all() for o in out):  # e.g. finite but huge weights
            source = "given in memory" if self.weights is None else str(self.weights)
            raise InputError(f"the learned inpainter's {kind} net gave NaN or infinite "
                             f"values with weights {source}; the weights are not usable")
        return out

    def _edges(self, items: list[NetInputs], *, run: bool) -> list[np.ndarray]:
        edges = [it.edges for it in items]
        if not run:
            return edges
        todo = [i for i, it in enumerate(items) if it.needs_edges]
        for _ in range(1 + self.options.edge_repeats):
            if not todo:
                break
            outs = self._run("edge", [items[i].edge_input(edges[i]) for i in todo])
            new = {i: ((o[0] > self.options.edge_threshold) & (items[i].syn > 0)).astype(np.float32)
                   for i, o in zip(todo, outs, strict=True)}
            changed = [i for i in todo if (np.maximum(items[i].edges, new[i]) != edges[i]).any()]
            for i in todo:
                edges[i] = np.maximum(items[i].edges, new[i])
            todo = changed  # a run that changes nothing would repeat itself
        return edges

    def _tears(self, edges: np.ndarray, p: Patch) -> np.ndarray:
        return reported_edges(edges, p) if self.options.paths else edges.astype(np.float32)

    def _colors(self, items: list[NetInputs], edges: list[np.ndarray]) -> list[np.ndarray]:
        import torch
        import torch.nn.functional as F

        refine = is_refine(self.nets.color)
        inputs, scaled, fills = [], [], []
        for it, e in zip(items, edges, strict=True):
            h, w = it.ctx.shape
            frac = color_scale(h, w, self.options.color_size)
            rgb = it.filled_rgb() if refine else it.rgb
            fills.append(rgb if refine else None)
            if frac >= 1:
                inputs.append(np.concatenate([rgb, np.stack([e, it.ctx, it.hole])]))
                scaled.append(None)
                continue
            size = (int(h * frac), int(w * frac))
            masks = F.interpolate(torch.from_numpy(np.stack([it.syn, it.ctx]))[None], size,
                                  mode="area")[0]
            syn = (masks[0] > 0).numpy()
            ctx = (masks[1] >= 1 - 1e-6).numpy() & ~syn
            hole = close_gaps(ctx, syn)
            small = F.interpolate(torch.from_numpy(rgb)[None], size, mode="area")[0].numpy()
            small = small * (ctx | hole) if refine else small * ctx
            inputs.append(np.concatenate([small, np.stack(
                [np.zeros(size, np.float32), ctx, hole]).astype(np.float32)]))
            scaled.append((h, w))
        outs = self._run("color", inputs)
        result = []
        for it, o, x, hw, fill in zip(items, outs, inputs, scaled, fills, strict=True):
            if refine and hw is not None:  # the residual, brought back to the full fill
                o = F.interpolate(torch.from_numpy(np.ascontiguousarray(o - x[:3]))[None], hw,
                                  mode="bicubic", align_corners=False)[0].numpy()
                o = fill + it.hole * o
            elif hw is not None:
                o = F.interpolate(torch.from_numpy(np.ascontiguousarray(o))[None], hw,
                                  mode="bicubic", align_corners=False)[0].numpy()
            result.append(np.clip(np.moveaxis(o, 0, 2), 0.0, 1.0).astype(np.float32))
        return result

    def fill_colors(self, patches: Sequence[Patch],
                    edges: Sequence[np.ndarray] | None = None) -> list[np.ndarray]:
        """The colour net alone on ``patches`` (each seen without the margin that only
        adds padding, as :meth:`inpaint` does), with ``edges`` (``(h, w)`` per patch;
        None: none), e.g. to score a colour net while it trains.

        Returns:
            ``(h, w, 3) float32`` per patch, meaningful under its synthesis region.
        """
        edges = [np.zeros(p.shape, np.float32) for p in patches] if edges is None else edges
        seen = [trim(p, self.units["color"]) for p in patches]
        out = self._colors([NetInputs(t, self.mapping) for t in seen],
                           [window(e, p.origin, t) for e, p, t in zip(edges, patches, seen,
                                                                       strict=True)])
        return [window(o, t.origin, p) for o, t, p in zip(out, seen, patches, strict=True)]

    def _joint_edges(self, patches: Sequence[Patch]) -> list | None:
        """New edges of all ``patches`` from edge-net runs over them together: the
        :func:`~photo3d.inpaint.canvas.joint_patch` of those whose context edges touch
        their synthesis, cut into crops around its synthesis pixels
        (:func:`~photo3d.inpaint.crops.cover`, ``edge_halo``, at most about
        ``joint_pixels`` padded pixels per run). A repeat (``edge_repeats``) runs only
        where the previous run changed the new edges (within ``edge_halo``: their
        crops cover the synthesis pixels there), and none follows a run that changed
        nothing (it would see the same input). Returns ``[(new (H, W) bool,
        origin)]`` (empty when no patch needs the edge net), or None when their
        contexts cannot share one image."""
        todo = [p for p in patches if NetInputs.touches(p)]
        if not todo:
            return []
        whole = joint_patch(todo)
        if whole is None:
            return None
        it = NetInputs(whole, self.mapping)
        syn = it.syn > 0
        new, target = np.zeros(whole.shape, bool), syn
        for _ in range(1 + self.options.edge_repeats):
            crops = cover(target, halo=self.options.edge_halo, unit=self.units["edge"],
                          max_pixels=self.options.joint_pixels,
                          phase=getattr(self.nets.edge, "input_multiple", 1))
            full = it.edge_input(np.maximum(it.edges, new))
            outs = self._run("edge", [c.take(full) for c in crops])
            del full
            before = new.copy()
            for c, o in zip(crops, outs, strict=True):
                core = c.slices()
                new[core] = np.where(target[core], o[0][c.local()] > self.options.edge_threshold,
                                     new[core])
            self.edge_runs.append([c.window for c in crops])
            changed = new != before
            if not changed.any():  # the next run would see the same input
                break
            target = syn & grow(changed, self.options.edge_halo)
        return [(new, whole.origin)]

    def _depths(self, items: list[NetInputs], edges: list[np.ndarray]) -> list[np.ndarray]:
        outs = self._run("depth", [np.stack([it.log_depth, e, it.ctx, it.hole])
                                   for it, e in zip(items, edges, strict=True)])
        result = []
        for it, d in zip(items, outs, strict=True):
            z = np.exp(np.clip(d[0].astype(np.float64) + it.log_mean, -30.0, 30.0))
            disp = (1.0 / z - self.mapping.offset) / self.mapping.scale
            result.append(np.clip(disp, 0, 1).astype(np.float32))
        return result

    def _shared(self, patches: Sequence[Patch], joint, progress: CountProgress | None):
        """Depth on clusters of non-conflicting patches, colour on whole groups (so
        the colour size limit shrinks them), edges from the joint run; each canvas
        without the empty margin that alone would grow its padded size
        (:func:`~photo3d.inpaint.canvas.trim`)."""
        color = [None] * len(patches)
        disparity = [None] * len(patches)
        edges = [None] * len(patches)
        stages = (("depth", share_canvases(patches, unit=self.units["depth"])),
                  ("color", share_canvases(patches, cluster=False)))
        done = 0
        for kind, canvases in stages:
            nets_see = [trim(c.patch, self.units[kind]) for c in canvases]
            order = sorted(range(len(canvases)), key=lambda k: padded_shape(*nets_see[k].shape))
            step = self.batch["batch_size"]
            for s in range(0, len(order), step):
                chunk = [nets_see[k] for k in order[s:s + step]]
                items = [NetInputs(c, self.mapping) for c in chunk]
                es = [edges_in(c, joint) for c in chunk]
                outs = (self._depths if kind == "depth" else self._colors)(items, es)
                for k, c, o, e in zip(order[s:s + step], chunk, outs, es, strict=True):
                    for i in canvases[k].members:
                        if kind == "depth":
                            disparity[i] = window(o, c.origin, patches[i])
                            edges[i] = self._tears(window(e, c.origin, patches[i]),
                                                   patches[i])
                        else:
                            color[i] = window(o, c.origin, patches[i])
                            done += 1
                            if progress is not None:
                                progress(done, len(patches))
        return [InpaintResult(c, d, e) for c, d, e in zip(color, disparity, edges, strict=True)]

    def _chunk(self, patches: Sequence[Patch], *, run_edges: bool) -> list[InpaintResult]:
        edges = self._edges([NetInputs(p, self.mapping) for p in patches], run=run_edges)
        out = {}
        for kind in ("depth", "color"):  # without the margin that only adds padding
            seen = [trim(p, self.units[kind]) for p in patches]
            fill = self._depths if kind == "depth" else self._colors
            res = fill([NetInputs(t, self.mapping) for t in seen],
                       [window(e, p.origin, t) for e, p, t in zip(edges, patches, seen,
                                                                   strict=True)])
            out[kind] = [window(r, t.origin, p) for r, t, p in zip(res, seen, patches,
                                                                    strict=True)]
        return [InpaintResult(color=c, disparity=d, edges=self._tears(e, p))
                for e, d, c, p in zip(edges, out["depth"], out["color"], patches, strict=True)]

    def inpaint(self, patches: Sequence[Patch], *, progress: CountProgress | None = None,
                pass_index: int = 0) -> list[InpaintResult]:
        """Fill every patch's synthesis region; one result per patch, same order.

        The edge net runs only when ``pass_index < edge_passes``. With ``share``
        (unless the patches' contexts hold different layers at one position while
        the edge net runs) it runs once over all patches together
        (:func:`~photo3d.inpaint.canvas.joint_patch`), the depth net on clusters and
        the colour net on groups of non-conflicting patches
        (:func:`~photo3d.inpaint.canvas.share_canvases`); else once per patch."""
        run_edges = pass_index < self.options.edge_passes
        if self.options.share and patches:
            joint = self._joint_edges(patches) if run_edges else []
            if joint is not None:
                return self._shared(patches, joint, progress)
        order = sorted(range(len(patches)), key=lambda i: padded_shape(*patches[i].shape))
        results: list[InpaintResult | None] = [None] * len(patches)
        step = self.batch["batch_size"]
        for s in range(0, len(order), step):
            chunk = order[s:s + step]
            for i, r in zip(chunk, self._chunk([patches[i] for i in chunk], run_edges=run_edges),
                            strict=True):
                results[i] = r
            if progress is not None:
                progress(min(s + step, len(order)), len(patches))
        return results  # type: ignore[return-value]

