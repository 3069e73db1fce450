"""Speed and memory of ``make`` with each inpainter, interleaved in one session.

The machine is shared and its speed drifts, so the inpainters alternate run by run
(A B A B ...) and the result is each one's median and the ratio of the medians. Each
run is a fresh process (``_make_child.py``; numba's cache warmed first); the time is
measured around ``photo3d.make`` on the Middlebury motorcycle at ``--size``; memory is
each child's own peak resident set size; the CPU time (user + system, all threads) is
recorded too, as it is less sensitive to other jobs on a shared machine. Writes
``benchmarks/results/fill_speed.json``.

Usage: python benchmarks/bench_fill.py [--runs 5] [--size 1024]
           [--inpainters structured,diffusion]
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import run_make, save_record  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--inpainters", default="structured,diffusion")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "fill_speed.json")
    args = parser.parse_args()
    names = args.inpainters.split(",")
    for name in names:  # warm-up: numba's cache, page cache
        run_make(args.size, "--inpainter", name)
    runs: dict[str, list[dict]] = {n: [] for n in names}
    for _ in range(args.runs):
        for name in names:
            runs[name].append(run_make(args.size, "--inpainter", name))
    median = {n: {"make_s": statistics.median(r["make_s"] for r in rs),
                  "cpu_s": statistics.median(r["cpu_s"] for r in rs),
                  "inpaint_s": statistics.median(r["stages"]["inpaint"] for r in rs),
                  "peak_rss_mb": max(r["peak_rss_mb"] for r in rs)}
              for n, rs in runs.items()}
    base = names[-1]
    ratio = {n: median[n]["make_s"] / median[base]["make_s"] for n in names}
    record = save_record({"size": args.size, "runs": runs, "median": median,
                          "ratio_to": base, "ratio": ratio}, args.out, "fill_speed",
                         "bench_fill.py")
    m = record["machine"]
    print(f"motorcycle at {args.size} px, {args.runs} interleaved runs each (median), "
          f"{m['cpu']}, {m['cores']} cores")
    for n in names:
        md = median[n]
        print(f"{n:12s} make {md['make_s']:.2f} s (inpaint {md['inpaint_s']:.2f} s, CPU time "
              f"{md['cpu_s']:.2f} s), {ratio[n]:.2f}x {base}, peak memory "
              f"{md['peak_rss_mb']:.0f} MB")


if __name__ == "__main__":
    main()
