"""Where a frame of ``photo3d render`` goes, in CPU time of one thread, step by step.

Renders ``--frames`` frames of the ``circle`` path at 1280x720 from a saved 3D photo
(``--photo DIR``; default: the demo's, made first with ``photo3d demo --no-video``) the
way ``photo3d render`` does (the light mesh read back from ``mesh.glb``, the command
line's settings) and encodes them to MP4, in one thread: ``NUMBA_NUM_THREADS=1`` and
the frames encoded in the loop, not on a worker thread, so the steps add up. Each step
is timed in process CPU seconds by wrapping the function that runs it: vertex
projection, block bounds, rasterization (texture lookup, edge blend and, from issue
35's second round, the 8-bit colours included), hole filling, the 8-bit conversion
left (``to_rgb8``, or the holes' pixels only), RGB->YUV, and the rest of
``VideoWriter.write`` (x264, whose threads run beside; approximate per step, exact in
the total).

This tree's ``src/`` and ``--ref``'s (``git archive``, default ``main``) run
alternated ``--runs`` times, each in a fresh process with its own warmed numba cache;
medians per step. Writes ``benchmarks/results/video_steps.json``.

Usage: python benchmarks/bench_video_steps.py [--photo DIR] [--ref main] [--runs 3]
[--frames 120]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import STEP_TIMERS, git_src, save_record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

CHILD = STEP_TIMERS + r"""
import json, sys, tempfile, time
from pathlib import Path
import photo3d
from photo3d.output import SaveOptions, _video_mesh
from photo3d.render import animate, raster, renderer as rmod
from photo3d.render.renderer import Renderer, video_settings
from photo3d.io import video as vmod
folder, frames = Path(sys.argv[1]), int(sys.argv[2])
photo = photo3d.load(folder)
settings = video_settings()
mesh = _video_mesh(photo, None, None, SaveOptions(render_settings=settings), folder=folder)
r = Renderer(mesh, settings)
cams = animate.path_cameras(photo.ldi, animate.VideoSpec(path="circle", size=(1280, 720)))
cams = (cams * (frames // len(cams) + 1))[:frames]
spent, timed = step_timers(time.process_time)
timed(raster, "project_vertices", "vertex projection")
timed(raster, "block_bounds", "block bounds")
timed(raster, "raster_frame", "rasterization")
timed(rmod, "grow_fill_far", "hole filling")
timed(animate, "to_rgb8", "8-bit conversion")
timed(rmod, "holes_to_rgb8", "8-bit conversion")
timed(rmod, "to_rgb8", "8-bit conversion")
timed(vmod, "rgb_to_yuv420", "RGB->YUV 4:2:0")
timed(vmod.VideoWriter, "write", "write")
with tempfile.TemporaryDirectory() as tmp:
    for i, frame in enumerate(animate.render_frames(r, cams[:2])):
        pass  # warm-up
    spent.clear()
    t = time.process_time()
    with vmod.VideoWriter(Path(tmp) / "circle.mp4", fps=40, size=(1280, 720)) as writer:
        for frame in animate.render_frames(r, cams):
            writer.write(frame)
    total = time.process_time() - t
ms = {k: 1000 * v / frames for k, v in spent.items()}
ms["x264 (write, less RGB->YUV)"] = ms.pop("write") - ms["RGB->YUV 4:2:0"]
ms["other (Python, cameras, file)"] = 1000 * total / frames - sum(ms.values())
print(json.dumps({"total_ms": 1000 * total / frames, "steps_ms": ms}))
"""


def child(src: Path, cache: Path, photo: Path, frames: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(cache),
               NUMBA_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD, str(photo), str(frames)], env=env,
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photo", type=Path, help="a saved 3D photo (default: the demo's)")
    parser.add_argument("--ref", default="main")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "video_steps.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        srcs = {"now": tmp / "now" / "src", "ref": tmp / "ref" / "src"}
        shutil.copytree(ROOT / "src", srcs["now"], ignore=shutil.ignore_patterns("__pycache__"))
        git_src(args.ref, srcs["ref"].parent)
        photo = args.photo
        if photo is None:
            photo = tmp / "photo"
            subprocess.run([sys.executable, "-m", "photo3d", "demo", "-o", str(photo),
                            "--no-video", "-q"], env=dict(os.environ, PYTHONPATH=str(
                                srcs["now"])), check=True)
        caches = {kind: tmp / f"cache_{kind}" for kind in srcs}
        for kind in srcs:  # warm-up: compiles into each cache
            child(srcs[kind], caches[kind], photo, 2)
        runs: dict[str, list[dict]] = {"ref": [], "now": []}
        loads = []
        for _ in range(args.runs):
            for kind in ("ref", "now"):
                loads.append(os.getloadavg()[0])
                runs[kind].append(child(srcs[kind], caches[kind], photo, args.frames))
    medians = {}
    for kind, rs in runs.items():
        steps = {k: statistics.median(r["steps_ms"].get(k, 0.0) for r in rs)
                 for k in rs[0]["steps_ms"]}
        medians[kind] = {"total_ms": statistics.median(r["total_ms"] for r in rs),
                         "steps_ms": steps}
    record = {"runs": runs, "median": medians, "ref": args.ref, "frames": args.frames,
              "load_1min": loads}
    save_record(record, args.out, "video_steps", "bench_video_steps.py")
    print(f"1-minute load average before the runs: {min(loads):.1f}-{max(loads):.1f}")
    print(f"CPU ms a frame, one thread (median of {args.runs}):   ref ({args.ref})    now")
    for step in medians["now"]["steps_ms"]:
        print(f"  {step:32s} {medians['ref']['steps_ms'].get(step, 0.0):8.2f} "
              f"{medians['now']['steps_ms'][step]:8.2f}")
    print(f"  {'total':32s} {medians['ref']['total_ms']:8.2f} {medians['now']['total_ms']:8.2f}")


if __name__ == "__main__":
    main()
