"""RESULTS.md sections of issues 35-37: hard depth maps, videos, the first run, export.

Each reads the JSON its benchmark writes (``benchmarks/results/``) and is called by
``make_results.py`` with its ``load``, ``machine_line`` and ``missing`` helpers.
"""

from __future__ import annotations


def _head(title: str, rec: dict | None, cmd: str, machine_line, missing) -> list[str] | str:
    out = [f"## {title}", ""]
    if rec is None:
        return "\n".join(out) + "\n" + missing(cmd)
    return out + [f"Command: `{rec.get('command', cmd)}`. Machine: {machine_line(rec)}.", ""]


def section_hard_depth(load, machine_line, missing) -> str:
    """``hard_depth.json``: make --no-video on the sample, its raw disparity and hostile maps."""
    rec = load("hard_depth.json")
    out = _head("Depth maps with holes and noise: bounded passes (issues 35, 36)", rec,
                "python benchmarks/bench_hard_depth.py --runs 3 --hostile", machine_line, missing)
    if isinstance(out, str):
        return out
    med = rec["median"]
    out += ["Whole process `photo3d make --no-video` (wall and CPU seconds, peak resident "
            "memory, edges per inpainting pass), the previous commit (`" + str(rec.get("ref"))
            + "`) and this one in the same session; memory estimate of `photo3d.resources` "
            f"for these inputs: {rec.get('estimate_mb', 0):.0f} MB.", "",
            "| input | before: wall / CPU s | before: peak MB | before: edges | now: wall / CPU s"
            " | now: peak MB | now: edges |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, now in med.get("now", {}).items():
        old = med.get("previous", {}).get(name, {})
        before = (f"{old['wall_s']:.1f} / {old['cpu_s']:.1f} | {old['peak_rss_mb']:.0f} | "
                  f"{old['edges']}") if old else "- | - | -"
        out.append(f"| {name} | {before} | {now['wall_s']:.1f} / {now['cpu_s']:.1f} | "
                   f"{now['peak_rss_mb']:.0f} | {now['edges']} |")
    return "\n".join(out + [""])


def section_videos(load, machine_line, missing) -> str:
    """``video.json``: render and demo against a reference, and the frames' PSNR to it."""
    rec = load("video.json")
    out = _head("Videos: render and demo against the previous commit (issue 35)", rec,
                "python benchmarks/bench_video.py --runs 3", machine_line, missing)
    if isinstance(out, str):
        return out
    med = rec["median"]
    out += [f"Reference: `{rec.get('ref')}`, alternated with this tree; medians, wall (CPU) "
            "seconds, whole process.", "", "| | reference | now | ratio |",
            "| --- | --- | --- | --- |"]
    for what in ("render", "demo"):
        ref, now = med.get(f"{what}_ref"), med.get(f"{what}_now")
        if ref and now:
            out.append(f"| {what} | {ref['wall_s']:.1f} s ({ref['cpu_s']:.1f}) | "
                       f"{now['wall_s']:.1f} s ({now['cpu_s']:.1f}) | "
                       f"{now['wall_s'] / ref['wall_s']:.2f} |")
    psnr = rec.get("psnr_now_vs_ref", {})
    if psnr:
        out += ["", "Frames against the reference's (PSNR, dB): " + ", ".join(
            f"{path} mean {v['mean_db']:.1f} (min {v['min_db']:.1f}, {v['frames']} frames)"
            for path, v in psnr.items()) + "."]
    return "\n".join(out + [""])


def section_export(load, machine_line, missing) -> str:
    """``export.json``: all five export formats of the sample."""
    rec = load("export.json")
    out = _head("Export: splats, USDZ and a quilt of the sample (issue 37)", rec,
                "python benchmarks/bench_export.py --runs 3 --ref REF_SRC", machine_line, missing)
    if isinstance(out, str):
        return out
    med = rec["medians"]
    out += ["Formats: " + ", ".join(rec["formats"]) + "; medians of wall (CPU) seconds; "
            "`call`: `export_folder` in the process, `command`: the whole command.", "",
            "| | now | reference | 1-min load |", "| --- | --- | --- | --- |"]
    for kind in ("call", "command"):
        now, ref = med["now"][kind], med["ref"][kind]
        out.append(f"| {kind} | {now['wall']:.2f} s ({now['cpu']:.2f}) | {ref['wall']:.2f} s "
                   f"({ref['cpu']:.2f}) | {now['load']:.1f} |")
    out += ["", "Files: " + ", ".join(f"{k} {v} MB" for k, v in rec["files_mb"].items()) + "."]
    return "\n".join(out + [""])
