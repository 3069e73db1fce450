"""Score novel-view methods on a stereo pair: render the right view, compare.

Methods (all from the same left image and ground-truth depth):

* ``forward-warp``: the left view splatted into the right view, holes left black;
* ``stretch``: photo3d's mesh without cutting at discontinuities (no inpainting);
* ``diffusion``: photo3d with the diffusion inpainter;
* ``structured``: photo3d with the structure-then-texture inpainter (the default fill:
  continued edges, piecewise diffusion, exemplar texture;
  :mod:`photo3d.inpaint.structured`);
* ``learned``: photo3d with the learned inpainter (the given weights; when none
  are given the compact weights shipped with photo3d; ``weights="random"``: the
  authors' architectures with random weights, reported as such);
* ``opencv-telea``, ``opencv-ns``: OpenCV's Telea and Navier-Stokes hole filling of
  the forward warp (a classical reference; needs OpenCV).

Scores on two regions of the right view: ``all`` (pixels the left view can explain:
between the first and last pixel the forward warp reaches in each row) and
``disoccluded`` (those the forward warp does not reach: hidden in the left view).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from photo3d.config import Config, PreprocessConfig
from photo3d.eval.metrics import psnr, ssim
from photo3d.eval.stereo_pair import StereoPair
from photo3d.eval.warp import forward_warp

METHODS = ("forward-warp", "stretch", "diffusion", "structured", "learned", "opencv-telea",
           "opencv-ns")


@dataclass
class Evaluation:
    """Rendered right views and their scores.

    Attributes:
        images: method -> ``(H, W, 3) float32`` rendered right view.
        scores: method -> region -> metric -> value.
        regions: region name -> ``(H, W) bool`` mask.
        notes: method -> remark (e.g. "random weights").
    """

    images: dict[str, np.ndarray] = field(default_factory=dict)
    scores: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    regions: dict[str, np.ndarray] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)


def photo3d_of_pair(pair: StereoPair, config: Config, inpainter=None):
    """The 3D photo of ``pair``'s left view with its ground-truth metric depth and camera
    (``config`` plus ``depth_kind="depth", metric=True``).

    Example:
        >>> from photo3d.eval.synthetic import synthetic_pair
        >>> photo = photo3d_of_pair(synthetic_pair(0, width=64, height=48), Config(size=None))
        >>> photo.ldi.intrinsics.width, photo.stats["passes"] >= 1
        (64, True)
    """
    import photo3d

    z = pair.depth()
    return photo3d.make(pair.left, depth=np.where(np.isfinite(z), z, np.nan),
                        intrinsics=pair.left_camera,
                        config=config.with_(depth_kind="depth", metric=True),
                        inpainter=inpainter)


def _photo3d_view(pair: StereoPair, config: Config, inpainter=None) -> np.ndarray:
    from photo3d.render.renderer import RenderSettings

    photo = photo3d_of_pair(pair, config, inpainter)
    return photo.render(pair.right_camera, settings=RenderSettings(ssaa=2)).color


def random_nets(seed: int = 0, architecture: dict | None = None):
    """The three nets with random weights (timing, or a learned run without weights,
    reported as such): at the authors' size, or as ``architecture`` gives them (per
    net, :func:`~photo3d.nets.build_net` keywords, e.g. the compact nets'
    ``training.json`` ``"architecture"``)."""
    import torch

    from photo3d.nets import InpaintingNets, build_net

    torch.manual_seed(seed)
    arch = architecture or {}
    nets = {k: build_net(k, **arch.get(k, {})).eval() for k in ("edge", "depth", "color")}
    return InpaintingNets(**nets, device=torch.device("cpu"),
                          sources={k: "random" for k in nets})


def render_method(name: str, pair: StereoPair, *, config: Config | None = None,
                  weights=None) -> tuple[np.ndarray, str]:
    """The right view rendered by method ``name``, and a note."""
    config = config or Config()
    if name == "forward-warp":
        return forward_warp(pair.left, pair.disparity).color, ""
    if name == "stretch":
        flat = replace(config, preprocess=PreprocessConfig(discontinuity=2.0))  # never cut
        return _photo3d_view(pair, flat), "no cuts, no inpainting"
    if name in ("diffusion", "structured"):
        return _photo3d_view(pair, config.with_(inpainter=name)), ""
    if name == "learned":
        from photo3d.inpaint import get_inpainter
        from photo3d.inpaint.learned import LearnedInpainter, bundled_weights

        if weights is None and bundled_weights().is_dir():
            backend = LearnedInpainter(weights=bundled_weights())
            note = "compact weights shipped with photo3d"
        elif weights is None or str(weights) == "random":
            backend, note = LearnedInpainter(nets=random_nets(seed=0)), "random weights"
        else:
            backend, note = get_inpainter("learned", weights=weights), f"weights {weights}"
        return _photo3d_view(pair, config.with_(inpainter="learned"), backend), note
    if name in ("opencv-telea", "opencv-ns"):
        import cv2

        warp = forward_warp(pair.left, pair.disparity)
        holes = (~warp.reached).astype(np.uint8)
        img8 = np.round(warp.color * 255).astype(np.uint8)
        flag = cv2.INPAINT_TELEA if name == "opencv-telea" else cv2.INPAINT_NS
        return cv2.inpaint(img8, holes, 5, flag).astype(np.float32) / 255.0, "radius 5"
    raise ValueError(f"unknown method {name!r}; methods: {', '.join(METHODS)}")


def evaluate(pair: StereoPair, methods: Sequence[str] = METHODS, *,
             config: Config | None = None, weights=None, lpips: bool = True,
             progress: Callable[[str], None] | None = None) -> Evaluation:
    """Render every method at the right camera and score it against the real right view.

    Methods whose optional dependency is missing (OpenCV, torch) are skipped with a
    note instead of failing the whole evaluation.
    """
    warp = forward_warp(pair.left, pair.disparity)
    result = Evaluation(regions={"all": warp.frame, "disoccluded": warp.disoccluded})
    metric_fns: dict[str, Callable] = {"psnr": psnr, "ssim": ssim}
    if lpips:
        from photo3d.eval.lpips import lpips as lpips_fn

        metric_fns["lpips"] = lpips_fn
    for name in methods:
        if progress:
            progress(name)
        try:
            image, note = render_method(name, pair, config=config, weights=weights)
        except ImportError as err:
            result.notes[name] = f"skipped: {err}"
            continue
        result.images[name] = image
        result.notes[name] = note
        result.scores[name] = {
            region: {m: fn(image, pair.right, mask) for m, fn in metric_fns.items()}
            for region, mask in result.regions.items()
        }
    return result


def grid(pair: StereoPair, result: Evaluation, *, tiles: int = 3, size: int = 96) -> np.ndarray:
    """Image grid of the crops where the methods differ most (rows: crops; columns:
    the real right view, then each method), ``(H, W, 3) uint8``."""
    from PIL import Image, ImageDraw

    names = list(result.images)
    stack = np.stack([result.images[n] for n in names])
    spread = stack.std(axis=0).mean(axis=2) * result.regions["all"]
    h, w = spread.shape
    step = size // 2
    candidates = []
    for y in range(0, max(1, h - size + 1), step):
        for x in range(0, max(1, w - size + 1), step):
            candidates.append((float(spread[y:y + size, x:x + size].mean()), y, x))
    chosen: list[tuple[int, int]] = []
    for _, y, x in sorted(candidates, reverse=True):
        if all(abs(y - cy) >= size or abs(x - cx) >= size for cy, cx in chosen):
            chosen.append((y, x))
        if len(chosen) == tiles:
            break
    label_h = 14
    cols = ["right (real)"] + names
    canvas = Image.new("RGB", (len(cols) * size, label_h + len(chosen) * size), "white")
    draw = ImageDraw.Draw(canvas)
    for j, name in enumerate(cols):
        draw.text((j * size + 2, 1), name[:15], fill="black")
        for i, (y, x) in enumerate(chosen):
            img = pair.right if j == 0 else result.images[name]
            crop = np.round(np.clip(img[y:y + size, x:x + size], 0, 1) * 255).astype(np.uint8)
            canvas.paste(Image.fromarray(crop), (j * size, label_h + i * size))
    return np.asarray(canvas)


def table(result: Evaluation) -> str:
    """Markdown table: one row per method, PSNR/SSIM/LPIPS on both regions."""
    metrics = ["psnr", "ssim", "lpips"]
    head = "| method | " + " | ".join(f"{m.upper()} {r}" for r in ("all", "disoccluded")
                                       for m in metrics) + " | note |"
    lines = [head, "|" + " --- |" * (2 + 2 * len(metrics))]
    for name, regions in result.scores.items():
        cells = []
        for region in ("all", "disoccluded"):
            for m in metrics:
                v = regions[region].get(m)
                cells.append("" if v is None else f"{v:.2f}" if m == "psnr" else f"{v:.3f}")
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {result.notes.get(name, '')} |")
    for name, note in result.notes.items():
        if name not in result.scores:
            lines.append(f"| {name} | " + " | ".join([""] * 2 * len(metrics)) + f" | {note} |")
    return "\n".join(lines)
