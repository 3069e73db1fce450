"""H.264 presets on rendered frames: encoding time, file size and fidelity.

Renders every third frame of the motorcycle photo's ``circle`` path (80 frames,
1280x720, 2x supersampling, the authors' crop), converts them to YUV 4:2:0 once,
then encodes them with libx264 at CRF 18 and each preset (two passes each, the
second timed). Fidelity is the PSNR of the decoded RGB frames against the rendered
ones (it includes the 4:2:0 chroma loss, the same for every preset).

Usage: python benchmarks/bench_encode.py [--presets ultrafast,superfast,veryfast,faster]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import run_child, save_record  # noqa: E402

CHILD = r"""
import json, os, sys, tempfile, time
import av
import numpy as np
import photo3d
from photo3d.sample import motorcycle
from photo3d.io._yuv import rgb_to_yuv420
from photo3d.render.animate import VideoSpec, path_cameras, render_frames
from photo3d.render.renderer import AUTHORS_CROP, Renderer, RenderSettings
s = motorcycle()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity))
r = Renderer(photo.mesh(), RenderSettings(ssaa=2, crop=AUTHORS_CROP))
cams = path_cameras(photo.ldi, VideoSpec(path="circle", size=(1280, 720), frames=240))[::3]
frames = list(render_frames(r, cams))
planes = [rgb_to_yuv420(f) for f in frames]
out = {}
with tempfile.TemporaryDirectory() as tmp:
    for preset in sys.argv[1].split(","):
        path = os.path.join(tmp, preset + ".mp4")
        for _ in range(2):
            container = av.open(path, "w")
            stream = container.add_stream("libx264", rate=40)
            stream.width, stream.height, stream.pix_fmt = 1280, 720, "yuv420p"
            stream.options = {"crf": "18", "preset": preset}
            t = time.perf_counter()
            for i, p in enumerate(planes):
                frame = av.VideoFrame.from_ndarray(p, format="yuv420p")
                frame.pts = i
                for packet in stream.encode(frame):
                    container.mux(packet)
            for packet in stream.encode():
                container.mux(packet)
            container.close()
            seconds = time.perf_counter() - t
        with av.open(path) as video:
            decoded = [f.to_ndarray(format="rgb24") for f in video.decode(video=0)]
        mse = np.mean([np.mean((a.astype(np.float64) - b) ** 2)
                       for a, b in zip(decoded, frames, strict=True)])
        out[preset] = {"ms_per_frame": 1000 * seconds / len(planes),
                       "mb": os.path.getsize(path) / 1e6,
                       "psnr_db": float(10 * np.log10(255.0**2 / mse))}
print(json.dumps({"frames": len(planes), "presets": out}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="ultrafast,superfast,veryfast,faster")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "encode.json")
    args = parser.parse_args()
    rec = run_child(CHILD, args.presets)
    save_record(rec, args.out, "encode", "bench_encode.py")
    print(f"{rec['frames']} rendered frames, 1280x720, libx264 CRF 18")
    for preset, r in rec["presets"].items():
        print(f"  {preset:10s} {r['ms_per_frame']:5.1f} ms/frame  {r['mb']:5.2f} MB  "
              f"PSNR {r['psnr_db']:.2f} dB")


if __name__ == "__main__":
    main()
