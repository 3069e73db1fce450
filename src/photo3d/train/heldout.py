"""A held-out score logged while the colour net trains (``RUN_DIR/heldout.csv``).

The protocol is the held-out fill benchmark's regions test
(:func:`photo3d.eval.heldout.evaluate_photo`, ``photo3d eval --heldout``): every photo
at 640 px, 4 first-pass region shapes of the motorcycle's ground-truth disparity and
the evaluation scenes' depth pasted at places seeded by the photo's file name, each
synthesis region filled from its context alone (one patch per call), LPIPS, PSNR and
SSIM inside the region; per photo the mean over its regions, then the mean over the
photos. The fill is the net being trained, run by the learned backend's own colour
path (:meth:`photo3d.inpaint.learned.LearnedInpainter.fill_colors`: the same input
building, trimming and resizing as ``make --inpainter learned``, no edges: the
photos have no depth); the diffusion backend is scored once on the same set for
reference.

``heldout.csv``: ``step, method, lpips, psnr, ssim, seconds`` (``method`` is
``diffusion`` once, at step 0, then ``net``).
"""

from __future__ import annotations

import csv
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from torch import nn

from photo3d.errors import InputError
from photo3d.files.atomic import write_bytes
from photo3d.structures.patch import InpaintResult, Patch

PHOTOS = 24
"""Held-out photos scored (the first of the folder, by name)."""
COLUMNS = ("step", "method", "lpips", "psnr", "ssim", "seconds")


class ColorNetFill:
    """An inpainter that fills colour with one colour net alone (disparity and edges
    zero): the learned backend's colour path
    (:meth:`~photo3d.inpaint.learned.LearnedInpainter.fill_colors`).

    Args:
        net: a colour net (in eval mode while it fills).
        device: where it lives.
    """

    name = "net"

    def __init__(self, net: nn.Module, device) -> None:
        from photo3d.inpaint.learned import LearnedInpainter
        from photo3d.nets.weights import InpaintingNets

        self.margin = LearnedInpainter.margin
        self._backend = LearnedInpainter(nets=InpaintingNets(None, None, net, device, {}))

    def inpaint(self, patches: Sequence[Patch], *, progress=None,
                pass_index: int = 0) -> list[InpaintResult]:
        colors = self._backend.fill_colors(patches)
        return [InpaintResult(c, np.zeros(p.shape, np.float32), np.zeros(p.shape, np.float32))
                for c, p in zip(colors, patches, strict=True)]


@dataclass(frozen=True)
class HeldoutSet:
    """Photos and region shapes of the held-out score (see the module docstring).

    Attributes:
        images: ``(H, W, 3) float32`` per photo, at 640 px.
        names: their file names (which seed the placements).
        bank: the region shapes (:func:`photo3d.eval.heldout_data.region_bank`).
    """

    images: tuple[np.ndarray, ...]
    names: tuple[str, ...]
    bank: tuple

    @classmethod
    def from_folder(cls, folder: str | Path, *, photos: int = PHOTOS) -> HeldoutSet:
        """The first ``photos`` photos of ``folder`` (sorted by name).

        Raises:
            InputError: the folder is missing or holds no photo.
        """
        from photo3d.eval.heldout_data import SIZE, load_photo, photo_files, region_bank

        files = photo_files(folder)[:photos]
        images = tuple(load_photo(p, SIZE) for p in files)
        return cls(images, tuple(p.name for p in files), region_bank(SIZE))

    def score(self, fill_with) -> dict[str, float]:
        """Mean ``lpips``, ``psnr``, ``ssim`` of the regions of every photo filled by
        ``fill_with`` (an inpainter), and ``seconds`` taken."""
        from photo3d.eval.heldout import evaluate_photo

        t = time.perf_counter()
        per = []
        for image, name in zip(self.images, self.names, strict=True):
            try:
                rec = evaluate_photo(image, name, {"m": fill_with}, bank=self.bank, border=0)
            except InputError:  # too small for any shape: not part of the set
                continue
            per.append(rec["regions"]["m"])
        if not per:
            raise InputError("no held-out photo is large enough for the region shapes")
        out = {k: float(np.mean([r[k] for r in per])) for k in ("lpips", "psnr", "ssim")}
        out["seconds"] = time.perf_counter() - t
        return out


class HeldoutLog:
    """``heldout.csv`` of a run, truncated to ``start`` on resume (rows of later steps
    go; the diffusion row stays)."""

    def __init__(self, path: Path, start: int) -> None:
        self.path = path
        self.rows: list[dict[str, str]] = []
        if path.is_file():
            with open(path, newline="") as f:
                self.rows = [r for r in csv.DictReader(f)
                             if r.get("step", "").isdigit() and int(r["step"]) <= start]
        self._write()

    def has(self, method: str, step: int | None = None) -> bool:
        return any(r["method"] == method and (step is None or int(r["step"]) == step)
                   for r in self.rows)

    def add(self, step: int, method: str, scores: dict[str, float]) -> None:
        self.rows.append({"step": str(step), "method": method,
                          **{k: f"{scores[k]:.6g}" for k in COLUMNS[2:]}})
        self._write()

    def _write(self) -> None:
        import io

        text = io.StringIO(newline="")
        writer = csv.DictWriter(text, COLUMNS)
        writer.writeheader()
        writer.writerows(self.rows)
        write_bytes(self.path, text.getvalue().encode())


def score_net(heldout: HeldoutSet, net: nn.Module, device) -> dict[str, float]:
    """:meth:`HeldoutSet.score` of ``net`` as the colour fill (in eval mode for it,
    restored to its previous mode after)."""
    was_training = net.training
    net.eval()
    try:
        return heldout.score(ColorNetFill(net, device))
    finally:
        net.train(was_training)


def score_diffusion(heldout: HeldoutSet) -> dict[str, float]:
    """:meth:`HeldoutSet.score` of the diffusion backend (the reference)."""
    from photo3d.inpaint.diffusion import DiffusionInpainter

    return heldout.score(DiffusionInpainter())
