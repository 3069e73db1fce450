"""Benchmark the light textured mesh against the full mesh on the 1024 px demo.

Makes the 3D photo of the bundled sample (Middlebury motorcycle, 1024 px; not
timed), then:

* sizes: ``mesh.glb`` (light, textured) and ``viewer.html`` as ``save`` writes them,
  against the full vertex-coloured GLB (``--full-glb``);
* save time: ``Photo3D.save`` now (light GLB, viewer from the light mesh) vs
  ``Photo3D.save`` of photo3d before issue 17 (commit ``BEFORE``: npz, PLY, full
  GLB, viewer from the full mesh), that commit's own code (``git archive``'d into a
  temporary folder); each in its own process after its own ``make``, the two
  processes alternated ``--rounds`` times, ``--runs`` saves each; medians;
* fidelity: frames of the four standard paths (``--frames`` per path, spread
  over the path) rendered from the light mesh and from the full mesh with the same
  renderer (numba, 2x supersampling, the authors' crop); PSNR per frame;
* render time per frame, light vs full, interleaved per frame; the same with the
  OpenGL backend (fewer frames) when EGL works.

Usage: python benchmarks/bench_light.py [--runs 3] [--rounds 2] [--frames 24] [--size 1280x720]
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
import json, sys, time
from pathlib import Path
import numpy as np
import photo3d
from photo3d.sample import motorcycle
from photo3d.mesh.light import build_light_mesh
from photo3d.render.animate import VideoSpec, path_cameras
from photo3d.render.paths import STANDARD_PATHS
from photo3d.render.renderer import AUTHORS_CROP, Renderer, RenderSettings
frames, width, height, max_error = (int(sys.argv[1]), int(sys.argv[2]),
                                    int(sys.argv[3]), float(sys.argv[4]))
s = motorcycle()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity))
full = photo.mesh()
import photo3d.mesh.light as light_module
seen = {}
simplify = light_module._simplify
def spy(points, faces, error, **kw):  # how many triangles reach the simplifier
    seen["faces"] = len(faces)
    return simplify(points, faces, error, **kw)
light_module._simplify = spy
t = time.perf_counter()
light = build_light_mesh(photo.ldi, full=full, max_error=max_error)
light_s = time.perf_counter() - t
light_module._simplify = simplify
out = {"ldi_pixels": int(photo.ldi.size), "full_faces": int(len(full.faces)),
       "light_faces": int(len(light.faces)), "light_vertices": int(len(light.vertices)),
       "texture": list(light.texture.shape[:2]), "build_light_s": light_s,
       "max_error": max_error, "simplify_faces": seen["faces"]}
settings = RenderSettings(ssaa=2, crop=AUTHORS_CROP, backend="numba")
psnr, times = {}, {"light": [], "full": []}
with Renderer(full, settings) as rf, Renderer(light, settings) as rl:
    for name in STANDARD_PATHS:
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
        for name in STANDARD_PATHS:
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

BEFORE = "8e45671"
"""The last commit before issue 17 (the light mesh): its save is the "before"."""

SAVE_CHILD = r"""
import json, sys, tempfile, time
from pathlib import Path
import numpy as np
import photo3d
try:
    from photo3d.sample import motorcycle
except ImportError:  # the BEFORE commit: photo3d.data
    from photo3d.data import motorcycle
runs = int(sys.argv[1])
s = motorcycle()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity))
times = []
with tempfile.TemporaryDirectory() as tmp:
    for r in range(runs):
        target = Path(tmp) / f"run{r}"
        t = time.perf_counter()
        photo.save(target)
        times.append(time.perf_counter() - t)
    sizes = {p.name: p.stat().st_size for p in target.iterdir()}
print(json.dumps({"save_s": times, "sizes": sizes, "photo3d": photo3d.__file__}))
"""


def save_times(runs: int, rounds: int) -> dict:
    """Save times of photo3d now and at ``BEFORE``, alternated ``rounds`` times."""
    import subprocess
    import tempfile

    root = Path(__file__).resolve().parent.parent
    out = {"now": [], "before": []}
    with tempfile.TemporaryDirectory() as old:
        archive = subprocess.run(["git", "-C", str(root), "archive", BEFORE, "src"],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", old], input=archive, check=True)
        for _ in range(rounds):
            for kind in ("before", "now"):
                env = dict(os.environ)
                if kind == "before":
                    env["PYTHONPATH"] = os.pathsep.join([str(Path(old) / "src"),
                                                         env.get("PYTHONPATH", "")])
                r = json.loads(subprocess.run(
                    [sys.executable, "-c", SAVE_CHILD, str(runs)], env=env,
                    capture_output=True, text=True, check=True).stdout.strip().splitlines()[-1])
                if kind == "before" and not r["photo3d"].startswith(old):
                    raise RuntimeError(f"the old save imported {r['photo3d']}")
                out[kind] += r["save_s"]
                out[f"{kind}_sizes"] = r["sizes"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="saves per process")
    parser.add_argument("--rounds", type=int, default=2,
                        help="processes per version, alternated")
    parser.add_argument("--frames", type=int, default=24)
    parser.add_argument("--size", type=lambda t: tuple(int(v) for v in t.split("x")),
                        default=(1280, 720))
    parser.add_argument("--max-error", type=float, default=0.5)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "light.json")
    args = parser.parse_args()
    w, h = args.size
    load = [os.getloadavg()[0]]
    saves = save_times(args.runs, args.rounds)
    r = run_child(CHILD, args.frames, w, h, args.max_error)
    r["save_s"] = {k: saves[k] for k in ("now", "before")}
    r["save_sizes"] = {k: saves[f"{k}_sizes"] for k in ("now", "before")}
    import numpy as np

    allp = np.concatenate([np.asarray(v) for v in r["psnr"].values()])
    med = {k: float(np.median(v)) for k, v in r["save_s"].items()}
    ft = {k: float(np.median(v)) for k, v in r["frame_s"].items()}
    record = {"benchmark": "light", **r, "size": [w, h], "mean_psnr": float(allp.mean()),
              "min_psnr": float(allp.min()), "median_save_s": med, "median_frame_s": ft,
              "before_commit": BEFORE, "machine": machine_info(),
              "load_1min": [*load, os.getloadavg()[0]],
              "command": " ".join(["python", "benchmarks/bench_light.py", *sys.argv[1:]])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))
    print(f"light mesh: {r['light_faces']:,} triangles, {r['light_vertices']:,} vertices, "
          f"texture {r['texture'][1]}x{r['texture'][0]} (full: {r['full_faces']:,} triangles); "
          f"built in {r['build_light_s']:.2f} s")
    for kind in ("before", "now"):
        sizes = r["save_sizes"][kind]
        label = {"before": f"before (commit {BEFORE}: full GLB + viewer)",
                 "now": "now (light GLB + viewer)"}
        print(f"{label[kind]}: save {med[kind]:.2f} s median of {len(r['save_s'][kind])}: "
              + ", ".join(f"{k} {v / 1e6:.2f} MB" for k, v in sorted(sizes.items())))
    print(f"save now / before: {med['now'] / med['before']:.2f}")
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
