"""Occlusion edges on the demo (issue 44): ``make`` time and before/after crops.

Runs ``photo3d.make`` on the bundled motorcycle sample (default config, 1024 px) with
``edges="exact"`` (before issue 44: the depth map's steps, hard cuts), ``edges="align"``
with hard cuts (``SilhouetteConfig.soft`` off: the steps on the photo's colour edges)
and the default (aligned and soft silhouettes), alternating, ``--repeat`` times each,
and renders swing frame 60 and circle frame 30 as the videos are drawn (the light mesh,
:func:`~photo3d.render.renderer.video_settings`). Writes 2x crops (nearest) around the
handlebar and mirror (swing 60) and the front fork (circle 30) to
``docs/img/edges_*.png`` (the three one above the other, in that order) and
``benchmarks/results/edges_demo.json`` (make times, fringe size).

Usage: python benchmarks/demo_edge_crops.py [--repeat 2] [--full]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CROPS = {  # (path, frame, name): (top, left, height, width) in the 1024x690 frame
    ("swing", 60, "handlebar"): (100, 430, 150, 250),
    ("circle", 30, "fork"): (330, 720, 150, 250),
}


def main() -> None:
    import photo3d
    from photo3d.mesh.light import build_light_mesh
    from photo3d.render.animate import VideoSpec, path_cameras
    from photo3d.render.renderer import Renderer, video_settings
    from photo3d.sample import motorcycle

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--full", action="store_true", help="also save the whole frames")
    args = ap.parse_args()
    s = motorcycle()
    default = photo3d.Config()
    configs = {"exact": default.with_(edges="exact"),
               "align": default, "soft": default.with_(edges="soft")}
    times: dict[str, list[float]] = {name: [] for name in configs}
    photos = {}
    for _ in range(args.repeat):
        for name, config in configs.items():
            t = time.perf_counter()
            photos[name] = photo3d.make(s.left, depth=np.asarray(s.disparity), config=config)
            times[name].append(time.perf_counter() - t)
    frames = {}
    for edges, photo in photos.items():
        light = build_light_mesh(photo.ldi)
        with Renderer(light, video_settings()) as renderer:
            for path, frame, _ in CROPS:
                cam = path_cameras(photo.ldi, VideoSpec(path=path))[frame]
                frames[edges, path, frame] = renderer.render(cam).color
    out = ROOT / "docs" / "img"
    for (path, frame, name), (top, left, h, w) in CROPS.items():
        pair = [frames[e, path, frame][top:top + h, left:left + w] for e in configs]
        both = np.concatenate([np.kron(p, np.ones((2, 2, 1))) for p in pair], axis=0)
        Image.fromarray((np.clip(both, 0, 1) * 255 + 0.5).astype(np.uint8)).save(
            out / f"edges_{path}{frame}_{name}.png", optimize=True)
        if args.full:
            for e in configs:
                Image.fromarray((np.clip(frames[e, path, frame], 0, 1) * 255 + 0.5).astype(
                    np.uint8)).save(f"/tmp/frame_{path}{frame}_{e}.png")
    save_record({"make_s": times,
                 "median_make_s": {k: float(np.median(v)) for k, v in times.items()},
                 "fringe_pixels": int(np.count_nonzero(photos["align"].ldi.alpha < 1)),
                 "ldi_pixels": {k: p.ldi.size for k, p in photos.items()},
                 **{f"timings_{k}": p.timings for k, p in photos.items()}},
                ROOT / "benchmarks" / "results" / "edges_demo.json", "edges_demo",
                "demo_edge_crops.py")
    print({k: [round(x, 1) for x in v] for k, v in times.items()})


if __name__ == "__main__":
    main()
