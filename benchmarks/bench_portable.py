"""What the wheel's portable kernels cost: make, render and export with the shipped
``generic`` x86-64 kernels against kernels compiled for this CPU, in the same run.

The wheel (``--wheel``, default the newest ``dist/photo3d-*.whl``) is installed into a
fresh virtual environment (``_wheel.py``; with the ``usdz`` extra when it installs).
One numba cache per kind, each warmed by one unmeasured run of every command:

* one per set the wheel ships (``generic``, and ``x86-64-v3`` if it has one): that
  set's kernels alone, adopted into an empty ``NUMBA_CACHE_DIR``
  (``PHOTO3D_SHIPPED_KERNELS=<cpu>``, ``photo3d.kernel_cache``);
* ``native``: ``PHOTO3D_SHIPPED_KERNELS=0``, the kernels compiled for this CPU into
  another ``NUMBA_CACHE_DIR`` (what a clone runs).

Then, ``--runs`` times, each command once with each cache, alternated: ``photo3d demo
--no-video`` (make: the sample to its files), ``photo3d render`` of that folder (one
240-frame 1280x720 video, ``--path circle``), ``photo3d export`` of every format.
Whole processes; medians of wall and CPU seconds and each set / native. The
machine may be shared: the CPU seconds compare best. Writes
``benchmarks/results/portable.json``.

Usage: python benchmarks/bench_portable.py [--runs 3] [--wheel PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import _wheel  # noqa: E402
from _machine import save_record, timed_python  # noqa: E402

FORMATS = ["splats.ply", "splats.spz", "splats.glb", "quilt"]


def commands(out: Path, usdz: bool) -> dict[str, list[str]]:
    """The three commands (argv after ``python``), by name."""
    return {"make": ["-m", "photo3d", "demo", "--no-video", "-o", str(out), "--overwrite", "-q"],
            "render": ["-m", "photo3d", "render", str(out), "--path", "circle", "-q"],
            "export": ["-m", "photo3d", "export", str(out), *FORMATS,
                       *(["mesh.usdz"] if usdz else []), "-q"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--wheel", type=Path, default=None)
    parser.add_argument("--commands", default="make,render,export",
                        help="the commands measured (comma-separated; make always runs once "
                             "first, for the folder the others read)")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "portable.json")
    args = parser.parse_args()
    wheel = _wheel.find_wheel(args.wheel)
    work = Path(tempfile.mkdtemp(prefix="bench_portable."))
    try:
        try:
            python = _wheel.fresh_venv(wheel, work / "venv", extras="sample,usdz")
            usdz = True
        except subprocess.CalledProcessError:
            shutil.rmtree(work / "venv", ignore_errors=True)
            python = _wheel.fresh_venv(wheel, work / "venv")
            usdz = False
        package = _wheel.installed_package(python)
        manifest = json.loads((package / "_kernel_cache" / "manifest.json").read_text())
        sets = [target["cpu"] for target in manifest["targets"]]
        kinds = {"native": {"NUMBA_CACHE_DIR": str(work / "native"),
                            "PHOTO3D_SHIPPED_KERNELS": "0"}}
        for cpu in sets:
            kinds[cpu] = {"NUMBA_CACHE_DIR": str(work / cpu), "PHOTO3D_SHIPPED_KERNELS": cpu}
        cmds = commands(work / "out", usdz)

        def timed(name: str, kind: str) -> dict:
            return timed_python(cmds[name], src=None, python=python,
                                env={"PYTHONPATH": "", **kinds[kind]})

        measured = args.commands.split(",")
        for kind in kinds:  # unmeasured: compiles (native) or adopts (a shipped set)
            for name in dict.fromkeys(["make", *measured]):
                timed(name, kind)
        times: dict[str, dict[str, list[float]]] = {}
        for run in range(args.runs):
            for name in measured:
                for kind in kinds:
                    result = timed(name, kind)
                    got = times.setdefault(f"{name} {kind}",
                                           {"wall_s": [], "cpu_s": [], "load": []})
                    got["wall_s"].append(result["wall_s"])
                    got["cpu_s"].append(result["cpu_s"])
                    got["load"].append(os.getloadavg()[0])
                    print(f"run {run + 1}: {name} {kind}: {result['wall_s']:.2f} s wall, "
                          f"{result['cpu_s']:.2f} s CPU (load {os.getloadavg()[0]:.1f})",
                          flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    med = {k: {m: statistics.median(v[m]) for m in v} for k, v in times.items()}
    rows = ["| command | " + " | ".join(["native (this CPU)", *sets]) + " | "
            + " | ".join(f"{cpu} / native, CPU (wall)" for cpu in sets) + " |",
            "| --- " * (2 + 2 * len(sets)) + "|"]
    cost: dict[str, dict[str, dict[str, float]]] = {}
    for name in measured:
        nat = med[f"{name} native"]
        cost[name] = {cpu: {m: med[f"{name} {cpu}"][m] / nat[m] for m in ("wall_s", "cpu_s")}
                      for cpu in sets}
        cells = [f"{med[f'{name} {k}']['wall_s']:.2f} s ({med[f'{name} {k}']['cpu_s']:.2f} s "
                 "CPU)" for k in kinds]
        ratios = [f"{cost[name][cpu]['cpu_s']:.3f}x ({cost[name][cpu]['wall_s']:.3f}x)"
                  for cpu in sets]
        rows.append(f"| {name} | " + " | ".join(cells + ratios) + " |")
    note = (f"\nWhole processes from the wheel `{wheel.name}` in a fresh venv, median of "
            f"{args.runs} runs per cell, the kinds alternated. make: `photo3d demo "
            "--no-video`; render: `photo3d render DIR --path circle` (240 frames, 1280x720); "
            f"export: `photo3d export DIR {' '.join(cmds['export'][4:-1])}`.")
    loads = [load for v in times.values() for load in v.get("load", [])]
    note += f" Load average (1 min) during the runs: {min(loads):.1f}-{max(loads):.1f}."
    record = {"wheel": wheel.name, "runs": args.runs, "times": times, "median": med,
              "set_over_native": cost, "usdz": usdz,
              "markdown": "\n".join(rows) + "\n" + note}
    save_record(record, args.out, "portable", "bench_portable.py")
    print("\n".join(rows) + "\n" + note)


if __name__ == "__main__":
    main()
