"""Benchmark the light textured mesh against the full mesh on the 1024 px demo.

Makes the 3D photo of the bundled sample (Middlebury motorcycle, 1024 px; not
timed), then:

* sizes: ``mesh.glb`` (light, textured) and ``viewer.html`` as ``save`` writes them,
  against the full vertex-coloured GLB (``--full-glb``);
* save time: ``Photo3D.save`` (light GLB, viewer from the light mesh) vs the save
  of photo3d before the light mesh (npz, full mesh, PLY, full GLB, viewer from the
  full mesh: the same writers called one by one), interleaved, median of ``--runs``;
* fidelity: frames of the four standard paths (``--frames`` per path, spread
  over the path) rendered from the light mesh and from the full mesh with the same
  renderer (numba, 2x supersampling, the authors' crop); PSNR per frame;
* render time per frame, light vs full, interleaved per frame; the same with the
  OpenGL backend (fewer frames) when EGL works.

Usage: python benchmarks/bench_light.py [--runs 3] [--frames 24] [--size 1280x720]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info, run_child  # noqa: E402

CHILD = r"""
import json, statistics, sys, tempfile, time
from pathlib import Path
import numpy as np
import photo3d
from photo3d.data import motorcycle
from photo3d.light import build_light_mesh
from photo3d.render.animate import VideoSpec, path_cameras
from photo3d.render.paths import PRESETS
from photo3d.render.renderer import AUTHORS_CROP, Renderer, RenderSettings
frames, width, height, runs, max_error = (int(sys.argv[1]), int(sys.argv[2]),
                                          int(sys.argv[3]), int(sys.argv[4]),
                                          float(sys.argv[5]))
s = motorcycle()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity))
full = photo.mesh()
t = time.perf_counter()
light = build_light_mesh(photo.ldi, full=full, max_error=max_error)
light_s = time.perf_counter() - t
out = {"ldi_pixels": int(photo.ldi.size), "full_faces": int(len(full.faces)),
       "light_faces": int(len(light.faces)), "light_vertices": int(len(light.vertices)),
       "texture": list(light.texture.shape[:2]), "build_light_s": light_s,
       "max_error": max_error}
from photo3d.io.gltf import write_glb
from photo3d.io.ply import write_ply
from photo3d.ldi import save_npz
from photo3d.viewer import write_viewer


def save_before(target):
    target.mkdir()
    meta = {"config": photo.config.to_dict(), "stats": photo.stats, "timings": photo.timings}
    save_npz(photo.ldi, target / "photo3d.npz", meta=meta)
    (target / "config.json").write_text(json.dumps(meta, indent=2))
    mesh = photo.mesh()
    write_ply(target / "mesh.ply", mesh)
    write_glb(target / "mesh.glb", mesh)
    write_viewer(mesh, target / "viewer.html", title=target.name)


save = {"light": [], "full": []}
with tempfile.TemporaryDirectory() as tmp:
    for r in range(runs):
        for kind in ("full", "light"):
            target = Path(tmp) / f"{kind}{r}"
            t = time.perf_counter()
            if kind == "full":
                save_before(target)
            else:
                photo.save(target, light_error=max_error)
            save[kind].append(time.perf_counter() - t)
            out[f"{kind}_sizes"] = {p.name: p.stat().st_size for p in target.iterdir()}
out["save_s"] = save
settings = RenderSettings(ssaa=2, crop=AUTHORS_CROP, backend="numba")
psnr, times = {}, {"light": [], "full": []}
with Renderer(full, settings) as rf, Renderer(light, settings) as rl:
    for name in PRESETS:
        spec = VideoSpec(path=name, size=(width, height), frames=240, fps=40)
        cameras = path_cameras(photo.ldi, spec)
        picks = np.linspace(0, len(cameras) - 1, frames).round().astype(int)
        values = []
        for i in picks:
            t = time.perf_counter(); a = rf.render(cameras[i]).color; t1 = time.perf_counter()
            b = rl.render(cameras[i]).color; t2 = time.perf_counter()
            times["full"].append(t1 - t); times["light"].append(t2 - t1)
            a8 = np.round(a * 255.0); b8 = np.round(b * 255.0)
            mse = float(np.mean((a8 - b8) ** 2))
            values.append(99.0 if mse == 0 else 10 * np.log10(255.0 ** 2 / mse))
        psnr[name] = values
out["psnr"] = psnr
out["frame_s"] = times
try:  # the OpenGL backend (EGL; software llvmpipe on a machine without a GPU)
    gl = RenderSettings(ssaa=2, crop=AUTHORS_CROP, backend="gl")
    gl_times, gl_psnr = {"light": [], "full": []}, []
    with Renderer(full, gl) as rf, Renderer(light, gl) as rl:
        for name in PRESETS:
            spec = VideoSpec(path=name, size=(width, height), frames=240, fps=40)
            cameras = path_cameras(photo.ldi, spec)
            for i in np.linspace(0, len(cameras) - 1, max(2, frames // 4)).round().astype(int):
                t = time.perf_counter(); a = rf.render(cameras[i]).color; t1 = time.perf_counter()
                b = rl.render(cameras[i]).color; t2 = time.perf_counter()
                gl_times["full"].append(t1 - t); gl_times["light"].append(t2 - t1)
                mse = float(np.mean((np.round(a * 255.0) - np.round(b * 255.0)) ** 2))
                gl_psnr.append(99.0 if mse == 0 else 10 * np.log10(255.0 ** 2 / mse))
    from photo3d.render.gl import gl_renderer
    out["gl"] = {"frame_s": gl_times, "psnr": gl_psnr, "renderer": gl_renderer()}
except Exception as err:  # no EGL here: the benchmark still reports the rest
    out["gl"] = {"error": repr(err)}
print(json.dumps(out))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--frames", type=int, default=24)
    parser.add_argument("--size", type=lambda t: tuple(int(v) for v in t.split("x")),
                        default=(1280, 720))
    parser.add_argument("--max-error", type=float, default=0.5)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "light.json")
    args = parser.parse_args()
    w, h = args.size
    load = [os.getloadavg()[0]]
    r = run_child(CHILD, args.frames, w, h, args.runs, args.max_error)
    import numpy as np

    allp = np.concatenate([np.asarray(v) for v in r["psnr"].values()])
    med = {k: float(np.median(v)) for k, v in r["save_s"].items()}
    ft = {k: float(np.median(v)) for k, v in r["frame_s"].items()}
    record = {"benchmark": "light", **r, "size": [w, h], "mean_psnr": float(allp.mean()),
              "min_psnr": float(allp.min()), "median_save_s": med, "median_frame_s": ft,
              "machine": machine_info(), "load_1min": [*load, os.getloadavg()[0]],
              "command": " ".join(["python", "benchmarks/bench_light.py", *sys.argv[1:]])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))
    print(f"light mesh: {r['light_faces']:,} triangles, {r['light_vertices']:,} vertices, "
          f"texture {r['texture'][1]}x{r['texture'][0]} (full: {r['full_faces']:,} triangles); "
          f"built in {r['build_light_s']:.2f} s")
    for kind in ("full", "light"):
        sizes = r[f"{kind}_sizes"]
        label = {"full": "before (full GLB + viewer)", "light": "now (light GLB + viewer)"}
        print(f"{label[kind]}: save {med[kind]:.2f} s median: " + ", ".join(
            f"{k} {v / 1e6:.2f} MB" for k, v in sorted(sizes.items())))
    print(f"fidelity, {len(allp)} frames of the 4 paths at {w}x{h}: PSNR mean "
          f"{allp.mean():.2f} dB, min {allp.min():.2f} dB; per path: " + ", ".join(
              f"{k} {np.mean(v):.2f}/{np.min(v):.2f}" for k, v in r["psnr"].items()))
    print(f"render per frame (numba, ssaa 2): full {1000 * ft['full']:.0f} ms, light "
          f"{1000 * ft['light']:.0f} ms (median, interleaved)")
    gl = r["gl"]
    if "error" in gl:
        print(f"OpenGL backend not measured: {gl['error']}")
    else:
        g = {k: float(np.median(v)) for k, v in gl["frame_s"].items()}
        print(f"render per frame (OpenGL {gl['renderer']}, ssaa 2): full {1000 * g['full']:.0f} "
              f"ms, light {1000 * g['light']:.0f} ms; PSNR light vs full mean "
              f"{np.mean(gl['psnr']):.2f} dB, min {np.min(gl['psnr']):.2f} dB")


if __name__ == "__main__":
    main()
