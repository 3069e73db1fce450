"""Benchmark stereo depth on the Middlebury motorcycle pair: accuracy, speed, views.

1. **Disparity accuracy** of ``photo3d.depth.stereo.stereo_disparity`` against the
   ground truth: bad-2 (share of GT-known pixels whose |error| > 2 px; the
   Middlebury metric, all GT-known pixels counted, occluded and border ones too),
   also bad-1, mean absolute error, and bad-2 on the pixels that passed the
   left-right check.
2. **Speed**: fresh process per run, one warm-up, median of N (``--runs``), time
   around ``stereo_disparity`` only (OpenCV imported before); peak RSS of the
   children (the maximum over all of them).
3. **End-to-end views**: ``photo3d.make`` (default config) once with the stereo
   disparity and once with the GT disparity (both on the left image); both are
   rendered at the right camera and compared with the real right image by PSNR
   over the pixels both renders cover. photo3d's geometry is in normalised
   disparity units, not metric, so the right camera is found by a grid search on
   the GT photo: ``Camera.translated(K, (t, 0, 0))`` with the principal point
   moved by ``-s`` px (the pair's constant disparity offset), (t, s) maximising
   the GT render's PSNR; the same camera renders the stereo photo.

Prints a summary and writes ``benchmarks/results/stereo.json``.

Usage: python benchmarks/bench_stereo.py [--runs 5] [--no-views]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info  # noqa: E402

CHILD = r"""
import json, time
import cv2  # imported before timing: a one-time cost per process, not per pair
from photo3d.sample import motorcycle
from photo3d.depth.stereo import stereo_disparity
s = motorcycle()
t = time.perf_counter()
res = stereo_disparity(s.left, s.right)
print(json.dumps({"stereo_s": time.perf_counter() - t}))
"""


def run_once() -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                         check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return result


def accuracy(sample, res) -> dict:
    gt, known = sample.disparity, np.isfinite(sample.disparity)
    err = np.abs(res.disparity - gt)
    return {
        "bad2": float((err > 2)[known].mean()),
        "bad1": float((err > 1)[known].mean()),
        "mae_px": float(err[known].mean()),
        "valid_fraction": float(res.valid.mean()),
        "bad2_on_valid": float((err > 2)[known & res.valid].mean()),
        "gt_known_pixels": int(known.sum()),
        "max_disparity": res.max_disparity,
    }


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    mse = float(((a - b) ** 2)[mask].mean())
    return 10.0 * np.log10(1.0 / mse)


def views(sample, stereo_disp) -> dict:
    import photo3d
    from photo3d.camera import Camera
    from photo3d.render.renderer import Renderer, RenderSettings

    h, w = sample.left.shape[:2]
    photos = {name: photo3d.make(sample.left, depth=d)
              for name, d in (("gt", sample.disparity), ("stereo", stereo_disp))}
    base = photos["gt"].ldi.intrinsics.scaled(w, h)  # render at the pair's own size
    target = sample.right
    settings = RenderSettings(ssaa=2)

    def camera(t: float, s: float) -> Camera:
        k = dataclasses.replace(base, cx=base.cx - s)
        return Camera.translated(k, (t, 0.0, 0.0))

    with Renderer(photos["gt"].mesh(), settings) as r:
        def score(t, s):
            v = r.render(camera(t, s))
            return psnr(v.color, target, v.mask)

        best = max((score(t, s), t, s) for t in np.linspace(0.005, 0.04, 8)
                    for s in np.linspace(0, 16, 5))
        _, t0, s0 = best
        fine = max((score(t, s), t, s) for t in t0 + np.linspace(-0.0025, 0.0025, 5)
                    for s in s0 + np.linspace(-2, 2, 5))
        _, t_best, s_best = fine
        gt_view = r.render(camera(t_best, s_best))
    with Renderer(photos["stereo"].mesh(), settings) as r:
        stereo_view = r.render(camera(t_best, s_best))
    both = gt_view.mask & stereo_view.mask
    return {
        "camera_t": float(t_best), "principal_point_shift_px": float(s_best),
        "psnr_gt_depth_db": psnr(gt_view.color, target, both),
        "psnr_stereo_depth_db": psnr(stereo_view.color, target, both),
        "psnr_input_view_as_is_db": psnr(sample.left, target, both),
        "compared_pixels": int(both.sum()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--no-views", action="store_true", help="skip the end-to-end renders")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "stereo.json")
    args = parser.parse_args()

    from photo3d.depth.stereo import stereo_disparity
    from photo3d.sample import motorcycle

    sample = motorcycle()
    res = stereo_disparity(sample.left, sample.right)
    acc = accuracy(sample, res)
    run_once()  # warm-up
    runs = [run_once() for _ in range(args.runs)]
    speed = {"stereo_s": statistics.median(r["stereo_s"] for r in runs),
             "peak_rss_mb": max(r["peak_rss_mb"] for r in runs)}
    t = time.perf_counter()
    view = None if args.no_views else views(sample, res.disparity)
    record = {"benchmark": "stereo", "accuracy": acc, "median": speed, "runs": runs,
              "views": view, "views_s": time.perf_counter() - t, "machine": machine_info(),
              "command": " ".join(["python", "benchmarks/bench_stereo.py", *sys.argv[1:]])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))

    h, w = sample.left.shape[:2]
    print(f"motorcycle {w}x{h}, {args.runs} runs (median), {record['machine']['cpu']}, "
          f"{record['machine']['cores']} cores")
    print(f"stereo_disparity: {speed['stereo_s']:.2f} s, peak memory {speed['peak_rss_mb']:.0f} MB"
          f", search range {acc['max_disparity']} px")
    print(f"bad-2 {acc['bad2']:.1%} of {acc['gt_known_pixels']:,} GT-known pixels "
          f"(bad-1 {acc['bad1']:.1%}, MAE {acc['mae_px']:.2f} px); "
          f"{acc['valid_fraction']:.1%} pass the left-right check, bad-2 there "
          f"{acc['bad2_on_valid']:.1%}")
    if view:
        print(f"right view (t={view['camera_t']:.4f}, principal point -"
              f"{view['principal_point_shift_px']:.1f} px): PSNR with GT depth "
              f"{view['psnr_gt_depth_db']:.2f} dB, with stereo depth "
              f"{view['psnr_stereo_depth_db']:.2f} dB (left image as is "
              f"{view['psnr_input_view_as_is_db']:.2f} dB)")


if __name__ == "__main__":
    main()
