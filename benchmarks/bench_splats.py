"""Benchmark the splat exports of the bundled sample (issue 46): how many splats, how
large each file, and how Spark shows them.

The 3D photo is ``photo3d demo --no-video`` (the Middlebury motorcycle at 1024 px),
read from ``--demo`` (made there if missing). For each layout (``dense``: one splat
per LDI pixel; ``adaptive``: the default) it records the splat count, the sizes of
``splats.ply``, ``splats.glb`` and ``splats.spz`` in SPZ versions 3 and 4, and the
time to build the splats (median of ``--runs``), each layout as built and with its
colours fitted (the default, :mod:`photo3d.export.splat_fit`; its time is the
build's with the fit); then renders ``splats.ply`` in Spark
2.2 (headless Chromium, SwiftShader, Spark's defaults: tests/export/spark_renderer.py)
from the input camera and from the circle path's widest camera and compares each
view with photo3d's own render of the 3D photo (the full mesh, numba, no hole
filling): PSNR over the pixels photo3d's render covers, and the share of those that
Spark leaves empty (alpha under 0.5). Issue 46's targets: at most 500,000 splats and
a 4 MB ``splats.spz``; from the input camera at least 30 dB, from the widest at
least 28 dB with at most 0.5 % empty. It also checks the model of Spark the fit
uses (:func:`photo3d.export.spark_model.spark_weights`) against Spark's own image:
``model_db``, PSNR over all pixels.

Needs Chromium, playwright and ``PHOTO3D_NODE_MODULES`` (``make test`` installs the
npm packages into ``.node/``), and backports-zstd (``photo3d[spz4]``) for version 4.
Writes ``benchmarks/results/splats.json``.

Usage: PHOTO3D_NODE_MODULES=.node python benchmarks/bench_splats.py [--demo DIR] [--runs 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(ROOT / "tests" / "export"))
from _machine import save_record  # noqa: E402
from spark_renderer import chromium, missing, render_views, widest_circle_camera  # noqa: E402

from photo3d.camera import Camera  # noqa: E402
from photo3d.export.spark_model import spark_quantized, spark_weights  # noqa: E402
from photo3d.export.splats import DENSITIES, build_splats, write_glb, write_ply, write_spz  # noqa: E402
from photo3d.io.npz import load_npz  # noqa: E402
from photo3d.photo import Photo3D  # noqa: E402
from photo3d.render.renderer import Renderer, RenderSettings  # noqa: E402

TARGETS = {"splats": 500_000, "spz_mb": 4.0, "input_db": 30.0, "widest_db": 28.0,
           "widest_empty": 0.005}


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((a - b) ** 2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--demo", type=Path, default=ROOT / "out" / "demo")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/splats.json")
    args = parser.parse_args()
    if missing():
        sys.exit(missing())
    if not (args.demo / "photo3d.npz").is_file():
        subprocess.run([sys.executable, "-m", "photo3d", "demo", "--no-video", "-q", "-o",
                        str(args.demo)], check=True)
    ldi, _ = load_npz(args.demo / "photo3d.npz")
    k = ldi.intrinsics
    cameras = [Camera(k, np.eye(4)), widest_circle_camera(k)]
    from photo3d.config import Config

    with Renderer(Photo3D(ldi, Config()).mesh(), RenderSettings(fill_holes=False,
                                                                backend="numba")) as r:
        want = [(v.color, v.mask) for v in (r.render(c) for c in cameras)]
    results = {}
    with tempfile.TemporaryDirectory() as tmp, chromium() as browser:
        tmp = Path(tmp)
        for density, fit in [(d, f) for d in DENSITIES for f in (False, True)]:
            times, load = [], os.getloadavg()[0]
            for _ in range(args.runs):
                start = time.perf_counter()
                splats = build_splats(ldi, density=density, fit=fit)
                times.append(time.perf_counter() - start)
            files = {}
            write_ply(ldi, tmp / "splats.ply", splats=splats)
            write_glb(ldi, tmp / "splats.glb", splats=splats)
            files["splats.ply"] = (tmp / "splats.ply").stat().st_size / 1e6
            files["splats.glb"] = (tmp / "splats.glb").stat().st_size / 1e6
            for version in (3, 4):
                write_spz(ldi, tmp / "splats.spz", splats=splats, spz_version=version)
                files[f"splats.spz v{version}"] = (tmp / "splats.spz").stat().st_size / 1e6
            got = render_views(tmp / "splats.ply", cameras, browser=browser)
            views = [psnr(rgba[..., :3][covered], color[covered])
                     for (color, covered), rgba in zip(want, got, strict=True)]
            empty = float(np.mean(got[1][..., 3][want[1][1]] < 0.5))
            model = [psnr((spark_weights(splats, c) @ spark_quantized(splats, c).colors)
                          .reshape(rgba[..., :3].shape), rgba[..., :3])
                     for c, rgba in zip(cameras, got, strict=True)]
            name = f"{density}, fitted" if fit else density
            results[name] = {
                "splats": len(splats), "build_s": statistics.median(times),
                "load_1min": round(load, 2),
                "files_mb": {name: round(mb, 3) for name, mb in files.items()},
                "input_db": round(views[0], 2), "widest_db": round(views[1], 2),
                "widest_empty": round(empty, 5),
                "model_db": [round(m, 2) for m in model]}
            print(name, results[name], flush=True)
    save_record({"demo": str(args.demo), "targets": TARGETS, "results": results},
                args.out, "splats", "bench_splats.py")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
