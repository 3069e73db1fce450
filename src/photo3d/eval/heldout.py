"""The held-out fill benchmark: first-pass region shapes pasted onto other photos
(paper, Sec. 3.3 and the supplement's dataset generation), and the border ring.

Three measurements per photo (resized to 640 px on its longer side), each against the
photo's own pixels:

* **regions**: ``count`` (default 4) context/synthesis pairs of the pipeline's first
  pass (:func:`~photo3d.eval.heldout_data.region_bank`: the motorcycle's ground-truth
  disparity and the synthetic scenes' depth) are laid over the photo at seeded random
  places (the seed is :data:`~photo3d.eval.heldout_data.SEED` and the photo's file
  name, so a photo's regions do not depend on which other photos share its folder).
  Each backend fills each synthesis region from its context alone: the patch it gets
  (:func:`~photo3d.eval.heldout_data.known_patch`) holds the photo's colour under the
  context and zeros everywhere else, a flat disparity under the context and no depth
  edges (the photos have no depth), and each patch is a call of its own (the learned
  backend joins the patches of one call on a shared canvas, where one region's
  context could show another's synthesis pixels).
* **border**: the outer ``border`` (48) px are hidden and each backend extrapolates
  them from a band of the photo next to them (the first pass's context depth, 62 px
  at 640), the regions-style border test.
* **make border** (:func:`make_border`): the end-to-end check of what
  :func:`photo3d.make` does at the frame: the outer 24 px are hidden, ``make`` builds
  the 3D photo of the rest (flat depth, the given configuration) and it is rendered
  from its own camera over the whole frame.

Scores (inside the synthesis region or the ring): PSNR (capped at :data:`PSNR_CAP`
dB), SSIM and LPIPS of the *composite* (the fill under the region, the truth
elsewhere), SSIM and LPIPS as their per-pixel maps averaged over the region (the same
masked LPIPS as ``photo3d eval``'s disoccluded scores, :func:`photo3d.eval.lpips.lpips`),
computed on the region's bounding box grown by :data:`SCORE_PAD` px (the whole photo for
the ring). Taking the truth outside the region keeps an unfilled outside from counting;
averaging the map over the region keeps the box's untouched pixels from diluting it.
Per photo each score is the mean over its regions; the summary is the mean over photos.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.ndimage import distance_transform_edt

from photo3d.config import Config
from photo3d.errors import InputError
from photo3d.eval.heldout_data import (
    COUNT,
    SEED,
    SIZE,
    RegionShape,
    border_masks,
    known_patch,
    load_photo,
    place,
    region_bank,
)
from photo3d.eval.metrics import psnr, ssim
from photo3d.inpaint.base import Inpainter
from photo3d.structures.patch import InpaintResult, Patch

BORDER = 48
"""Width of the hidden frame of the border test, in pixels."""
MAKE_RING = 24
"""Width of the hidden frame of :func:`make_border`, in pixels."""
PSNR_CAP = 100.0
"""PSNR of a perfect fill (an MSE of 1e-10), so means stay finite."""
SCORE_PAD = 16
"""Pixels of truth around a region's bounding box in the scored crop."""
METHODS = ("diffusion", "structured", "learned", "replicate")
"""Default backends: the built-in inpainters and :class:`ReplicateFill`."""


class ReplicateFill:
    """Backend ``"replicate"``: every synthesis pixel copies its nearest context pixel
    (on the frame this is what :func:`photo3d.stages.border.extend_border` does today).

    Example:
        >>> ctx = np.zeros((1, 4), bool); ctx[0, :2] = True
        >>> color = np.zeros((1, 4, 3), np.float32); color[0, 1] = 0.5
        >>> p = Patch(color, ctx * 0.5, np.zeros((1, 4), np.float32), ctx, ~ctx, (0, 0))
        >>> ReplicateFill().inpaint([p])[0].color[0, :, 0].tolist()
        [0.0, 0.5, 0.5, 0.5]
    """

    name = "replicate"
    margin = 0

    def inpaint(self, patches: Sequence[Patch], *, progress=None,
                pass_index: int = 0) -> list[InpaintResult]:
        out = []
        for p in patches:
            iy, ix = distance_transform_edt(~p.context, return_distances=False,
                                            return_indices=True)
            out.append(InpaintResult(p.color[iy, ix], p.disparity[iy, ix],
                                     np.zeros(p.shape, np.float32)))
        return out


def backend(name: str, *, weights: str | Path | None = None) -> Inpainter:
    """The fill ``name``: ``replicate`` or a registered inpainter (``weights``: the
    learned backend's, default its shipped compact nets; ``"random"``: the authors'
    architectures with random weights)."""
    if name == "replicate":
        return ReplicateFill()
    from photo3d.inpaint import get_inpainter

    if name == "learned" and str(weights) == "random":
        from photo3d.eval.evaluate import random_nets

        return get_inpainter(name, nets=random_nets(seed=0))

    if name == "learned" and weights is None:  # eval's default: the shipped compact nets
        from photo3d.inpaint.learned import bundled_weights

        weights = bundled_weights()
    options = {"weights": weights} if name == "learned" else {}
    return get_inpainter(name, **options)


def fill(fill_with: Inpainter, image: np.ndarray, context: np.ndarray,
         synthesis: np.ndarray, origin: tuple[int, int]) -> np.ndarray:
    """``(h, w, 3) float32``: ``fill_with``'s colours over the masks' window (one call,
    one patch; only values under ``synthesis`` mean anything)."""
    m = int(fill_with.margin)
    patch = known_patch(image, context, synthesis, origin, margin=m)
    result = fill_with.inpaint([patch], pass_index=0)[0]
    h, w = context.shape
    return np.clip(result.color[m:m + h, m:m + w], 0.0, 1.0).astype(np.float32)


def score(filled: np.ndarray, truth: np.ndarray, mask: np.ndarray, *,
          lpips: bool = True) -> dict[str, float]:
    """PSNR (capped), SSIM and LPIPS of ``filled`` inside ``mask``, the truth outside.

    Args:
        filled, truth: ``(h, w, 3) float32`` in [0, 1] (at least 32 x 32 for LPIPS).
        mask: ``(h, w) bool`` the filled pixels.
        lpips: also LPIPS (needs torch).

    Example:
        >>> t = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
        >>> m = np.zeros((32, 32), bool); m[8:24, 8:24] = True
        >>> score(t, t, m, lpips=False)
        {'psnr': 100.0, 'ssim': 1.0}
    """
    composite = np.where(mask[..., None], filled, truth).astype(np.float32)
    out = {"psnr": min(psnr(composite, truth, mask), PSNR_CAP),
           "ssim": ssim(composite, truth, mask)}
    if lpips:
        from photo3d.eval.lpips import lpips as lpips_fn

        out["lpips"] = lpips_fn(composite, truth, mask)
    return out


def _crop(y: int, x: int, h: int, w: int, shape: tuple[int, int]) -> tuple[slice, slice]:
    """The scored window: the box grown by SCORE_PAD, at least 32 px, inside ``shape``."""
    out = []
    for start, size, limit in ((y, h, shape[0]), (x, w, shape[1])):
        lo, hi = max(0, start - SCORE_PAD), min(limit, start + size + SCORE_PAD)
        grow = max(0, 32 - (hi - lo))
        lo = max(0, lo - grow)
        out.append(slice(lo, min(limit, max(hi, lo + 32))))
    return out[0], out[1]


def evaluate_photo(image: np.ndarray, name: str, fills: dict[str, Inpainter], *,
                   bank: Sequence[RegionShape], count: int = COUNT, seed: int = SEED,
                   border: int = BORDER, lpips: bool = True) -> dict:
    """Regions and border scores of one photo for every fill (see the module doc).

    Args:
        image: ``(H, W, 3) float32`` the photo at its benchmark size.
        name: its file name (seeds the placement).
        fills: method name -> backend.
        bank: the region pairs to place.
        count, seed: pairs per photo and the fixed seed.
        border: hidden frame of the border test (0: no border test).
        lpips: also LPIPS.

    Returns:
        JSON-able ``{"size": [W, H], "regions": {method: {metric: mean}}, "border":
        {method: {metric: value}}, "placements": [...], "seconds": {method: s}}``.

    Raises:
        InputError: the photo is too small for the border test or no pair fits it.
    """
    h, w = image.shape[:2]
    if min(h, w) < max(64, 2 * border + 16):
        raise InputError(f"{name} is {w}x{h}: too small (needs at least "
                         f"{max(64, 2 * border + 16)} px on each side)")
    places = place((h, w), bank, name, count=count, seed=seed)
    if not places:
        raise InputError(f"{name} is {w}x{h}: no region pair of the bank fits it")
    out: dict = {"size": [w, h], "regions": {}, "border": {}, "seconds": {},
                 "placements": [{"source": bank[p.shape].source, "shape": p.shape, "y": p.y,
                                 "x": p.x, "synthesis": int(bank[p.shape].synthesis.sum())}
                                for p in places]}
    depth = Config().spatial(Config().regions.context_iterations, max(h, w))
    ring_ctx, ring = border_masks((h, w), border, depth)
    for method, fill_with in fills.items():
        t = time.perf_counter()
        per = []
        for p in places:
            s = bank[p.shape]
            filled = image.copy()
            sh, sw = s.shape
            filled[p.y:p.y + sh, p.x:p.x + sw] = fill(fill_with, image, s.context,
                                                     s.synthesis, (p.y, p.x))
            mask = np.zeros((h, w), bool)
            mask[p.y:p.y + sh, p.x:p.x + sw] = s.synthesis
            win = _crop(p.y, p.x, sh, sw, (h, w))
            per.append(score(filled[win], image[win], mask[win], lpips=lpips))
        out["regions"][method] = {k: float(np.mean([r[k] for r in per])) for k in per[0]}
        if border > 0:
            filled = fill(fill_with, image, ring_ctx, ring, (0, 0))
            out["border"][method] = score(filled, image, ring, lpips=lpips)
        out["seconds"][method] = time.perf_counter() - t
    return out


def make_border(image: np.ndarray, *, config: Config | None = None, ring: int = MAKE_RING,
                inpainter: Inpainter | None = None, lpips: bool = True) -> dict[str, float]:
    """What :func:`photo3d.make` puts beyond the frame, scored against the true pixels.

    The outer ``ring`` px of ``image`` are hidden; ``make`` builds the 3D photo of the
    rest with flat depth and ``config`` (default :class:`Config`), its camera the full
    photo's (focal ``max(H, W)``) with the principal point shifted by ``ring``; the
    3D photo is rendered from that camera over the full ``W x H`` frame (default
    render settings) and the ring is scored (:func:`score`).

    Args:
        image: ``(H, W, 3) float32`` the photo (the benchmark uses 640 px).
        config: the configuration ``make`` runs with.
        ring: hidden frame in pixels.
        inpainter: passed to ``make``.
        lpips: also LPIPS.

    Returns:
        ``{"psnr", "ssim", "lpips"}`` in the ring, and ``"inner_psnr"``: the render
        against the photo inside (a check that the render lines up, not a fill score).
    """
    from photo3d.camera import Camera, Intrinsics
    from photo3d.pipeline import make

    h, w = image.shape[:2]
    if min(h, w) <= 2 * ring + 16:
        raise InputError(f"image is {w}x{h}: too small for a {ring} px ring")
    full = Intrinsics.default(w, h)
    inner = image[ring:h - ring, ring:w - ring]
    k = Intrinsics(full.fx, full.fy, full.cx - ring, full.cy - ring, w - 2 * ring, h - 2 * ring)
    photo = make(inner, depth=np.ones(inner.shape[:2], np.float32), config=config or Config(),
                 intrinsics=k, inpainter=inpainter)
    view = np.clip(photo.render(Camera(full, np.eye(4))).color, 0.0, 1.0)
    hidden = np.ones((h, w), bool)
    hidden[ring:h - ring, ring:w - ring] = False
    out = score(view, image, hidden, lpips=lpips)
    out["inner_psnr"] = psnr(view, image, ~hidden)
    return out


@dataclass(frozen=True)
class HeldoutResult:
    """Scores of a held-out run.

    Attributes:
        methods: the fills, in order.
        photos: file name -> :func:`evaluate_photo`'s record (plus ``"make_border"``).
        mean: ``{"regions" | "border": {method: {metric: mean}}, "make_border":
            {metric: mean}}`` over the photos.
        skipped: file name -> why (unreadable or too small).
        notes: method -> why it did not run (a missing optional package).
        settings: count, seed, size, border, ring, bank size.
    """

    methods: tuple[str, ...]
    photos: dict[str, dict]
    mean: dict
    skipped: dict[str, str] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-able record (keys ``methods`` and ``pairs``, the region pairs used, as
        every ``photo3d eval`` results file has)."""
        return {"methods": list(self.methods), "pairs": self.settings.get("pairs", {}),
                "settings": self.settings, "photos": self.photos, "mean": self.mean,
                "skipped": self.skipped, "notes": self.notes}


def _mean(records: list[dict]) -> dict:
    acc: dict = {}
    for rec in records:
        for k, v in rec.items():
            if isinstance(v, dict):
                acc.setdefault(k, []).append(v)
            else:
                acc.setdefault(k, []).append(float(v))
    return {k: _mean(v) if isinstance(v[0], dict) else float(np.mean(v)) for k, v in acc.items()}


def evaluate_heldout(photos: Sequence[str | Path], *, methods: Sequence[str] = METHODS,
                     weights: str | Path | None = None, count: int = COUNT, seed: int = SEED,
                     size: int = SIZE, border: int = BORDER,
                     make_config: Config | None = None, ring: int = MAKE_RING,
                     lpips: bool = True, bank: Sequence[RegionShape] | None = None,
                     progress: Callable[[str], None] | None = None) -> HeldoutResult:
    """Run the benchmark over ``photos`` (files; see the module doc).

    Args:
        photos: photo files (a folder's: :func:`~photo3d.eval.heldout_data.photo_files`).
        methods: fills by name (:func:`backend`).
        weights: the learned backend's weights (default: its compact nets).
        count, seed, size, border: regions per photo, placement seed, photo size,
            border test width (0: none).
        make_config: run :func:`make_border` with this configuration (None: skip it).
        ring: its hidden frame.
        lpips: also LPIPS (needs torch).
        bank: region pairs (default :func:`~photo3d.eval.heldout_data.region_bank`
            at ``size``).
        progress: ``progress(line)`` after each photo.
    """
    bank = region_bank(size) if bank is None else bank
    fills, notes = {}, {}
    for m in methods:  # a fill whose optional package is missing is noted, not run
        try:
            fills[m] = backend(m, weights=weights)
        except ImportError as err:
            notes[m] = f"skipped: {err}"
    if not fills:
        raise InputError("no fill can run: " + "; ".join(f"{m} {v}" for m, v in notes.items()))
    done, skipped = {}, {}
    for path in photos:
        name = Path(path).name
        t = time.perf_counter()
        try:
            image = load_photo(path, size)
            rec = evaluate_photo(image, name, fills, bank=bank, count=count, seed=seed,
                                 border=border, lpips=lpips)
            if make_config is not None:
                rec["make_border"] = make_border(image, config=make_config, ring=ring,
                                                 lpips=lpips)
        except InputError as err:  # recorded and reported, the other photos go on
            if isinstance(err, ImportError):  # a missing extra (LPIPS): no photo can run
                raise
            skipped[name] = str(err)
            if progress:
                progress(f"{name}: skipped: {err}")
            continue
        done[name] = rec
        if progress:
            scores = ", ".join(f"{m} {v.get('lpips', v['psnr']):.3f}"
                               for m, v in rec["regions"].items())
            progress(f"{name}: {time.perf_counter() - t:.1f} s; regions "
                     f"{'LPIPS' if lpips else 'PSNR'}: {scores}")
    if not done:
        raise InputError(f"no usable photo among {len(skipped)}: "
                         + "; ".join(f"{k}: {v}" for k, v in skipped.items()))
    mean = _mean([{k: v for k, v in r.items() if k in ("regions", "border", "make_border")}
                  for r in done.values()])
    used = [p for r in done.values() for p in r["placements"]]
    settings = {"count": count, "seed": seed, "size": size, "border": border,
                "ring": ring if make_config is not None else None, "bank": len(bank),
                "pairs": {"used": len(used), "sources": sorted({p["source"] for p in used}),
                          "synthesis_pixels": int(sum(p["synthesis"] for p in used))}}
    return HeldoutResult(tuple(fills), done, mean, skipped=skipped, notes=notes,
                         settings=settings)


def table(record: dict) -> str:
    """Markdown tables of a :meth:`HeldoutResult.to_dict` record: the mean over the
    photos per method, the end-to-end border, then every photo."""
    metrics = [m for m in ("lpips", "psnr", "ssim")
               if any(m in v for v in record["mean"].get("regions", {}).values())]

    def cells(scores: dict | None) -> list[str]:
        return [f"{scores[m]:.2f}" if m == "psnr" else f"{scores[m]:.3f}"
                if scores and m in scores else "" for m in metrics]

    head = " | ".join(f"{part} {m.upper()}" for part in ("regions", "border") for m in metrics)
    rule = "|" + " --- |" * (1 + 2 * len(metrics))
    s = record["settings"]
    lines = [f"Mean over {len(record['photos'])} photos ({s['count']} regions each at "
             f"{s['size']} px, border {s['border']} px):", "", f"| method | {head} |", rule]
    for m in record["methods"]:
        lines.append(f"| {m} | " + " | ".join(cells(record["mean"].get("regions", {}).get(m))
                                            + cells(record["mean"].get("border", {}).get(m)))
                     + " |")
    if "make_border" in record["mean"]:
        mb = record["mean"]["make_border"]
        lines += ["", f"End to end (`make`, outer {s['ring']} px hidden, rendered over the "
                  f"full frame): " + ", ".join(f"{m.upper()} {c}" for m, c in
                                               zip(metrics, cells(mb), strict=True))
                  + f"; inner PSNR {mb['inner_psnr']:.2f} dB."]
    lines += ["", f"| photo | method | {head} |", "|" + " --- |" * (2 + 2 * len(metrics))]
    for name, rec in record["photos"].items():
        for m in record["methods"]:
            lines.append(f"| {name} | {m} | " + " | ".join(
                cells(rec["regions"].get(m)) + cells(rec["border"].get(m))) + " |")
    lines += [f"\nSkipped {k}: {v}" for k, v in record.get("skipped", {}).items()]
    lines += [f"\nNot run: {k}: {v}" for k, v in record.get("notes", {}).items()]
    return "\n".join(lines) + "\n"
