"""The light-mesh section of ``RESULTS.md`` (kept apart from make_results.py for size)."""

from __future__ import annotations

import statistics


def _load(rec) -> str:
    """The load average around the run, if recorded."""
    if "load_1min" not in rec:
        return "Load not recorded (the machine was shared with other jobs). "
    a, b = rec["load_1min"]
    return f"1-minute load average {a:.1f} at the start, {b:.1f} at the end (2 cores). "


def section_light(load, machine_line, missing) -> str:
    out = ["## Light textured mesh.glb (issue 17)", ""]
    rec = load("light.json")
    if rec is None:
        return "\n".join(out) + "\n" + missing("python benchmarks/bench_light.py")
    full, light = rec["full_sizes"], rec["light_sizes"]
    mb = 1e6
    save = rec["median_save_s"]
    frames = rec["median_frame_s"]
    n = sum(len(v) for v in rec["psnr"].values())
    out += [
        f"Command: `{rec['command']}`. Machine: {machine_line(rec)}. {_load(rec)}"
        "Before/after pairs were run interleaved in the same process, so their ratios are "
        "the fair comparison.", "",
        f"The 1024 px motorcycle 3D photo ({rec['ldi_pixels']:,} LDI pixels). Light mesh: "
        f"error bound {rec['max_error']} px (parallax for a 0.03 camera shift, and texture "
        "drift), built with meshoptimizer from the full mesh.", "",
        "| | before (full mesh) | now (light, default) | target |",
        "| --- | --- | --- | --- |",
        f"| `mesh.glb` | {full['mesh.glb'] / mb:.1f} MB, {rec['full_faces']:,} triangles | "
        f"**{light['mesh.glb'] / mb:.2f} MB, {rec['light_faces']:,} triangles** "
        f"(texture {rec['texture'][1]}x{rec['texture'][0]} JPEG) | <= 10 MB, <= 400k |",
        f"| `viewer.html` | {full['viewer.html'] / mb:.2f} MB | **{light['viewer.html'] / mb:.2f}"
        " MB** | <= 4 MB |",
        f"| `mesh.ply`, `photo3d.npz` | {full['mesh.ply'] / mb:.1f} MB, "
        f"{full['photo3d.npz'] / mb:.1f} MB | unchanged | unchanged |",
        f"| save time, median of {len(rec['save_s']['light'])} | {save['full']:.2f} s | "
        f"{save['light']:.2f} s | <= half of before |",
        f"| fidelity: PSNR light vs full, {n} frames of the 4 paths at "
        f"{rec.get('size', [1280, 720])[0]}x{rec.get('size', [1280, 720])[1]} | | mean "
        f"**{rec['mean_psnr']:.2f} dB**, lowest frame **{rec['min_psnr']:.2f} dB** | mean >= "
        "35 dB, every frame >= 30 dB |",
        f"| render time per frame (numba, 2x supersampling, interleaved) | "
        f"{1000 * frames['full']:.0f} ms | {1000 * frames['light']:.0f} ms | faster? |", ""]
    per_path = ", ".join(f"{k} {statistics.mean(v):.2f} (min {min(v):.2f})"
                         for k, v in rec["psnr"].items())
    out += [f"PSNR per path (dB): {per_path}.", ""]
    ratio = save["light"] / save["full"]
    if ratio > 0.5:
        out += [f"**The save-time target is not met**: now / before = {ratio:.2f} (target "
                "<= 0.5). Building the light mesh (first build in this run, with numba's "
                f"compilation: {rec['build_light_s']:.1f} s) is mostly meshoptimizer's "
                "simplification. Done so far: planar lattice blocks (32 to 4 pixels, planar "
                "within 0.3 x the error bound) are merged into fans before meshoptimizer "
                "(about half of the 3 million triangles reach it) and `photo3d.npz` is "
                "compressed in a second thread meanwhile. What remains is meshoptimizer on "
                "about 1.6 million triangles (the hidden layers' bands and depth edges have "
                "few whole planar blocks) plus the full mesh that `mesh.ply` needs.", ""]
    if frames["light"] >= frames["full"]:
        out += ["Videos are **not** faster from the light mesh with the numba rasterizer at "
                "this size (its frames cost about as much: the deferred texture lookup per "
                "sample against fewer, larger triangles), so with numba videos stay on the "
                "full mesh (`Renderer` draws either).", ""]
    gl = rec.get("gl", {})
    if "frame_s" in gl:
        g = {k: statistics.median(v) for k, v in gl["frame_s"].items()}
        out += [f"With the OpenGL backend ({gl['renderer']}; {len(gl['psnr'])} frames of the "
                f"4 paths, interleaved) a frame takes {1000 * g['full']:.0f} ms from the full "
                f"mesh and {1000 * g['light']:.0f} ms from the light one "
                f"({g['full'] / g['light']:.1f}x faster), PSNR light vs full mean "
                f"{statistics.mean(gl['psnr']):.2f} dB, lowest {min(gl['psnr']):.2f} dB: "
                "so videos rendered with OpenGL use the light mesh. (On this machine "
                "OpenGL is software rendering, slower than numba either way, and `auto` "
                "picks numba.)", ""]
    elif gl:
        out += [f"OpenGL backend not measured: {gl.get('error')}.", ""]
    return "\n".join(out)
