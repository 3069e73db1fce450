"""Benchmark ``viewer.html``: size against the GLB and time to first frame in Chromium.

The 3D photo is the Middlebury motorcycle pair at 1024 px (``photo3d.make`` with
its ground-truth disparity). Sizes: ``viewer.html`` and ``mesh.glb`` of the same
mesh. Write time: ``write_viewer`` (median of N). First frame: a fresh headless
Chromium per run (``/usr/bin/chromium`` driven by Playwright; one unmeasured
warm-up run fills the OS page cache), the page opened from ``file://`` in a
1280x720 viewport; the time is the page's own ``performance.now()`` when
``photo3dViewer.ready`` becomes true, i.e. milliseconds from navigation start to
the first frame drawn and read back (the page also reports its stages). Without a
GPU, Chromium draws WebGL with SwiftShader on the CPU, so the draw stage here is far
slower than on any laptop (the page turns multisampling off on such software
renderers). Last, the frame rate while the camera animates (one
run of 10 s). Prints a table and writes ``benchmarks/results/viewer.json``.

The page is built from the light textured mesh, as ``save`` writes it;
``--full-mesh`` builds it from the full mesh (one vertex per LDI pixel), as before.

Usage: python benchmarks/bench_viewer.py [--runs 3] [--size 1024] [--full-mesh --out F]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info  # noqa: E402

CHROMIUM = os.environ.get("PHOTO3D_CHROMIUM", "/usr/bin/chromium")
VIEWPORT = {"width": 1280, "height": 720}
RENDERER_JS = """() => {
    const gl = document.createElement('canvas').getContext('webgl2');
    const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
    return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : null;
}"""


def make_photo(size: int):
    import photo3d
    from photo3d.sample import motorcycle

    sample = motorcycle()
    return photo3d.make(sample.left, depth=np.asarray(sample.disparity),
                        config=photo3d.Config(size=size))


def first_frame(playwright, url: str) -> dict:
    """One cold start: a new browser process, navigation, wait for ``ready``."""
    browser = playwright.chromium.launch(executable_path=CHROMIUM,
                                         args=["--enable-unsafe-swiftshader"])
    try:
        page = browser.new_page(viewport=VIEWPORT, device_scale_factor=1)
        start = time.perf_counter()
        page.goto(url)
        while not page.evaluate("window.photo3dViewer && (photo3dViewer.ready || "
                                "photo3dViewer.error !== null)"):
            time.sleep(0.05)
        wall = time.perf_counter() - start
        result = page.evaluate("({ms: photo3dViewer.firstFrameMs, error: photo3dViewer.error,"
                               " timings: photo3dViewer.timings, canvas: [document.querySelector("
                               "'canvas').width, document.querySelector('canvas').height]})")
        if result["error"]:
            raise RuntimeError(f"viewer failed: {result['error']}")
        result["harness_wall_s"] = wall
        result["gl_renderer"] = page.evaluate(RENDERER_JS)
        return result
    finally:
        browser.close()


def frame_rate(playwright, url: str, seconds: float = 10.0) -> float:
    """Frames per second while the camera animates. Headless Chromium runs
    requestAnimationFrame at 1 fps on pages that draw WebGL unless
    ``--disable-frame-rate-limit`` is given; with it the rate is the renderer's."""
    args = ["--enable-unsafe-swiftshader", "--disable-frame-rate-limit"]
    browser = playwright.chromium.launch(executable_path=CHROMIUM, args=args)
    try:
        page = browser.new_page(viewport=VIEWPORT, device_scale_factor=1)
        page.goto(url)
        while not page.evaluate("window.photo3dViewer && photo3dViewer.ready"):
            time.sleep(0.05)
        time.sleep(2.0)  # past the start of the animation
        frames, start = page.evaluate("[photo3dViewer.frames, performance.now()]")
        time.sleep(seconds)
        frames_end, end = page.evaluate("[photo3dViewer.frames, performance.now()]")
        return (frames_end - frames) / ((end - start) / 1000)
    finally:
        browser.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--full-mesh", action="store_true",
                        help="the viewer of the full mesh (before the light mesh)")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "viewer.json")
    args = parser.parse_args()
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        sys.exit("bench_viewer needs playwright: pip install playwright (and apt chromium)")
    if not Path(CHROMIUM).is_file():
        sys.exit(f"bench_viewer needs Chromium at {CHROMIUM} (apt-get install chromium)")
    from photo3d.io.gltf import write_glb
    from photo3d.io.gltf_textured import write_textured_glb
    from photo3d.viewer import write_viewer

    photo = make_photo(args.size)
    mesh = photo.mesh() if args.full_mesh else photo.light_mesh()
    with tempfile.TemporaryDirectory() as tmp:
        html, glb = Path(tmp) / "viewer.html", Path(tmp) / "mesh.glb"
        (write_glb if args.full_mesh else write_textured_glb)(glb, mesh)
        write_times = []
        for _ in range(args.runs):
            t = time.perf_counter()
            write_viewer(mesh, html)
            write_times.append(time.perf_counter() - t)
        sizes = {"html_bytes": html.stat().st_size, "glb_bytes": glb.stat().st_size}
        sizes["ratio"] = sizes["html_bytes"] / sizes["glb_bytes"]
        with sync_playwright() as p:
            first_frame(p, html.as_uri())  # warm-up
            runs = [first_frame(p, html.as_uri()) for _ in range(args.runs)]
            fps = frame_rate(p, html.as_uri())
    version = subprocess.run([CHROMIUM, "--version"], capture_output=True, text=True).stdout
    stages = {k: statistics.median(r["timings"][k] for r in runs) for k in runs[0]["timings"]}
    med = {"first_frame_ms": statistics.median(r["ms"] for r in runs),
           "harness_wall_s": statistics.median(r["harness_wall_s"] for r in runs),
           "write_viewer_s": statistics.median(write_times), "stages_ms": stages,
           "animated_fps": fps}
    machine = machine_info()
    machine["chromium"] = version.strip()
    record = {"benchmark": "viewer", "size": args.size,
              "mesh": "full" if args.full_mesh else "light",
              "photo": {"width": mesh.width, "height": mesh.height,
                        "vertices": len(mesh.vertices), "faces": len(mesh.faces)},
              "sizes": sizes, "viewport": VIEWPORT, "canvas": runs[0]["canvas"],
              "gl_renderer": runs[0]["gl_renderer"], "runs": runs,
              "write_viewer_runs_s": write_times, "median": med, "machine": machine,
              "command": " ".join(["python", "benchmarks/bench_viewer.py", *sys.argv[1:]])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))
    print(f"motorcycle {mesh.width}x{mesh.height}: {len(mesh.vertices):,} vertices, "
          f"{len(mesh.faces):,} faces; {machine['cpu']}, {machine['cores']} cores")
    print(f"viewer.html {sizes['html_bytes'] / 1e6:.2f} MB, mesh.glb "
          f"{sizes['glb_bytes'] / 1e6:.2f} MB (ratio {sizes['ratio']:.3f}); "
          f"write_viewer {med['write_viewer_s']:.2f} s")
    print(f"first frame (navigation start -> ready), {args.runs} runs (median): "
          f"{med['first_frame_ms']:.0f} ms at {runs[0]['canvas'][0]}x{runs[0]['canvas'][1]} "
          f"on {runs[0]['gl_renderer']}")
    print("  stages (ms): " + ", ".join(f"{k} {v:.0f}" for k, v in stages.items()))
    print("  individual: " + ", ".join(f"{r['ms']:.0f}" for r in runs))
    print(f"animated: {fps:.2f} frames per second (--disable-frame-rate-limit)")


if __name__ == "__main__":
    main()
