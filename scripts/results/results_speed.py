"""RESULTS.md sections of issues 35-37 and 46: hard depth maps, videos, the first run,
export, the splats.

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


VIDEO_RUNS = ("video_vs_cdd3384_soft.json", "video_demo_round3.json",
              "video_vs_cdd3384_round3b.json",
              "video_vs_cdd3384_round3.json",
              "video_demo_final.json", "video_vs_cdd3384_final.json",
              "video_vs_cdd3384_frames2.json", "video_vs_cdd3384_frames.json",
              "video_vs_cdd3384_second.json", "video_vs_cdd3384.json", "video_render.json",
              "video.json")
"""The runs of ``bench_video.py`` shown, each against its own reference."""


def section_videos(load, machine_line, missing) -> str:
    """``video*.json``: render (and demo) against a reference, the frames' PSNR to it."""
    out = ["## Videos: render and demo against earlier commits (issue 35)", ""]
    found = False
    for name in VIDEO_RUNS:
        rec = load(name)
        if rec is None:
            continue
        found = True
        med = rec["median"]
        loads = [x for runs in rec.get("runs", {}).values() for r in runs
                 for x in r.get("load_1min", [])]
        load_text = f", 1-minute load {min(loads):.1f}-{max(loads):.1f}" if loads else ""
        own = (" Each version renders the demo photo it made itself (`--own-photos`: the "
               "reference cannot read this version's `photo3d.npz` format), so the frames "
               "differ by more than the renderer.") if rec.get("own_photos") else ""
        out += [f"### `{name}`: against `{rec.get('ref')}`", "",
                f"Command: `{rec.get('command')}`. Machine: {machine_line(rec)}{load_text}. "
                "Medians, wall (CPU) seconds, whole process, the two versions alternated."
                + own, "",
                "| | reference | now | ratio |", "| --- | --- | --- | --- |"]
        for what in ("render", "demo"):
            ref, now = med.get(f"{what}_ref"), med.get(f"{what}_now")
            if ref and now:
                out.append(f"| {what} | {ref['wall_s']:.1f} s ({ref['cpu_s']:.1f}) | "
                           f"{now['wall_s']:.1f} s ({now['cpu_s']:.1f}) | "
                           f"{now['wall_s'] / ref['wall_s']:.3f} |")
        psnr = rec.get("psnr_now_vs_ref", {})
        if psnr:
            out += ["", "Frames against the reference's (PSNR, dB): " + ", ".join(
                f"{path} mean {v['mean_db']:.1f} (min {v['min_db']:.1f}, {v['frames']} frames)"
                for path, v in psnr.items()) + "."]
        out.append("")
    if not found:
        return "\n".join(out) + "\n" + missing("python benchmarks/bench_video.py --runs 3")
    return "\n".join(out)


PART_RUNS = (("The fill alone changed", "hard_depth_inpaint.json", "hard_depth"),
             ("The save step alone", "save.json", "save"),
             ("A video frame's steps, one thread", "video_steps.json", "steps"),
             ("Third round: the fill's sweeps and batches", "hard_depth_fill.json", "hard_depth"),
             ("Third round: the save, start-up and preprocess", "hard_depth_save.json",
              "hard_depth"),
             ("Third round: the save step alone", "save_round3.json", "save"),
             ("Third round: the save step alone, raw disparity", "save_raw_round3.json", "save"))
"""The runs of the parts of issue 35's second and third rounds: ``(title, file, kind)``."""


def _part_rows(kind: str, rec: dict) -> list[str]:
    """Table rows of one run of :data:`PART_RUNS`."""
    med = rec["median"]
    if kind == "hard_depth":
        rows = ["| input | ref: wall / CPU s | now: wall / CPU s | edges |",
                "| --- | --- | --- | --- |"]
        for name, now in med.get("now", {}).items():
            old = med.get("previous", {}).get(name, {})
            rows.append(f"| {name} | {old.get('wall_s', 0):.2f} / {old.get('cpu_s', 0):.1f} | "
                        f"{now['wall_s']:.2f} / {now['cpu_s']:.1f} | {now['edges']} |")
        return rows
    if kind == "save":
        rows = [f"Light mesh identical: {rec.get('identical')}.", "",
                "| version | wall s | user CPU s | system CPU s |", "| --- | --- | --- | --- |"]
        for version in ("previous", "now"):
            m = med[version]
            rows.append(f"| {version} | {m['wall_s']:.2f} | {m['user_s']:.2f} | "
                        f"{m['sys_s']:.2f} |")
        return rows
    rows = ["Milliseconds a 1280x720 frame.", "", "| step | ref | now |", "| --- | --- | --- |"]
    for step, ms in med["now"]["steps_ms"].items():
        rows.append(f"| {step} | {med['ref']['steps_ms'].get(step, 0):.1f} | {ms:.1f} |")
    return rows + [f"| total | {med['ref']['total_ms']:.1f} | {med['now']['total_ms']:.1f} |"]


def section_parts(load, machine_line, missing) -> str:
    """:data:`PART_RUNS`: the parts of ``make`` and ``render`` timed in issue 35's
    second and third rounds, each against its ``ref`` (the main branch when it ran)."""
    out = ["## Parts of make and render, second and third rounds (issue 35)", "",
           "Each against the main branch of the time (`ref`), alternated, medians; the "
           "machine was shared with other runs: compare the CPU seconds.", ""]
    for title, name, kind in PART_RUNS:
        rec = load(name)
        if rec is not None:
            out += [f"### {title}: `{rec['command']}`", "", f"Machine: {machine_line(rec)}.",
                    "", *_part_rows(kind, rec), ""]
    if len(out) == 4:
        return "\n".join(out) + "\n" + missing("python benchmarks/bench_save.py")
    return "\n".join(out)


def section_ui(load, machine_line, missing) -> str:
    """``ui.json``: one request of photo3d ui after the warm-up."""
    rec = load("ui.json")
    out = _head("One request of photo3d ui (issue 35)", rec,
                "python benchmarks/bench_ui.py --runs 3", machine_line, missing)
    if isinstance(out, str):
        return out
    out += ["The bundled sample's photo and depth at 1024 px, one `circle` video, after the "
            "warm-up; medians, the two versions alternated.", "",
            "| | request (s) | CPU (s) | 3D photo shown after (s) |", "| --- | --- | --- | --- |"]
    for who in ("ref", "now"):
        m = rec["median"][who]
        label = f"reference (`{rec.get('ref')}`)" if who == "ref" else "now"
        out.append(f"| {label} | {m['wall_s']:.2f} | {m['cpu_s']:.1f} | "
                   f"{m['first_result_s']:.2f} |")
    stages = rec.get("median_stages_s", {}).get("now", {})
    if stages:
        out += ["", "Stages now (s): " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items())
                + "."]
    return "\n".join(out + [""])


def section_export(load, machine_line, missing) -> str:
    """``export.json``: all five export formats of the sample."""
    rec = load("export.json")
    out = _head("Export: splats, USDZ and a quilt of the sample (issue 37)", rec,
                "python benchmarks/bench_export.py --runs 3 --ref REF_SRC", machine_line, missing)
    if isinstance(out, str):
        return out
    med = rec["medians"]
    nofit = "now-nofit" in med  # --no-fit-too: now with --no-splat-fit as well
    out += ["Formats: " + ", ".join(rec["formats"]) + "; medians of wall (CPU) seconds; "
            "`call`: `export_folder` in the process, `command`: the whole command"
            + ("; now: the default (splat colours fitted), now, `--no-splat-fit`: the "
               "colours as built, each version run in turn" if nofit else "") + ".", "",
            "| | now |" + (" now, `--no-splat-fit` |" if nofit else "")
            + " reference | 1-min load |",
            "| --- | --- |" + (" --- |" if nofit else "") + " --- | --- |"]
    for kind in ("call", "command"):
        cells = [med[v][kind] for v in ("now", "now-nofit", "ref") if v in med]
        out.append(f"| {kind} | " + " | ".join(f"{c['wall']:.2f} s ({c['cpu']:.2f})"
                                                for c in cells)
                   + f" | {med['now'][kind]['load']:.1f} |")
    out += ["", "Files: " + ", ".join(f"{k} {v} MB" for k, v in rec["files_mb"].items()) + "."]
    if "peak_rss_mb" in rec:
        peaks = rec["peak_rss_mb"]
        out += ["", "Peak resident memory of the processes: " + ", ".join(
            f"{'reference' if k == 'ref' else k} {v:.0f} MB" for k, v in peaks.items())
            + f"; what `photo3d export` states before it starts (now): "
            f"{rec['stated_mb']:.0f} MB. Splats: " + ", ".join(
                f"{'reference' if k == 'ref' else k} "
                + ", ".join(f"{n} {c:,}" for n, c in v.items())
                for k, v in rec.get("splats", {}).items()) + "."]
    return "\n".join(out + [""])


def section_splats(load, machine_line, missing) -> str:
    """``splats.json``: the sample's splats, dense and adaptive, in Spark (issue 46)."""
    rec = load("splats.json")
    out = _head("Splats of the sample: dense and adaptive, in Spark (issue 46)", rec,
                "PHOTO3D_NODE_MODULES=.node python benchmarks/bench_splats.py", machine_line,
                missing)
    if isinstance(out, str):
        return out
    t = rec["targets"]
    out += ["Spark 2.2 (headless Chromium) against photo3d's own render of the 3D photo: "
            "PSNR over the pixels photo3d's render covers; empty: the share of those Spark "
            f"leaves empty. Issue 46's targets: at most {t['splats']:,} splats, "
            f"`splats.spz` at most {t['spz_mb']} MB, input camera at least "
            f"{t['input_db']} dB, widest circle camera at least {t['widest_db']} dB with at "
            f"most {100 * t['widest_empty']} % empty. Each layout as built (`--no-splat-fit`) "
            "and with its colours fitted (the default: photo3d.export.splat_fit, fitted to "
            "photo3d's render from the input camera only). build s: median seconds to build the "
            "splats in that session, the fit included (its reference is made from the "
            "LDI; the machine's "
            "load shows in it: load, the 1-minute load average before the runs; "
            f"{rec.get('load_note', 'see the machine line')}). model dB: the fit's model of "
            "Spark (photo3d.export.spark_model) against Spark's own image, input and widest "
            "camera, all pixels (Spark blends in 8 bits).", "",
            "| layout | splats | build s (load) | PLY MB | GLB MB | SPZ 3 MB | SPZ 4 MB "
            "| input dB | widest dB | widest empty | model dB |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name, r in rec["results"].items():
        f = r["files_mb"]
        out.append(f"| {name} | {r['splats']:,} | {r['build_s']:.2f} ({r.get('load_1min', '?')}) "
                   f"| {f['splats.ply']:.1f} "
                   f"| {f['splats.glb']:.1f} | {f['splats.spz v3']:.2f} | "
                   f"{f['splats.spz v4']:.2f} | {r['input_db']:.2f} | {r['widest_db']:.2f} | "
                   f"{100 * r['widest_empty']:.3f} % | "
                   + " / ".join(f"{m:.1f}" for m in r.get("model_db", [])) + " |")
    return "\n".join(out + [""])
