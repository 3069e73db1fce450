"""Benchmark ``photo3d.make`` on the Middlebury motorcycle pair (diffusion backend).

Each run is a fresh process (``_make_child.py``; numba's on-disk cache is warmed
first, so no run pays for compilation); the time is measured around ``photo3d.make``
only, then ``Photo3D.mesh()`` is timed; the peak memory is the child's peak resident
set size. Prints a table and writes ``benchmarks/results/make.json``.

Usage: python benchmarks/bench_make.py [--runs 5] [--size 1024] [--inpainter diffusion]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info, run_make  # noqa: E402


def run_once(size: int, inpainter: str) -> dict:
    return run_make(size, "--inpainter", inpainter, "--mesh")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--inpainter", default="diffusion")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "make.json")
    args = parser.parse_args()

    run_once(args.size, args.inpainter)  # warm-up: fills numba's cache, page cache
    runs = [run_once(args.size, args.inpainter) for _ in range(args.runs)]
    med = {
        "make_s": statistics.median(r["make_s"] for r in runs),
        "mesh_s": statistics.median(r["mesh_s"] for r in runs),
        "peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
        "stages": {k: statistics.median(r["stages"][k] for r in runs)
                   for k in runs[0]["stages"]},
    }
    record = {"benchmark": "make", "size": args.size, "inpainter": args.inpainter,
              "runs": runs, "median": med, "machine": machine_info(),
              "command": " ".join(["python", "benchmarks/bench_make.py", *sys.argv[1:]])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))
    stats = runs[0]["stats"]
    print(f"motorcycle {stats['working_size'][0]}x{stats['working_size'][1]}, "
          f"inpainter {args.inpainter}, {args.runs} runs (median), {record['machine']['cpu']}, "
          f"{record['machine']['cores']} cores")
    print(f"make: {med['make_s']:.2f} s  (" + ", ".join(
        f"{k} {v:.2f}" for k, v in med["stages"].items()) + ")")
    print(f"mesh: {med['mesh_s']:.2f} s, {runs[0]['faces']:,} faces, "
          f"{runs[0]['ldi_pixels']:,} LDI pixels, passes {stats['passes']}, "
          f"edges per pass {stats['edges']}")
    print(f"peak memory (whole process): {med['peak_rss_mb']:.0f} MB")
    times = ", ".join(f"{r['make_s']:.2f}" for r in runs)
    print(f"individual make times: {times}")


if __name__ == "__main__":
    main()
