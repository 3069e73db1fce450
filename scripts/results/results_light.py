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
    full, light = rec["save_sizes"]["before"], rec["save_sizes"]["now"]
    mb = 1e6
    save = rec["median_save_s"]
    frames = rec["median_frame_s"]
    n = sum(len(v) for v in rec["psnr"].values())
    out += [
        f"Command: `{rec['command']}`. Machine: {machine_line(rec)}. {_load(rec)}"
        f"Save times: `Photo3D.save` now against `Photo3D.save` of commit "
        f"`{rec['before_commit']}` (the last before issue 17: npz, PLY, full vertex-coloured "
        "GLB, viewer from the full mesh), that commit's own code, each in its own process "
        "after its own `make`, the processes alternated; render times interleaved per "
        "frame.", "",
        f"The 1024 px motorcycle 3D photo ({rec['ldi_pixels']:,} LDI pixels). Light mesh: "
        f"error bound {rec['max_error']} px (parallax for a 0.03 camera shift, and texture "
        "drift), built by edge collapses (`photo3d.mesh._simplify`) from the full mesh.", "",
        "| | before (full mesh) | now (light, default) | target |",
        "| --- | --- | --- | --- |",
        f"| `mesh.glb` | {full['mesh.glb'] / mb:.1f} MB, {rec['full_faces']:,} triangles | "
        f"**{light['mesh.glb'] / mb:.2f} MB, {rec['light_faces']:,} triangles** "
        f"(texture {rec['texture'][1]}x{rec['texture'][0]} JPEG) | <= 10 MB, <= 400k |",
        f"| `viewer.html` | {full['viewer.html'] / mb:.2f} MB | **{light['viewer.html'] / mb:.2f}"
        " MB** | <= 4 MB |",
        f"| `mesh.ply`, `photo3d.npz` | {full['mesh.ply'] / mb:.1f} MB, "
        f"{full['photo3d.npz'] / mb:.1f} MB | {light['mesh.ply'] / mb:.1f} MB, "
        f"{light['photo3d.npz'] / mb:.1f} MB (both lossless) | full resolution, lossless |",
        f"| save time (all files), median of {len(rec['save_s']['now'])} | "
        f"{save['before']:.2f} s | **{save['now']:.2f} s** ({save['now'] / save['before']:.2f}"
        "x) | <= half of before |",
        f"| fidelity: PSNR light vs full, {n} frames of the 4 paths at "
        f"{rec.get('size', [1280, 720])[0]}x{rec.get('size', [1280, 720])[1]} | | mean "
        f"**{rec['mean_psnr']:.2f} dB**, lowest frame **{rec['min_psnr']:.2f} dB** | mean >= "
        "35 dB, every frame >= 30 dB |",
        f"| render time per frame (numba, 2x supersampling, interleaved) | "
        f"{1000 * frames['full']:.0f} ms | {1000 * frames['light']:.0f} ms | faster? |", ""]
    per_path = ", ".join(f"{k} {statistics.mean(v):.2f} (min {min(v):.2f})"
                         for k, v in rec["psnr"].items())
    out += [f"PSNR per path (dB): {per_path}.", ""]
    ratio = save["now"] / save["before"]
    out += [f"Save now / before = {ratio:.2f} (target <= 0.5: "
            f"**{'met' if ratio <= 0.5 else 'not met'}**). What makes it fast: lattice blocks "
            "(32 to 2 pixels) planar within 0.3 x the error bound become fans that share "
            "their edges without the pixels between block corners, so "
            f"{rec['simplify_faces']:,} of the {rec['full_faces']:,} triangles reach "
            "the simplifier, which runs on "
            "four vertical strips in two threads with the vertices they share locked (5 % more "
            "triangles); the texture is built while it runs; the full mesh's faces come from "
            "a numba kernel; writer threads write `photo3d.npz` (format 2: colours stored, "
            "links relative to their pixel, deflated with the rest), `mesh.ply` and "
            "`mesh.glb` while the light mesh is built. Light mesh built alone (the first "
            "build in the process): "
            f"{rec['build_light_s']:.2f} s.", ""]
    gain = 1 - frames["light"] / frames["full"]
    if 0 < gain < 0.1:
        out += [f"With the numba rasterizer a frame from the light mesh is only {100 * gain:.0f} "
                "% faster at this size (the deferred texture lookup per sample costs about "
                "what the fewer, larger triangles save), so with numba videos stay on the "
                "full mesh, which is exact (`Renderer` draws either).", ""]
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
