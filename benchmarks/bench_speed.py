"""Per-stage time and peak memory of ``photo3d.make`` at 512, 1024 and 2048 px.

Input: the motorcycle sample (741x500, resized by the pipeline to each working
size). Each run is a fresh process (``_make_child.py``, numba cache warm); median
of N runs per size and backend; peak memory is the child's peak RSS. Writes
``results/speed.json`` and a plot of total time vs pixels, ``results/speed.png``.

Backends: ``diffusion`` (or another ``Config.inpainter`` name); ``learned`` = the
authors' architectures with random weights (inference time does not depend on the
values); ``learned-compact`` = the learned backend with the weights in ``--weights
DIR`` (e.g. the compact nets shipped with photo3d).

Usage: python benchmarks/bench_speed.py [--runs 3] [--sizes 512,1024,2048]
                                        [--backends diffusion,learned,learned-compact]
                                        [--weights DIR]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info, run_make  # noqa: E402
from _plot import line_plot  # noqa: E402


def run_once(size: int, backend: str, weights: str = "") -> dict:
    """One ``make`` (then ``mesh``, reported as the stage ``mesh``) in a fresh process."""
    if backend == "learned":
        options = ["--random-nets"]
    elif backend == "learned-compact":
        options = ["--weights", weights]
    else:
        options = ["--inpainter", backend]
    run = run_make(size, *options, "--mesh")
    run["stages"]["mesh"] = run["mesh_s"]
    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--sizes", default="512,1024,2048")
    parser.add_argument("--backends", default="diffusion")
    parser.add_argument("--weights", default="", help="weights of learned-compact")
    parser.add_argument("--merge", action="store_true",
                        help="add to an existing results file instead of replacing it")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "speed.json")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    backends = args.backends.split(",")
    command = " ".join(["python", "benchmarks/bench_speed.py", *sys.argv[1:]])
    record = {"benchmark": "speed", "machine": machine_info(), "results": {},
              "command": command}
    if args.merge and args.out.is_file():  # keep the other backends' results
        record = json.loads(args.out.read_text())
        commands = record["command"].split("; ")
        if command not in commands:
            commands.append(command)
        record["command"] = "; ".join(commands)
    for backend in backends:
        if args.runs > 1:
            run_once(sizes[0], backend, args.weights)  # warm-up (numba cache, page cache)
        for size in sizes:
            runs = [run_once(size, backend, args.weights) for _ in range(args.runs)]
            med = {
                "make_s": statistics.median(r["make_s"] for r in runs),
                "stages": {k: statistics.median(r["stages"][k] for r in runs)
                           for k in runs[0]["stages"]},
                "peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
                "pixels": runs[0]["pixels"], "ldi_pixels": runs[0]["ldi_pixels"],
                "faces": runs[0]["faces"], "edges": runs[0]["edges"],
                "cpu": machine_info()["cpu"],  # a merged file may mix machines
            }
            record["results"].setdefault(backend, {})[str(size)] = {"median": med, "runs": runs}
            stages = ", ".join(f"{k} {v:.2f}" for k, v in med["stages"].items())
            print(f"{backend:9} {size:5} px: make {med['make_s']:6.2f} s ({stages}); "
                  f"peak {med['peak_rss_mb']:.0f} MB; {med['pixels']:,} px")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))
    series = {b: [(v["median"]["pixels"] / 1e6, v["median"]["make_s"])
                  for v in record["results"][b].values()] for b in record["results"]}
    line_plot(series, args.out.with_suffix(".png"), x_label="megapixels (working size)",
              y_label="make time (s)", title="photo3d make: time vs image size")


if __name__ == "__main__":
    main()
