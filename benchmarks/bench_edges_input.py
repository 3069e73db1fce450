"""Soft silhouettes at the photo's own camera, and what they cost a video frame (issue 44).

For each of ``bench_edges.py``'s three layered scenes, with exact depth and with the
depth spread 2 px onto the far side: ``make`` with ``--edges align`` and ``soft``, then
the input view rendered as the videos are (2 x 2 supersampling), scored against the
photo within 4 px of depth steps (mean absolute error and LPIPS). A 3D photo must give
its photo back; with soft silhouettes drawn with alpha interpolated between pixel
centres it did not (``docs/edges.md``). Then the bundled sample at 1024 px with both
settings: the seconds of a circle-path frame of its light mesh (11 frames, after one
unmeasured), and the fringe's triangles.

Writes ``benchmarks/results/edges_input.json`` (with a markdown summary for
RESULTS.md).

Usage: python benchmarks/bench_edges_input.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import _edge_scenes as es  # noqa: E402
import bench_edges as be  # noqa: E402
from _machine import save_record  # noqa: E402

EDGES = ("align", "soft")


def input_views() -> list[dict]:
    """Per scene, depth condition and setting: the input view's scores near steps."""
    import photo3d
    from photo3d.camera import Camera, Intrinsics
    from photo3d.config import Config
    from photo3d.eval.lpips import lpips_map
    from photo3d.render.renderer import RenderSettings

    k = Intrinsics.default(es.WIDTH, es.HEIGHT)
    camera = Camera(k, np.eye(4))
    rows = []
    for seed in range(3):
        image, z = es.cast(es.scene(seed), camera)
        near = be._near_steps(be.depth_steps(z))
        for condition in ("exact", "spread2"):
            for edges in EDGES:
                config = Config(size=None, depth_kind="depth", metric=True, edges=edges)
                photo = photo3d.make(image, depth=be.depth_condition(z, condition),
                                     config=config, intrinsics=k)
                view = photo.render(camera, settings=RenderSettings(ssaa=2)).color
                rows.append({"scene": seed, "depth": condition, "edges": edges,
                             "error": float(np.abs(view - image)[near].mean()),
                             "lpips": float(lpips_map(view, image)[near].mean())})
                print(rows[-1], flush=True)
    return rows


def frame_cost() -> dict:
    """Seconds of a circle-path frame of the sample's light mesh, per setting."""
    import photo3d
    from photo3d.mesh.light import build_light_mesh
    from photo3d.render.animate import VideoSpec, path_cameras
    from photo3d.render.renderer import Renderer, video_settings
    from photo3d.sample import motorcycle

    sample = motorcycle()
    out = {}
    for edges in EDGES:
        photo = photo3d.make(sample.left, depth=np.asarray(sample.disparity),
                             config=photo3d.Config(edges=edges))
        light = build_light_mesh(photo.ldi)
        cameras = path_cameras(photo.ldi, VideoSpec(path="circle"))[::24]
        with Renderer(light, video_settings()) as renderer:
            renderer.render_rgb8(cameras[0])
            start = time.perf_counter()
            for camera in cameras:
                renderer.render_rgb8(camera)
            seconds = (time.perf_counter() - start) / len(cameras)
        out[edges] = {"frame_s": seconds, "fringe_triangles":
                      0 if light.overlay is None else len(light.overlay.faces)}
        print(edges, out[edges], flush=True)
    return out


def main() -> None:
    rows = input_views()
    frames = frame_cost()
    lines = ["| scene | depth | align: error, LPIPS | soft: error, LPIPS |",
             "| --- | --- | --- | --- |"]
    for seed in range(3):
        for condition in ("exact", "spread2"):
            cells = [next(r for r in rows if (r["scene"], r["depth"], r["edges"])
                          == (seed, condition, e)) for e in EDGES]
            lines.append(f"| {seed} | {condition} | " + " | ".join(
                f"{c['error']:.4f}, {c['lpips']:.4f}" for c in cells) + " |")
    lines += ["", "Input view (2 x 2 supersampling) against the photo, within 4 px of "
              "depth steps. A circle-path frame of the sample's light mesh: " + ", ".join(
                  f"{e} {frames[e]['frame_s']:.3f} s ({frames[e]['fringe_triangles']:,} "
                  "fringe triangles)" for e in EDGES) + "."]
    save_record({"input_views": rows, "frames": frames, "markdown": "\n".join(lines)},
                Path(__file__).parent / "results" / "edges_input.json", "edges_input",
                "bench_edges_input.py")


if __name__ == "__main__":
    main()
