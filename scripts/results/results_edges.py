"""The occlusion-edges section of ``RESULTS.md`` (issue 44; ``benchmarks/bench_edges.py``)."""

from __future__ import annotations

ROWS = ("exact", "spread1", "spread2", "spread3", "shrunk1", "shrunk2", "blurred",
        "motorcycle/gt", "motorcycle/stereo")


def _cell(s: dict) -> str:
    return (f"{s['lpips_steps']:.4f} / {s['psnr_steps']:.2f} / {s['gross_steps']:.1%} | "
            f"{s['lpips_disoccluded']:.4f} / {s['psnr_disoccluded']:.2f} | "
            f"{s['lpips_all']:.4f} / {s['psnr_all']:.2f}")


def section_edges(load, machine_line, missing) -> str:
    """Per depth condition and version: steps LPIPS / PSNR / gross errors, disoccluded
    and whole-view LPIPS / PSNR; the targets; ``make``'s time on the sample."""
    out = ["## Occlusion edges: depth steps on the photo's colour edges (issue 44)", ""]
    rec = load("edges.json")
    if rec is None:
        return "\n".join(out) + "\n" + missing("python benchmarks/bench_edges.py")
    versions = rec["versions"]
    others = ", ".join(f"`{k}`: {v['overrides']}" for k, v in versions.items() if v["overrides"])
    if rec.get("parts"):  # several processes at once, joined by --merge
        runs = "; ".join(f"`{c}`" for c in rec["parts"])
        command = f"{runs}, joined by `{rec['command']}`"
    else:
        command = f"`{rec['command']}`"
    out += [f"Command: {command}. Machine: {machine_line(rec)}. Sizes: {rec['size']}. "
            f"`ref` is commit `{rec['ref']}` (the code before issue 44), `new` this tree's "
            "defaults, other columns this tree with other settings "
            f"({others}). "
            "Scenes: the median over three layered scenes of the mean over 8 exact views; "
            "the motorcycle: its right view. Cells: LPIPS / PSNR (dB) / share off by > 0.25 "
            "within 4 px of depth steps | LPIPS / PSNR of the disoccluded pixels | of the "
            "whole view (method: the script's docstring).", ""]
    out += ["| depth | version | within 4 px of steps | disoccluded | whole view |",
            "| --- | --- | --- | --- | --- |"]
    for row in ROWS:
        for name, v in versions.items():
            s = v["summary"].get(row)
            if s:
                out.append(f"| {row} | {name} | {_cell(s)} |")
    out.append("")
    lines = []
    for name, v in versions.items():
        s = v["summary"]
        if "exact" in s and "spread2" in s:
            lines.append(f"`{name}` {s['spread2']['lpips_steps'] / s['exact']['lpips_steps']:.2f}x"
                         f" (gross {s['spread2']['gross_steps']:.1%})")
    out += ["Spread 2 px against exact depth, LPIPS within 4 px of steps (target <= 1.3x, "
            "gross <= 3 %): " + ", ".join(lines) + ".", ""]
    soft = load("edges_soft.json")
    if soft is not None:
        vs = soft["versions"]
        out += ["### Soft silhouettes on top of the alignment", "",
                f"Command: `{soft['command']}` (machine: {machine_line(soft)}). `align` is "
                "the default, `soft` is `--edges soft` (the alignment and soft silhouettes), "
                "`exact` the depth map's steps; cells as above.", "",
                *_table(vs)]
        out += ["", "Cells: LPIPS within 4 px of steps, share of those off by > 0.25, "
                "LPIPS of the disoccluded pixels.", ""]
    ramps = load("edges_ramps.json")
    if ramps is not None:
        vs = ramps["versions"]
        out += ["### Ramps across depth steps turned into steps", "",
                f"Command: `{ramps['command']}` (machine: {machine_line(ramps)}). `new` "
                "sharpens the ramps (the default), `ramp0` is the code before it (the "
                "alignment alone), the others: "
                + ", ".join(f"`{k}`: {v['overrides']}" for k, v in vs.items() if v["overrides"])
                + "; cells as in the soft silhouettes' table.", "", *_table(vs), ""]
    out += _soft_default(load, machine_line, rec)
    tr = load("edges_time_ramps.json")
    if tr is not None:
        out += [_time_line(tr, "With the ramps (", f"load average "
                           f"{tr['runs']['new'][0]['load_1min'][0]:.1f} at the start"), ""]
    t = load("edges_time.json")
    if t is not None:
        m, load0 = t["median"], t["runs"]["new"][0]["load_1min"][0]
        out += [f"`make` of the sample at 1024 px (`{t['command']}`, {len(t['runs']['new'])} "
                f"alternating runs each, medians; load average {load0:.1f} at the start): "
                f"ref {m['ref']['make_s']:.2f} s (preprocess "
                f"{m['ref']['preprocess_s']:.2f} s), new {m['new']['make_s']:.2f} s (preprocess "
                f"{m['new']['preprocess_s']:.2f} s): {t['ratio_make']:.2f}x (target <= 1.15x); "
                f"CPU time {m['ref']['cpu_s']:.2f} -> {m['new']['cpu_s']:.2f} s "
                f"({m['new']['cpu_s'] / m['ref']['cpu_s']:.2f}x).",
                ""]
    return "\n".join(out)


def _soft_default(load, machine_line, rec: dict) -> list[str]:
    """The soft silhouettes as the default against `align` (one run) and against
    e951c93 (``edges.json``'s ``ref`` rows), with ``make``'s time."""
    soft = load("edges_soft_default.json")
    if soft is None:
        return []
    vs = dict(soft["versions"])
    if "ref" in rec["versions"]:
        vs = {"ref (e951c93)": rec["versions"]["ref"], **vs}
    out = ["### Soft silhouettes as the default", "",
           f"Command: `{soft['command']}` (machine: {machine_line(soft)}; the source a "
           "`git archive` of commit 44ba968); `ref (e951c93)` from the first table. `new` "
           "is the default, `soft` (the alignment, the ramps and soft silhouettes, the "
           "fringe drawn in one pass, synthesis regions at least twice the fringe's band "
           "deep); `align` the same without soft silhouettes. Cells: "
           "LPIPS within 4 px of steps, share of those off by > 0.25, LPIPS of the "
           "disoccluded pixels, LPIPS of the whole view.", "",
           *_table(vs, whole=True), ""]
    thin = load("edges_thin_median.json")
    if thin is not None:
        before = {"soft, before": soft["versions"]["new"]}
        out += ["### A median that keeps thin structures", "",
                f"Command: `{thin['command']}` (machine: {machine_line(thin)}). `new` is the "
                "default (soft) with the median keeping long thin structures a colour-guided "
                "run of it keeps (`filters.keep_thin`), `align` the same without soft "
                "silhouettes, `soft, before` the table above's default. Cells as above.", "",
                *_table({**before, **thin["versions"]}, whole=True), ""]
        tt = load("edges_time_thin.json")
        if tt is not None:
            out += [_time_line(tt, "`make` with it (", None,
                               "the source a `git archive` of commit c79d328; "), ""]
        tf = load("edges_time_fast.json")
        if tf is not None:
            out += [_time_line(tf, "With the alignment's median sought only where it can "
                               "move a pixel and `link_edges` sorting only the silhouette "
                               "pixels, the same output (", "calm machine",
                               "the source a `git archive` of commit d734df1; "), ""]
    t = load("edges_time_soft.json")
    if t is not None:
        out += [_time_line(t, "`make` of the sample at 1024 px with soft silhouettes on (",
                           f"load average {t['runs']['new'][0]['load_1min'][0]:.1f} at the "
                           "start"), ""]
    return out


def _time_line(t: dict, lead: str, after: str | None, before: str = "") -> str:
    """One ``bench_edges.py --time`` record as a sentence: ``lead``, the command, the
    runs (``before`` them, ``after`` the medians), the two medians, their ratio
    against the 1.15x target and the preprocess stage's seconds."""
    m = t["median"]
    runs = f"{len(t['runs']['new'])} alternating runs each, medians"
    tail = f"; {after}" if after else ""
    return (f"{lead}`{t['command']}`, {before}{runs}{tail}): ref {m['ref']['make_s']:.2f} s, "
            f"new {m['new']['make_s']:.2f} s: {t['ratio_make']:.2f}x (target <= 1.15x); "
            f"preprocess {m['ref']['preprocess_s']:.2f} -> {m['new']['preprocess_s']:.2f} s.")


def _table(versions: dict, *, whole: bool = False) -> list[str]:
    """A row per depth condition, a column per version: LPIPS within 4 px of steps,
    gross errors, disoccluded LPIPS (and, ``whole``, the whole view's)."""
    out = ["| depth | " + " | ".join(versions) + " |", "| --- |" + " --- |" * len(versions)]
    for row in ROWS:
        if all(row in v["summary"] for v in versions.values()):
            cells = []
            for v in versions.values():
                r = v["summary"][row]
                cells.append(f"{r['lpips_steps']:.4f}, {r['gross_steps']:.1%}, "
                             f"{r['lpips_disoccluded']:.4f}"
                             + (f", {r['lpips_all']:.4f}" if whole else ""))
            out.append(f"| {row} | " + " | ".join(cells) + " |")
    return out
