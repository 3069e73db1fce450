"""What soft silhouettes cost on the sample (issue 44, item 3): the stage, the paint
behind them, and video frames with the blended fringe.

On the bundled motorcycle at 1024 px: :func:`~photo3d.stages.silhouettes.soft_silhouettes`
on the preprocessed photo, :func:`~photo3d.stages.silhouettes.paint_behind` on the
finished LDI, and 24 frames of the ``circle`` path drawn from the light mesh as
videos are (``video_settings()``), with the fringe (``edges="align"``) and from the
LDI made with ``edges="exact"``; each measured ``--repeat`` times, alternating,
median reported. Writes ``benchmarks/results/alpha_cost.json``.

Usage: python benchmarks/bench_alpha_cost.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402


def main() -> None:
    import photo3d
    from photo3d.depth.normalize import prepare_depth
    from photo3d.mesh.light import build_light_mesh
    from photo3d.render.animate import VideoSpec, path_cameras
    from photo3d.render.renderer import Renderer, video_settings
    from photo3d.sample import motorcycle
    from photo3d.stages.preprocess import preprocess
    from photo3d.stages.silhouettes import paint_behind, silhouettes_of

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--frames", type=int, default=24)
    args = ap.parse_args()
    s = motorcycle()
    config = photo3d.Config()
    dep = prepare_depth(np.asarray(s.disparity), s.left.shape[:2], kind=config.depth_kind)
    pre = preprocess(s.left, dep.disparity, config=config)
    photos = {e: photo3d.make(s.left, depth=np.asarray(s.disparity),
                              config=config.with_(edges=e)) for e in ("exact", "align")}
    sil = silhouettes_of(pre.image, pre.disparity, pre.edges.cuts, config=config,
                         working_size=pre.working_size)
    behind = sil.behind()
    meshes = {e: build_light_mesh(p.ldi) for e, p in photos.items()}
    cams = path_cameras(photos["align"].ldi, VideoSpec(path="circle"))[::240 // args.frames]
    times: dict[str, list[float]] = {"silhouettes": [], "paint_behind": [],
                                     "frames_exact": [], "frames_align": []}
    renderers = {e: Renderer(m, video_settings()) for e, m in meshes.items()}
    for r in renderers.values():
        r.render_rgb8(cams[0])  # warm-up (compiles, allocates)
    for _ in range(args.repeat):
        t = time.perf_counter()
        silhouettes_of(pre.image, pre.disparity, pre.edges.cuts, config=config,
                       working_size=pre.working_size)
        times["silhouettes"].append(time.perf_counter() - t)
        t = time.perf_counter()
        paint_behind(photos["align"].ldi, behind,
                     threshold=config.preprocess.discontinuity)
        times["paint_behind"].append(time.perf_counter() - t)
        for e in ("exact", "align"):
            t = time.perf_counter()
            for cam in cams:
                renderers[e].render_rgb8(cam)
            times[f"frames_{e}"].append((time.perf_counter() - t) / len(cams))
    median = {k: float(np.median(v)) for k, v in times.items()}
    save_record({"times_s": times, "median_s": median, "fringe_pixels": sil.fringe,
                 "overlay_faces": len(meshes["align"].overlay.faces),
                 "light_faces": {e: len(m.faces) for e, m in meshes.items()}},
                Path(__file__).parent / "results" / "alpha_cost.json", "alpha_cost",
                "bench_alpha_cost.py")
    print({k: round(v, 4) for k, v in median.items()})


if __name__ == "__main__":
    main()
