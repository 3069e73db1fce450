"""Soft silhouettes (issue 44, item 3): novel views near depth steps, with and without.

A layered scene with an exact answer: a far wall (z = 6) textured with a real photo
(scikit-image's, as :mod:`photo3d.eval.synthetic`), in front of it a textured box, a
ring, poles 3, 6 and 10 px wide, a 2 px wire and a fence (z = 1.8 to 3.2). Every view
is ray-cast here with 4x4 samples per pixel (so the input photo has exactly mixed
pixels along every outline), independently of photo3d's renderer. ``make`` gets the
input view and, as metric depth (``depth_kind="depth", metric=True``, so the scene's
cameras apply to the LDI unchanged), either the exact depth (nearest surface at each
pixel centre) or that depth spread ``--spread`` px onto the far side (a 5x5 minimum
filter: what depth networks and stereo matchers give). The views of cameras moved by
10 to 30 cm (like the four paths) are scored against the exact views: PSNR and LPIPS
within 4 px of the exact view's depth steps, the share of those pixels off by more
than 0.25 (max over channels), and the whole view.

Variants: ``exact`` (``Config(edges="exact")``: today's hard cut) and ``soft`` (the
default, soft silhouettes), plus the matting method and band given by ``--variants``.
Writes ``benchmarks/results/alpha.json``.

``--accuracy``: the alpha estimates themselves, against the exact coverage of the
input view's fringe pixels (the share of a pixel's 4x4 samples on a surface at least
as near as the pixel's LDI disparity less half the threshold), for each method, band
and radius; writes ``benchmarks/results/alpha_accuracy.json``.

``--stereo``: the stereo pairs of ``photo3d eval`` (the Middlebury motorcycle with its
ground truth, synthetic pairs 0-2), the right view with ``edges="exact"`` and with
the default, PSNR and LPIPS over the whole view and the disoccluded pixels (the
issue's "within 1 % of today"); writes ``benchmarks/results/alpha_stereo.json``.

Usage: python benchmarks/bench_alpha.py [--scenes 3] [--size 384x256] [--accuracy]
                                        [--stereo]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402

from photo3d.camera import Camera, Intrinsics  # noqa: E402
from photo3d.config import Config  # noqa: E402

CAMERAS = ((0.15, 0.0, 0.0), (-0.2, 0.05, 0.0), (0.0, 0.1, 0.25), (0.25, -0.1, -0.1),
           (-0.1, -0.12, 0.15), (0.3, 0.0, 0.1))
"""Camera centres (scene units: the wall is 6 away, the objects 1.8 to 3.2)."""


def _textures() -> list[np.ndarray]:
    from skimage import data

    return [np.asarray(i, np.float32) / 255.0
            for i in (data.astronaut(), data.coffee(), data.chelsea(), data.rocket())]


def scene(seed: int, k: Intrinsics) -> list[tuple]:
    """Layers ``(z, inside(u, v) -> bool, texture, (u0, v0, u1, v1))``, shapes given in
    input-view pixel coordinates at their own depth, nearest last."""
    rng = np.random.default_rng(seed)
    tex = _textures()
    w, h = k.width, k.height
    order = rng.permutation(len(tex))
    wall = (6.0, lambda u, v: np.ones(u.shape, bool), tex[order[0]], (-0.3 * w, -0.3 * h,
                                                                       1.3 * w, 1.3 * h))
    bx, by = rng.uniform(0.1, 0.5) * w, rng.uniform(0.15, 0.45) * h
    box = (3.2, lambda u, v: (u > bx) & (u < bx + 0.3 * w) & (v > by) & (v < by + 0.4 * h),
           tex[order[1]], (bx, by, bx + 0.3 * w, by + 0.4 * h))
    rx, ry, r0, r1 = rng.uniform(0.6, 0.8) * w, rng.uniform(0.3, 0.6) * h, 0.08 * h, 0.16 * h
    ring = (2.8, lambda u, v: ((u - rx) ** 2 + (v - ry) ** 2 > r0 ** 2)
            & ((u - rx) ** 2 + (v - ry) ** 2 < r1 ** 2), tex[order[2]],
            (rx - r1, ry - r1, rx + r1, ry + r1))
    xs = np.sort(rng.uniform(0.05, 0.95, 3)) * w + rng.uniform(0, 1, 3)
    widths = (3.0, 6.0, 10.0)

    def poles(u, v):
        return np.logical_or.reduce([np.abs(u - x) < wd / 2 for x, wd in zip(xs, widths,
                                                                              strict=True)])

    pole = (2.2, poles, tex[order[3]], (0, 0, w, h))
    wy = rng.uniform(0.2, 0.8) * h + 0.37
    wire = (1.8, lambda u, v: np.abs(v - wy - 0.05 * (u - w / 2)) < 1.0,
            np.full((2, 2, 3), (0.9, 0.85, 0.2), np.float32), (0, 0, w, h))
    fy0 = rng.uniform(0.7, 0.8) * h
    fence = (2.5, lambda u, v: (v > fy0) & (v < fy0 + 0.15 * h)
             & ((np.mod(u, 14.0) < 4.0) | (np.abs(v - fy0 - 0.05 * h) < 2.0)),
             np.full((2, 2, 3), (0.95, 0.95, 0.95), np.float32), (0, 0, w, h))
    return [wall, box, ring, pole, fence, wire]


def cast(layers, k: Intrinsics, centre, *, samples: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """``(image (H, W, 3), depth (H, W))`` from a camera at ``centre`` (no rotation),
    ``samples x samples`` rays per pixel; depth at pixel centres."""
    from photo3d.eval.synthetic import _bilinear

    cx, cy, cz = centre
    yy, xx = np.mgrid[0:k.height, 0:k.width].astype(np.float64)
    image = np.zeros((k.height, k.width, 3))
    depth = np.full((k.height, k.width), np.inf)
    offsets = [(o + 0.5) / samples for o in range(samples)]
    for oy in offsets + [None]:
        for ox in offsets if oy is not None else [0.5]:
            sy = yy + (0.5 if oy is None else oy)
            sx = xx + ox
            rx, ry = (sx - k.cx) / k.fx, (sy - k.cy) / k.fy
            z_best = np.full(rx.shape, np.inf)
            col = np.zeros(rx.shape + (3,))
            for z, inside, tex, (u0, v0, u1, v1) in layers:
                t = z - cz  # ray (rx, ry, 1) from the centre meets the plane at t
                if t <= 0:
                    continue
                wx, wy = cx + rx * t, cy + ry * t
                u, v = k.fx * wx / z + k.cx, k.fy * wy / z + k.cy  # input-view pixels
                hit = inside(u, v) & (z < z_best)
                if hit.any():
                    col[hit] = _bilinear(tex, (u[hit] - u0) / (u1 - u0),
                                         (v[hit] - v0) / (v1 - v0))
                    z_best[hit] = z
            if oy is None:
                depth = z_best
            else:
                image += col
    return (image / samples**2).astype(np.float32), depth.astype(np.float32)


def samples(layers, k: Intrinsics, *, samples: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """The input view ``(image (H, W, 3), depth of every sample (S, H, W))``."""
    from photo3d.eval.synthetic import _bilinear

    yy, xx = np.mgrid[0:k.height, 0:k.width].astype(np.float64)
    image = np.zeros((k.height, k.width, 3))
    depths = []
    for oy in ((o + 0.5) / samples for o in range(samples)):
        for ox in ((o + 0.5) / samples for o in range(samples)):
            u, v = xx + ox, yy + oy
            z_best = np.full(u.shape, np.inf)
            col = np.zeros(u.shape + (3,))
            for z, inside, tex, (u0, v0, u1, v1) in layers:
                hit = inside(u, v) & (z < z_best)
                col[hit] = _bilinear(tex, (u[hit] - u0) / (u1 - u0), (v[hit] - v0) / (v1 - v0))
                z_best[hit] = z
            depths.append(z_best)
            image += col
    return (image / samples**2).astype(np.float32), np.array(depths)


def accuracy(seed: int, k: Intrinsics, spread: int, settings: list[tuple]) -> list[dict]:
    """Alpha error on the fringe of scene ``seed`` for each ``(method, band, radius)``."""
    from photo3d.depth.normalize import prepare_depth
    from photo3d.stages.preprocess import preprocess
    from photo3d.stages.silhouettes import _FAR, _near_distance, soft_silhouettes

    image, depths = samples(scene(seed, k), k)
    z = np.median(depths, axis=0)
    if spread:
        z = ndimage.minimum_filter(z, 2 * spread + 1)
    config = Config(size=None, depth_kind="depth", metric=True, spatial_scale=1.0)
    pre = preprocess(image, prepare_depth(z.astype(np.float32), image.shape[:2],
                                          kind="depth").disparity, config=config)
    lo, hi = pre.disparity_range
    threshold = config.preprocess.discontinuity
    truth = ((1.0 / depths - lo) / (hi - lo) >= pre.disparity[None] - threshold / 2).mean(0)
    rows = []
    for method, band, radius in settings:
        dist = _near_distance(pre.disparity, pre.edges.cuts, np.int32(band + 2 * radius),
                              np.float32(threshold))
        fringe = (dist < band) & (dist < _FAR)
        sil = soft_silhouettes(pre.image, pre.disparity, pre.edges.cuts, band=band,
                               radius=radius, threshold=threshold, method=method)
        err = np.abs(sil.alpha - truth)[fringe]
        hard = np.abs(1.0 - truth)[fringe]
        rows.append({"scene": seed, "spread": spread, "method": method, "band": band,
                     "radius": radius, "pixels": int(fringe.sum()), "mean_error": float(err.mean()),
                     "share_off_0.25": float((err > 0.25).mean()),
                     "hard_cut_mean_error": float(hard.mean())})
    return rows


def near_steps(depth: np.ndarray, radius: int = 4) -> np.ndarray:
    """``(H, W) bool`` pixels within ``radius`` px of a depth step (> 10 %)."""
    z = depth
    step = np.zeros(z.shape, bool)
    for a, b in ((z[:, 1:], z[:, :-1]), (z[1:], z[:-1])):
        jump = np.abs(a - b) > 0.1 * np.minimum(a, b)
        if a.shape[1] != z.shape[1]:
            step[:, 1:] |= jump
            step[:, :-1] |= jump
        else:
            step[1:] |= jump
            step[:-1] |= jump
    return ndimage.binary_dilation(step, iterations=radius)


def score(got: np.ndarray, want: np.ndarray, band: np.ndarray) -> dict:
    from photo3d.eval.lpips import lpips_map
    from photo3d.eval.metrics import psnr

    dmap = lpips_map(got, want)
    gross = np.abs(got - want).max(axis=2) > 0.25
    return {"psnr_edges": psnr(got, want, band), "lpips_edges": float(dmap[band].mean()),
            "gross_edges": float(gross[band].mean()), "psnr": psnr(got, want),
            "lpips": float(dmap.mean())}


VARIANTS = {
    "exact": lambda c: c.with_(edges="exact"),
    "soft": lambda c: c,
    "soft-means": lambda c: c.with_(silhouettes=replace(c.silhouettes, method="means")),
    "soft-band2": lambda c: c.with_(silhouettes=replace(c.silhouettes, band=2)),
    "soft-band4": lambda c: c.with_(silhouettes=replace(c.silhouettes, band=4, radius=5)),
}


def main() -> None:
    import photo3d
    from photo3d.render.renderer import RenderSettings

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=int, default=3)
    ap.add_argument("--size", default="384x256")
    ap.add_argument("--variants", default="exact,soft")
    ap.add_argument("--spread", type=int, default=2)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "alpha.json"))
    ap.add_argument("--accuracy", action="store_true")
    ap.add_argument("--stereo", action="store_true")
    args = ap.parse_args()
    if args.stereo:
        from photo3d.eval.evaluate import evaluate
        from photo3d.eval.stereo_pair import motorcycle_pair
        from photo3d.eval.synthetic import synthetic_pair

        pairs = {"motorcycle": motorcycle_pair, **{f"synthetic{i}": (
            lambda i=i: synthetic_pair(i)) for i in range(3)}}
        rows = []
        for name, make_pair in pairs.items():
            pair = make_pair()
            for edges in ("exact", "align"):
                scores = evaluate(pair, ["structured"], config=Config(edges=edges)).scores
                row = {"pair": name, "edges": edges, **{
                    f"{m}_{region}": float(v) for region, ms in scores["structured"].items()
                    for m, v in ms.items()}}
                rows.append(row)
                print(row, flush=True)
        save_record({"rows": rows}, Path(args.out).with_name("alpha_stereo.json"),
                    "alpha_stereo", "bench_alpha.py")
        return
    w, h = (int(v) for v in args.size.split("x"))
    k = Intrinsics.default(w, h)
    if args.accuracy:
        settings = [("pairs", 3, 4), ("means", 3, 4), ("pairs", 2, 3), ("pairs", 4, 5)]
        rows = [r for seed in range(args.scenes) for spread in (0, args.spread)
                for r in accuracy(seed, k, spread, settings)]
        summary = {}
        for spread in (0, args.spread):
            for method, band, radius in settings:
                sel = [r for r in rows if r["spread"] == spread and r["method"] == method
                       and r["band"] == band]
                key = f"spread{spread}/{method}/band{band}/radius{radius}"
                summary[key] = {m: float(np.mean([r[m] for r in sel])) for m in (
                    "mean_error", "share_off_0.25", "hard_cut_mean_error")}
                print(key, {m: round(v, 3) for m, v in summary[key].items()})
        out = Path(args.out).with_name("alpha_accuracy.json")
        save_record({"rows": rows, "mean_over_scenes": summary}, out, "alpha_accuracy",
                    "bench_alpha.py")
        return
    # the paper's spatial sizes are for 1024 px: keep them in pixels at this small size
    base = Config(size=None, depth_kind="depth", metric=True, spatial_scale=1.0)
    settings = RenderSettings(ssaa=2, backend="numba")
    rows = []
    for seed in range(args.scenes):
        layers = scene(seed, k)
        image, depth = cast(layers, k, (0.0, 0.0, 0.0))
        truth = [(c, *cast(layers, k, c)) for c in CAMERAS]
        depths = {"exact": depth,
                  f"spread{args.spread}": ndimage.minimum_filter(depth, 2 * args.spread + 1)}
        for dname, dmap in depths.items():
            for vname in args.variants.split(","):
                config = VARIANTS[vname](base)
                t = time.perf_counter()
                photo = photo3d.make(image, depth=dmap, config=config)
                took = time.perf_counter() - t
                scores = []
                for c, want, zt in truth:
                    pose = np.eye(4)
                    pose[:3, 3] = -np.asarray(c)
                    got = photo.render(Camera(k, pose), settings=settings).color
                    scores.append(score(got, want, near_steps(zt)))
                mean = {key: float(np.mean([s[key] for s in scores])) for key in scores[0]}
                rows.append({"scene": seed, "depth": dname, "variant": vname,
                             "make_s": round(took, 2),
                             "fringe": int(np.count_nonzero(photo.ldi.alpha < 1)), **mean})
                print(f"scene {seed} {dname:8} {vname:11} LPIPS edges {mean['lpips_edges']:.4f}"
                      f"  PSNR edges {mean['psnr_edges']:.2f}  gross {mean['gross_edges']:.4f}"
                      f"  LPIPS {mean['lpips']:.4f}  fringe {rows[-1]['fringe']}", flush=True)
    summary = {}
    for dname in {r["depth"] for r in rows}:
        for vname in args.variants.split(","):
            sel = [r for r in rows if r["depth"] == dname and r["variant"] == vname]
            summary[f"{dname}/{vname}"] = {key: float(np.median([r[key] for r in sel]))
                                           for key in ("lpips_edges", "psnr_edges",
                                                       "gross_edges", "lpips", "psnr")}
    save_record({"size": [w, h], "cameras": [list(c) for c in CAMERAS], "rows": rows,
                 "median_over_scenes": summary}, args.out, "alpha", "bench_alpha.py")


if __name__ == "__main__":
    main()
