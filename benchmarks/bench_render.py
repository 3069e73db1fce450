"""Benchmark video rendering: the four standard camera paths of the motorcycle photo.

Each run is a fresh process: it makes the 1024 px 3D photo of the bundled sample
(not timed), then renders ``dolly-zoom-in``, ``zoom-in``, ``circle`` and ``swing``,
240 frames each at 1280x720 with 2x supersampling, encoded as H.264 MP4 (timed:
rendering + encoding of all four). Peak memory is the child's peak RSS.

Usage: python benchmarks/bench_render.py [--runs 3] [--frames 240] [--size 1280x720]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info, run_child  # noqa: E402

CHILD = r"""
import json, sys, tempfile, time
from pathlib import Path
import numpy as np
import photo3d
from photo3d.sample import motorcycle
from photo3d.output import write_videos
from photo3d.render.animate import VideoSpec
from photo3d.render.paths import STANDARD_PATHS
from photo3d.render.renderer import AUTHORS_CROP, RenderSettings
frames, width, height, ssaa, backend = (int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]),
                                        int(sys.argv[4]), sys.argv[5])
s = motorcycle()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity))
mesh = photo.mesh()
specs = [VideoSpec(path=p, size=(width, height), frames=frames, fps=40) for p in STANDARD_PATHS]
settings = RenderSettings(ssaa=ssaa, crop=AUTHORS_CROP, backend=backend)
with tempfile.TemporaryDirectory() as tmp:
    t = time.perf_counter()
    paths = write_videos(photo, mesh, Path(tmp), specs, settings=settings)
    wall = time.perf_counter() - t
    sizes = {p.name: p.stat().st_size for p in paths}
print(json.dumps({"render_s": wall, "faces": int(mesh.faces.shape[0]), "sizes": sizes}))
"""


def run_once(args) -> dict:
    w, h = args.size
    return run_child(CHILD, args.frames, w, h, args.ssaa, args.backend)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--frames", type=int, default=240)
    parser.add_argument("--size", type=lambda t: tuple(int(v) for v in t.split("x")),
                        default=(1280, 720))
    parser.add_argument("--ssaa", type=int, default=2)
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "render.json")
    args = parser.parse_args()
    runs = [run_once(args) for _ in range(args.runs)]
    med = statistics.median(r["render_s"] for r in runs)
    record = {"benchmark": "render", "frames": args.frames, "size": list(args.size),
              "ssaa": args.ssaa, "backend": args.backend, "runs": runs,
              "median_render_s": med, "peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
              "machine": machine_info(),
              "command": " ".join(["python", "benchmarks/bench_render.py", *sys.argv[1:]])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))
    n = 4 * args.frames
    print(f"4 videos x {args.frames} frames, {args.size[0]}x{args.size[1]}, ssaa {args.ssaa}, "
          f"backend {args.backend}, {runs[0]['faces']:,} triangles; {args.runs} runs, "
          f"{record['machine']['cpu']}, {record['machine']['cores']} cores")
    times = ", ".join(f"{r['render_s']:.1f}" for r in runs)
    print(f"render + encode, all four: {med:.1f} s median ({1000 * med / n:.1f} ms per frame); "
          f"runs: {times}")
    print(f"peak memory (whole process, incl. making the photo): {record['peak_rss_mb']:.0f} MB")
    sizes = runs[0]["sizes"]
    print("files: " + ", ".join(f"{k} {v / 1e6:.1f} MB" for k, v in sorted(sizes.items())))


if __name__ == "__main__":
    main()
