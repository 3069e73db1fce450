"""Benchmark ``photo3d export``: all five formats of the bundled sample's 3D photo.

The 3D photo is ``photo3d demo --no-video`` (the Middlebury motorcycle at 1024 px),
made once into ``--demo`` (default: a temporary folder). Each measured run exports
``splats.ply splats.spz splats.glb mesh.usdz quilt`` into a fresh copy of its
``photo3d.npz`` and ``config.json``, in a fresh process, two ways:

* ``call``: :func:`photo3d.export.export_folder` timed inside the process (wall and
  CPU seconds of the call, all threads: ``time.process_time``), imports excluded
  but usd-core's first import, which happens inside the call, included;
* ``command``: the whole ``python -m photo3d export FOLDER FORMATS -q`` process
  (wall seconds, and CPU seconds of the process: ``os.wait4``'s user + system).

Two versions of the code run in the same session, alternated: ``now``, this working
tree's ``src/`` (copied into a temporary folder first, so edits made while the
benchmark runs do not mix in), and, with ``--ref DIR``, another ``src/`` folder (e.g.
``git archive HEAD src | tar -x -C /tmp/ref`` gives ``/tmp/ref/src``). One unmeasured
run of each version first (numba's cache, beside the copied sources); then
``--runs`` rounds; medians. The 1-minute load average is recorded before every run:
the machine is shared, and its load shows in wall times, far less in CPU times.
``--no-fit-too`` also measures ``now`` with ``--no-splat-fit`` (``now-nofit``).
Issue 37's target: the call at most 5 s, the command at most 8 s, on 2 cores; issue
46's: the command within the reference's time (e951c93: 2.65 s on an idle machine) and
its peak resident memory within what it states before it starts
(:func:`photo3d.resources.export_memory_estimate`, recorded as ``stated_mb``).
Writes ``benchmarks/results/export.json``.

Usage: python benchmarks/bench_export.py [--runs 3] [--demo DIR] [--ref SRC_DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record, timed_python  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FORMATS = ["splats.ply", "splats.spz", "splats.glb", "mesh.usdz", "quilt"]
TIMEOUT = 600
"""Seconds after which a run is taken for hung."""
CALL = """
import json, sys, time
from photo3d.export import export_folder
wall, cpu = time.perf_counter(), time.process_time()
options = {} if sys.argv[2] == "default" else {"splat_fit": False}
written = export_folder(sys.argv[1], sys.argv[3:], **options)
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
from photo3d.export.splats import splat_count
print(json.dumps({"wall": wall, "cpu": cpu,
                  "files": {p.name: p.stat().st_size for p in written},
                  "splats": {p.name: splat_count(p) for p in written
                             if splat_count(p) is not None}}))
"""


def run_measured(src: Path, argv: list[str]) -> tuple[float, float, str, float] | None:
    """``python argv`` with ``src`` first on the path: (wall seconds, CPU seconds of
    the whole process from ``os.wait4``, its stdout, its peak resident MB); None if it
    was still running after :data:`TIMEOUT` seconds (a deadlock, not a slow run: it is
    killed)."""
    run = timed_python(argv, src=src, timeout=TIMEOUT)
    return None if run is None else (run["wall_s"], run["cpu_s"], run["stdout"],
                                     run["peak_rss_mb"])


def fresh(demo: Path, work: Path, name: str) -> Path:
    """A new folder holding the demo's ``photo3d.npz`` and ``config.json``."""
    folder = work / name
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    for file in ("photo3d.npz", "config.json"):
        shutil.copy2(demo / file, folder / file)
    return folder


def measure(src: Path, demo: Path, work: Path, kind: str, *, fit: bool = True) -> dict:
    """One run of ``kind`` (``call`` or ``command``) with ``src``; ``fit``: its
    default splat colours (False: ``--no-splat-fit``)."""
    folder = fresh(demo, work, "out")
    load = os.getloadavg()[0]
    argv = (["-c", CALL, str(folder), "default" if fit else "nofit", *FORMATS]
            if kind == "call" else ["-m", "photo3d", "export", str(folder), *FORMATS, "-q"]
            + ([] if fit else ["--no-splat-fit"]))
    done = run_measured(src, argv)
    if done is None:
        return {"load": load, "hung": True}
    wall, cpu, out, peak = done
    if kind == "call":
        inside = json.loads(out.strip().splitlines()[-1])
        return {"load": load, "wall": inside["wall"], "cpu": inside["cpu"],
                "process_wall": wall, "process_cpu": cpu, "files": inside["files"],
                "splats": inside.get("splats", {}), "peak_rss_mb": peak}
    return {"load": load, "wall": wall, "cpu": cpu, "peak_rss_mb": peak}


def stated_mb(src: Path, demo: Path) -> float:
    """The memory ``photo3d export`` (the ``src`` version) states it needs for the five
    formats of ``demo`` before it starts, MB."""
    code = ("import sys; from photo3d.io.npz import ldi_pixels; "
            "from photo3d.resources import export_memory_estimate; "
            "print(export_memory_estimate(ldi_pixels(sys.argv[1]), sys.argv[2:], "
            "splat_fit=True) / 1e6)")
    run = timed_python(["-c", code, str(demo / "photo3d.npz"), *FORMATS], src=src)
    return float(run["stdout"].strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--demo", type=Path, help="the demo's folder (made if missing)")
    parser.add_argument("--ref", type=Path, help="a src/ folder of the reference version")
    parser.add_argument("--no-fit-too", action="store_true",
                        help="also measure this version with --no-splat-fit ('now-nofit')")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/export.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-export-") as tmp:
        work = Path(tmp)
        versions = {"now": work / "now" / "src"}
        shutil.copytree(ROOT / "src", versions["now"],
                        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        if args.ref is not None:
            versions["ref"] = work / "ref" / "src"
            shutil.copytree(args.ref, versions["ref"],
                            ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        demo = args.demo or work / "demo"
        if not (demo / "photo3d.npz").is_file():
            print(f"making the demo into {demo} ...", flush=True)
            run_measured(versions["now"], ["-m", "photo3d", "demo", "--no-video", "-q",
                                           "-o", str(demo)])
        stated = stated_mb(versions["now"], demo)  # while the copied sources exist
        fits = dict.fromkeys(versions, True)
        if args.no_fit_too:
            versions["now-nofit"], fits["now-nofit"] = versions["now"], False
        for name, src in versions.items():  # warm-up: numba's cache, the page cache
            measure(src, demo, work, "call", fit=fits[name])
        runs: dict[str, dict[str, list]] = {v: {"call": [], "command": []} for v in versions}
        for i in range(args.runs):
            for kind in ("call", "command"):
                for name, src in versions.items():
                    result = measure(src, demo, work, kind, fit=fits[name])
                    runs[name][kind].append(result)
                    if result.get("hung"):
                        print(f"run {i + 1} {name:3s} {kind:7s} HUNG (killed after "
                              f"{TIMEOUT} s)  load {result['load']:.2f}", flush=True)
                        continue
                    print(f"run {i + 1} {name:9s} {kind:7s} wall {result['wall']:6.2f} s  "
                          f"cpu {result['cpu']:6.2f} s  load {result['load']:.2f}", flush=True)
    medians = {name: {kind: {key: statistics.median(r[key] for r in results if "wall" in r)
                             for key in ("wall", "cpu", "load")}
                      | {"hung": sum("hung" in r for r in results)}
                      for kind, results in kinds.items()}
               for name, kinds in runs.items()}
    print(f"\nmedians of {args.runs} (1-minute load average before each run):")
    for name, kinds in medians.items():
        for kind, m in kinds.items():
            print(f"  {name:9s} {kind:7s} wall {m['wall']:6.2f} s  cpu {m['cpu']:6.2f} s  "
                  f"load {m['load']:.2f}" + (f"  ({m['hung']} hung)" if m["hung"] else ""))
    if "ref" in medians:
        for kind in ("call", "command"):
            ratio = {k: medians["now"][kind][k] / medians["ref"][kind][k] for k in ("wall", "cpu")}
            print(f"  now/ref {kind:7s} wall {ratio['wall']:.2f}  cpu {ratio['cpu']:.2f}")
    files = next(r["files"] for r in runs["now"]["call"] if "files" in r)
    peaks = {name: max(r.get("peak_rss_mb", 0) for rs in kinds.values() for r in rs)
             for name, kinds in runs.items()}
    print("  peak resident memory: " + ", ".join(f"{k} {v:.0f} MB" for k, v in peaks.items())
          + f"; stated before the export (now): {stated:.0f} MB")
    record = {"formats": FORMATS, "runs": runs, "medians": medians,
              "files_mb": {k: round(v / 1e6, 2) for k, v in files.items()},
              "splats": {name: next((r["splats"] for r in kinds["call"] if "splats" in r), {})
                         for name, kinds in runs.items()},
              "peak_rss_mb": peaks, "stated_mb": stated,
              "target": {"call_wall_s": 5.0, "command_wall_s": 8.0,
                         "issue46_command_wall_s": 2.65},
              "ref": str(args.ref) if args.ref else None}
    save_record(record, args.out, "export", "bench_export.py")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
