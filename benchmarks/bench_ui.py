"""``photo3d ui``: one request (the bundled sample's 1024 px photo and its depth, one
video) end to end after the warm-up, against the previous commit in the same session.

Two versions of the code, each run with ``PYTHONPATH`` set to its own copy and its own
``NUMBA_CACHE_DIR`` (warmed by an unmeasured request first), as
``benchmarks/bench_video.py`` does:

* ``now``: this working tree's ``src/``, copied into a temporary folder first;
* ``ref``: ``--ref`` (default ``HEAD``), ``git archive``'d into a temporary folder.

Each measured run is a fresh process that starts the UI's warm-up
(:class:`photo3d.ui.warmup.Warmup`), waits for it to finish (its seconds are
recorded, not counted), then answers one request with
:func:`photo3d.ui.job.run_job`, what the page and the HTTP API call (the server's
Gradio layer around it is not timed): the sample as ``sample.png`` and its
ground-truth disparity as ``sample.pfm``, the request's defaults (1024 px, the
structured fill, ``splats.spz``, one ``circle`` video at the photo's size). Timed:
wall seconds of the request (first result, and the last one with its video), the
process's CPU seconds during it (user + system, all threads), and the seconds of
each stage the progress reports (``depth``, ..., ``video``, ``zip``). The two
versions alternate ``--runs`` times; medians; the 1-minute load average before and
after each run is recorded. Writes ``benchmarks/results/ui.json``.

Usage: python benchmarks/bench_ui.py [--runs 3] [--ref HEAD]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402
from bench_video import copy_sources, run  # noqa: E402

CHILD = r"""
import json, os, resource, sys, time
from pathlib import Path
import numpy as np
from photo3d.io.depth import write_pfm
from photo3d.io.images import write_image
from photo3d.sample import motorcycle
from photo3d.ui.job import JobOptions, run_job
from photo3d.ui.warmup import Warmup

tmp = Path(sys.argv[1])
sample = motorcycle()
write_image(tmp / "sample.png", sample.left)
write_pfm(tmp / "sample.pfm", np.asarray(sample.disparity))
start = time.perf_counter()
warm = Warmup(tmp / "warm")
(tmp / "warm").mkdir()
warm.start()
warm.wait()
warm_s = time.perf_counter() - start
if warm.error:
    raise SystemExit(f"warm-up failed: {warm.error}")
stages, last = {}, ["start", time.perf_counter()]

def progress(fraction, label):
    now = time.perf_counter()
    if label != last[0]:
        stages[last[0]] = stages.get(last[0], 0.0) + now - last[1]
        last[:] = [label, now]

def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime

folder = tmp / "request"
folder.mkdir()
c0, t0 = cpu(), time.perf_counter()
results = []
for result in run_job(tmp / "sample.png", folder, options=JobOptions(),
                      depth=tmp / "sample.pfm", name="sample", progress=progress):
    results.append(time.perf_counter() - t0)
wall, used = time.perf_counter() - t0, cpu() - c0
stages[last[0]] = stages.get(last[0], 0.0) + time.perf_counter() - last[1]
print(json.dumps({"warmup_s": warm_s, "first_result_s": results[0], "wall_s": wall,
                  "cpu_s": used, "stages_s": stages, "videos": len(result.videos),
                  "size": list(result.size)}))
"""


def request(src: Path, cache: Path, tmp: Path) -> dict:
    """One warm-up and one request in a fresh process: its own numbers (``run``'s
    wall and CPU are the whole process's, warm-up included, and are dropped)."""
    tmp.mkdir()
    record = run(src, cache, ["-c", CHILD, str(tmp)])
    child = json.loads(record["stdout"].strip().splitlines()[-1])
    return {**child, "load_1min": record["load_1min"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--ref", default="HEAD")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "ui.json")
    args = parser.parse_args()
    runs: dict[str, list[dict]] = {"ref": [], "now": []}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        srcs = copy_sources(tmp, args.ref)
        caches = {kind: tmp / f"cache_{kind}" for kind in srcs}
        for kind in ("ref", "now"):  # numba compiles into each cache, unmeasured
            request(srcs[kind], caches[kind], tmp / f"first_{kind}")
        for i in range(args.runs):
            for kind in ("ref", "now"):
                runs[kind].append(request(srcs[kind], caches[kind], tmp / f"{kind}_{i}"))
    medians = {kind: {key: statistics.median(r[key] for r in rs)
                      for key in ("wall_s", "cpu_s", "first_result_s", "warmup_s")}
               for kind, rs in runs.items()}
    stages = {kind: {s: statistics.median(r["stages_s"].get(s, 0.0) for r in rs)
                     for s in rs[0]["stages_s"]} for kind, rs in runs.items()}
    record = {"runs": runs, "median": medians, "median_stages_s": stages, "ref": args.ref,
              "ratio": medians["now"]["wall_s"] / medians["ref"]["wall_s"]}
    save_record(record, args.out, "ui", "bench_ui.py")
    loads = [v for rs in runs.values() for r in rs for v in r["load_1min"]]
    print(f"1-minute load average during the runs: {min(loads):.1f}-{max(loads):.1f} "
          f"(machine: {record['machine']['cpu']}, {record['machine']['cores']} cores)")
    for kind in ("ref", "now"):
        m = medians[kind]
        print(f"{kind}: request {m['wall_s']:.2f} s ({m['cpu_s']:.1f} s CPU; 3D photo shown "
              f"after {m['first_result_s']:.2f} s; warm-up {m['warmup_s']:.1f} s), walls "
              f"{[round(r['wall_s'], 2) for r in runs[kind]]}")
        print("  stages: " + ", ".join(f"{s} {t:.2f}" for s, t in stages[kind].items()))
    print(f"now/ref {record['ratio']:.3f} (median of {args.runs})")


if __name__ == "__main__":
    main()
