"""Where the gross errors near depth steps come from (issue 44): ``bench_edges.py``'s
scenes and cameras, ``make`` in this process.

Every pixel within 4 px of a depth step of a true view whose largest channel error is
above 0.25 (``bench_edges.py``'s ``gross``) is counted by where it is and by what the
rendered depth says:

- where: ``seen_fg`` (seen by the input view, the near side of a step: the true depth
  is the smallest within 4 px), ``seen_bg`` (seen, the far side), ``disocc``
  (disoccluded: hidden from the input view or outside it);
- cause, from the rendered depth (the nearest sample of each pixel) against the true
  one: ``colour`` (within 2 %: the geometry is right, the colour wrong: a fill colour
  or a halo painted on the right layer), ``nearer_layer`` / ``farther_layer`` (within
  2 % of another true depth within 4 px: the wrong layer, a fat or a thinned object),
  ``stretched`` (neither: an in-between depth, a triangle stretched across a step or
  a layer cut at a wrong depth), ``hole`` (the renderer's hole filling).

Prints the shares of the pixels near steps, pooled over the views and the scenes;
``--crops DIR`` saves the true view, the render and the gross pixels of views 0 and 6
as PNG and NPZ. ``--config`` takes nested ``Config.to_dict`` overrides as JSON (as
``bench_edges.py``'s variants).

Usage: python benchmarks/bench_edges_gross.py [--conditions exact,spread2,blurred]
           [--scenes 3] [--config '{"preprocess": {"ramp_passes": 0}}'] [--out JSON]
           [--crops DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import _edge_scenes as es  # noqa: E402
import bench_edges as be  # noqa: E402

SIDES = ("seen_fg", "seen_bg", "disocc")
CAUSES = ("colour", "nearer_layer", "farther_layer", "stretched", "hole")


def classify(view, truth_color, truth_depth, disoccluded, layer_depths):
    """``(gross (H, W) bool, side (H, W) str, cause (H, W) str)`` of one rendered
    ``view`` (a :class:`photo3d.render.renderer.View`) against the true view."""
    from scipy import ndimage

    steps = be._near_steps(be.depth_steps(truth_depth))
    gross = (np.abs(view.color - truth_color).max(axis=2) > 0.25) & steps
    lo = ndimage.minimum_filter(truth_depth, 9)
    hi = ndimage.maximum_filter(truth_depth, 9)
    rel = view.depth / truth_depth
    other = np.zeros(truth_depth.shape, bool)  # another true depth within 4 px
    for z in layer_depths:
        other |= (np.abs(view.depth / z - 1) < 0.02) & (lo <= z * 1.001) & (hi >= z * 0.999)
    cause = np.full(truth_depth.shape, "stretched", object)
    cause[(rel < 0.98) & other] = "nearer_layer"
    cause[(rel > 1.02) & other] = "farther_layer"
    cause[np.abs(rel - 1) < 0.02] = "colour"
    cause[~view.mask] = "hole"
    near_side = truth_depth <= lo * 1.01
    side = np.where(disoccluded, "disocc", np.where(near_side, "seen_fg", "seen_bg"))
    return gross, steps, side, cause


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--conditions", default="exact,spread2,blurred")
    parser.add_argument("--scenes", type=int, default=3)
    parser.add_argument("--config", default="{}", help="Config.to_dict overrides, JSON")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--crops", type=Path, default=None)
    args = parser.parse_args()

    import photo3d
    from photo3d.camera import Camera, Intrinsics
    from photo3d.config import Config
    from photo3d.render.renderer import RenderSettings

    overrides = json.loads(args.config)
    base = Config(size=None, depth_kind="depth", metric=True).to_dict()
    for key, value in overrides.items():
        base[key] = {**base[key], **value} if isinstance(value, dict) else value
    config = Config.from_dict(base)
    k = Intrinsics.default(es.WIDTH, es.HEIGHT)
    cam0 = Camera(k, np.eye(4))
    cams = be.cameras(k)
    counts: dict[str, dict[str, int]] = {}
    for seed in range(args.scenes):
        layers = es.scene(seed)
        image, z = es.cast(layers, cam0)
        truths = [es.cast(layers, c) for c in cams]
        for cond in args.conditions.split(","):
            photo = photo3d.make(image, depth=be.depth_condition(z, cond), config=config,
                                 intrinsics=k)
            c = counts.setdefault(cond, {"steps": 0, "gross": 0})
            for i, (cam, (tv, td)) in enumerate(zip(cams, truths, strict=True)):
                view = photo.render(cam, settings=RenderSettings(ssaa=2))
                depths = [layer.z + cam.pose[2, 3] for layer in layers]
                gross, steps, side, cause = classify(
                    view, tv, td, es.disoccluded(layers, cam, cam0), depths)
                c["steps"] += int(steps.sum())
                c["gross"] += int(gross.sum())
                for s in SIDES:
                    for why in CAUSES:
                        key = f"{s}/{why}"
                        c[key] = c.get(key, 0) + int((gross & (side == s) & (cause == why)).sum())
                if args.crops and i in (0, 6):
                    _save_crop(args.crops / f"s{seed}_{cond}_v{i}", tv, view, gross)
    for cond, c in counts.items():
        st, g = c["steps"], c["gross"]
        print(f"{cond}: gross {g / st:.2%} of {st} pixels near steps")
        for s in SIDES:
            print(f"  {s:8s} {sum(c[f'{s}/{w}'] for w in CAUSES) / st:6.2%}: " + ", ".join(
                f"{w} {c[f'{s}/{w}'] / st:.2%}" for w in CAUSES))
        print("  by cause: " + ", ".join(
            f"{w} {sum(c[f'{s}/{w}'] for s in SIDES) / st:.2%}" for w in CAUSES))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"config": overrides, "scenes": args.scenes,
                                        "counts": counts}, indent=1))


def _save_crop(stem: Path, truth: np.ndarray, view, gross: np.ndarray) -> None:
    """The true view, the render and the gross pixels (red) stacked, as PNG; the
    arrays as NPZ."""
    from PIL import Image

    stem.parent.mkdir(parents=True, exist_ok=True)
    marks = gross[..., None] * np.array([1.0, 0.0, 0.0], np.float32)
    stack = np.concatenate([truth, view.color, marks], axis=0)
    Image.fromarray((np.clip(stack, 0, 1) * 255).astype(np.uint8)).save(f"{stem}.png")
    np.savez_compressed(f"{stem}.npz", color=view.color, depth=view.depth, truth=truth,
                        gross=gross)


if __name__ == "__main__":
    main()
