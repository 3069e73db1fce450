"""The save step of ``make`` alone: ``photo3d.npz``, ``mesh.ply``, ``mesh.glb`` (the light
textured mesh) and ``viewer.html`` of the bundled sample, against a previous commit.

Each version runs in its own fresh process (``PYTHONPATH`` its ``src/``; the
previous commit ``git archive``'d into a temporary folder), which loads the kernels,
reads the sample's 3D photo (made once by this tree: both versions save the same
LDI) and saves it ``--saves`` times after one unmeasured save: wall, user and
system CPU seconds of the process (``getrusage``: all threads) per save, and for
the last save a timeline of its parts per thread (start, end, thread CPU of each
call). The two versions alternate ``--runs`` times; medians. The light mesh is
compared too: ``identical`` is True when both versions give the same faces, texture
coordinates and texture. Writes ``benchmarks/results/save.json`` (``save_raw.json``).

Usage: python benchmarks/bench_save.py [--runs 3] [--saves 3] [--ref HEAD] [--raw]
(``--raw``: the motorcycle's raw disparity, unknown = 0, instead of the sample's)
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import START_ENV, git_src, save_record  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

CHILD = r"""
import json, os, resource, sys, tempfile, threading, time
import numpy as np
import photo3d
from photo3d.kernels import compile_kernels
import photo3d.mesh._simplify as simplify, photo3d.mesh.light as light
import photo3d.output as output, photo3d.viewer as viewer

compile_kernels(helper=False)
photo = photo3d.load(sys.argv[1])
events, t0 = [], [0.0]

def timed(module, name):
    f = getattr(module, name)
    def call(*a, **k):
        s, c = time.perf_counter(), time.thread_time()
        r = f(*a, **k)
        events.append([name, threading.current_thread().name, round(s - t0[0], 4),
                       round(time.perf_counter() - t0[0], 4), round(time.thread_time() - c, 4)])
        return r
    setattr(module, name, call)

for name in ("save_npz", "write_ply", "write_textured_glb", "build_light_mesh"):
    timed(output, name)
for name in ("_merge_planar", "chart_vertices", "_texture"):
    timed(light, name)
timed(simplify, "collapse_part")
timed(viewer, "write_viewer")
saves = []
for i in range(int(sys.argv[2]) + 1):
    events.clear()
    out = os.path.join(tempfile.mkdtemp(), "o")
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    t0[0] = time.perf_counter()
    output.save_photo(photo, out)
    wall = time.perf_counter() - t0[0]
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    if i:  # the first save is a warm-up
        saves.append({"wall_s": wall, "user_s": r1.ru_utime - r0.ru_utime,
                      "sys_s": r1.ru_stime - r0.ru_stime})
timeline = sorted(events, key=lambda e: e[2])  # of the last save
mesh = photo.light_mesh()
np.savez(sys.argv[3], faces=mesh.faces, uv=mesh.uv, texture=mesh.texture)
print(json.dumps({"saves": saves, "timeline": timeline}))
"""


def run(src: Path, folder: Path, saves: int, mesh_file: Path) -> dict:
    env = {**START_ENV, "PYTHONPATH": str(src)}
    out = subprocess.run([sys.executable, "-c", CHILD, str(folder), str(saves), str(mesh_file)],
                         capture_output=True, text=True, check=True, env=env)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result["load_1min"] = os.getloadavg()[0]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--saves", type=int, default=3, help="measured saves per process")
    parser.add_argument("--ref", default="HEAD", help="the commit to compare with")
    parser.add_argument("--raw", action="store_true", help="the raw disparity (unknown = 0)")
    parser.add_argument("--out", type=Path, help="default: benchmarks/results/save.json "
                        "(save_raw.json with --raw)")
    args = parser.parse_args()
    args.out = args.out or ROOT / "benchmarks" / "results" / (
        "save_raw.json" if args.raw else "save.json")
    import numpy as np

    with tempfile.TemporaryDirectory(prefix="bench_save_") as tmp:
        tmp = Path(tmp)
        folder = tmp / "photo"
        make = [sys.executable, "-m", "photo3d", "demo", "--no-video", "-o", str(folder), "-q"]
        if args.raw:
            from bench_hard_depth import write_inputs

            image, depth = write_inputs(tmp)["raw"]
            make = [sys.executable, "-m", "photo3d", "make", str(image), "--depth", str(depth),
                    "--no-video", "-o", str(folder), "-q"]
        subprocess.run(make, check=True, env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
        trees = {"previous": git_src(args.ref, tmp / "ref"), "now": ROOT / "src"}
        runs: dict[str, list[dict]] = {name: [] for name in trees}
        for i in range(args.runs):
            for name, src in trees.items():
                r = run(src, folder, args.saves, tmp / f"{name}.npz")
                runs[name].append(r)
                print(f"{name:8s} run {i + 1}: " + ", ".join(
                    f"{s['wall_s']:.2f} s ({s['user_s']:.2f} + {s['sys_s']:.2f} CPU)"
                    for s in r["saves"]) + f", load {r['load_1min']:.1f}")
        a, b = (np.load(tmp / f"{name}.npz") for name in trees)
        identical = all(np.array_equal(a[k], b[k]) for k in ("faces", "uv", "texture"))
    median = {name: {key: statistics.median(s[key] for r in rs for s in r["saves"])
                     for key in ("wall_s", "user_s", "sys_s")} for name, rs in runs.items()}
    record = {"ref": args.ref, "input": "raw" if args.raw else "sample", "median": median,
              "identical": identical, "runs": runs}
    save_record(record, args.out, "save", "bench_save.py")
    print(f"\nthe save step, medians of {args.runs} x {args.saves} saves; light mesh "
          f"identical: {identical}")
    for name, m in median.items():
        print(f"{name:8s} {m['wall_s']:.2f} s wall, {m['user_s']:.2f} s user, "
              f"{m['sys_s']:.2f} s system")
    print("\ntimeline of the last save (now): part, thread, start, end, thread CPU (s)")
    for part, thread, start, end, cpu in runs["now"][-1]["timeline"]:
        print(f"  {part:20s} {thread[-12:]:>12s} {start:6.3f} {end:6.3f} {cpu:6.3f}")


if __name__ == "__main__":
    main()
