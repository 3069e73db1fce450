"""Where a video frame's time goes: per-stage timings of the CPU renderer.

Makes the 1024 px motorcycle 3D photo, then renders and encodes ``--frames`` frames
of the ``circle`` path at 1280x720 with 2x supersampling and the authors' crop,
timing each stage by wrapping the functions that run it: vertex projection, block
bounds, rasterization (with the supersampling resolve fused in), hole filling,
8-bit conversion, RGB->YUV conversion and H.264 encoding (the rest of
``VideoWriter.write``). Stages run one after the other, so they add up to the total.

Usage: python benchmarks/bench_render_stages.py [--frames 96]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import STEP_TIMERS, run_child, save_record  # noqa: E402

CHILD = STEP_TIMERS + r"""
import json, sys, tempfile, time
from pathlib import Path
import numpy as np
import photo3d
from photo3d.sample import motorcycle
from photo3d.io import video
from photo3d.render import animate, raster, renderer
from photo3d.render.animate import VideoSpec, render_video
from photo3d.render.renderer import AUTHORS_CROP, Renderer, RenderSettings
frames = int(sys.argv[1])
s = motorcycle()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity))
r = Renderer(photo.mesh(), RenderSettings(ssaa=2, crop=AUTHORS_CROP, backend="numba"))
spent, timed = step_timers(time.perf_counter)

timed(raster, "project_vertices", "vertex projection")
timed(raster, "block_bounds", "block bounds")
timed(raster, "raster_frame", "rasterization + resolve")
timed(renderer, "grow_fill", "hole filling")
timed(renderer, "grow_fill_far", "hole filling")
timed(animate, "to_rgb8", "8-bit conversion")
timed(video, "rgb_to_yuv420", "RGB->YUV 4:2:0")
timed(video.VideoWriter, "write", "encoder (write)")
spec = VideoSpec(path="circle", size=(1280, 720), frames=frames, fps=40)
with tempfile.TemporaryDirectory() as tmp:
    render_video(r, photo.ldi, VideoSpec(path="circle", size=(1280, 720), frames=2),
                 Path(tmp) / "warm.mp4")
    spent.clear()
    t = time.perf_counter()
    render_video(r, photo.ldi, spec, Path(tmp) / "circle.mp4")
    total = time.perf_counter() - t
ms = {k: 1000 * v / frames for k, v in spent.items()}
ms["H.264 encoding"] = ms.pop("encoder (write)") - ms["RGB->YUV 4:2:0"]
ms["other (Python, cameras, file)"] = 1000 * total / frames - sum(ms.values())
print(json.dumps({"frames": frames, "total_ms": 1000 * total / frames, "stages_ms": ms,
                  "faces": int(photo.mesh().faces.shape[0])}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=96)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "render_stages.json")
    args = parser.parse_args()
    rec = run_child(CHILD, args.frames)
    save_record(rec, args.out, "render_stages", "bench_render_stages.py")
    print(f"circle path, {args.frames} frames, 1280x720, ssaa 2, {rec['faces']:,} triangles: "
          f"{rec['total_ms']:.1f} ms per frame")
    for stage, value in sorted(rec["stages_ms"].items(), key=lambda kv: -kv[1]):
        print(f"  {stage:32s} {value:6.1f} ms")


if __name__ == "__main__":
    main()
