"""The first run: ``photo3d demo --no-video`` with an empty numba cache against a warm one.

numba compiles photo3d's kernels on first use and caches them on disk, so the very
first run of an installation pays for compiling. This times that first run, whole
process (``python -m photo3d demo --no-video -o TMP --overwrite -q``: start-up,
compiling, the 3D photo, its files), against the same command with a warm cache, for
two versions of the code in the same session:

* ``now``: this working tree's ``src/`` (copied into a temporary folder first, so
  edits made while the benchmark runs do not mix in);
* ``ref``: ``--ref`` (default ``HEAD``), ``git archive``'d into a temporary folder.

Each version runs with ``PYTHONPATH`` set to its own copy and its own
``NUMBA_CACHE_DIR``: a new empty folder for every *cold* run, one folder warmed by an
unmeasured run first for the *warm* runs (so the caches in ``src/**/__pycache__`` are
never read nor written). The four kinds (ref cold, now cold, ref warm, now warm) are
alternated ``--runs`` times; medians of wall seconds and of the child's CPU seconds
(user + system, all threads). The cold/warm ratio of each version is the target
(issue 35: at most 2x).

With ``--wheel`` (a path, or ``auto``: the newest ``dist/photo3d-*.whl`` of ``make
wheel``) a third version runs beside them, the wheel path (issue 47: cold at most
1.5x warm): the wheel installed with its ``sample`` extra into a fresh virtual
environment (``_wheel.py``), no source tree, run as a user who cannot write into it
(``nobody`` via ``setpriv`` when run as root), numba's cache where numba puts it
then (``$XDG_CACHE_HOME/numba``; cold: a new empty ``XDG_CACHE_HOME`` per run). It
checks that no run wrote a cache file into the installed package, and that a cold
run without ``-q`` shows no "compiling, once" step. Writes
``benchmarks/results/first_run.json``.

Usage: python benchmarks/bench_first_run.py [--runs 3] [--ref HEAD|none]
       [--wheel auto|PATH [--no-clone]]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import _wheel  # noqa: E402
from _machine import git_src, save_record, timed_python  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
COMMAND = ["-m", "photo3d", "demo", "--no-video", "--overwrite", "-q"]


def timed(src: Path, cache: Path, out: Path) -> tuple[float, float]:
    """Run :data:`COMMAND` with ``src`` first on the path and numba's cache in
    ``cache``; (wall seconds, CPU seconds) of the whole child process."""
    # the compile step's helper processes are children of the child: counted too
    result = timed_python([*COMMAND, "-o", str(out)], src=src, cache=cache)
    return result["wall_s"], result["cpu_s"]


class WheelPath:
    """The wheel installed into a fresh environment (:mod:`_wheel`), run as a user who
    cannot write into it."""

    def __init__(self, wheel: Path, work: Path) -> None:
        self.wheel = _wheel.find_wheel(None if str(wheel) == "auto" else wheel)
        self.work = work
        work.parent.chmod(0o755)  # mkdtemp's 0700 would keep the user out of the venv
        self.python = _wheel.fresh_venv(self.wheel, work / "venv")
        self.package = _wheel.installed_package(self.python)
        self.prefix = _wheel.as_user(self.package)
        self.before = _wheel.cache_files(self.package)

    def timed(self, home: Path, out: Path, *, quiet: bool = True) -> tuple[float, float, str]:
        """:data:`COMMAND` with ``home`` as the user's home and cache folder: (wall
        seconds, CPU seconds, what it printed on stderr)."""
        # photo3d stages its output beside the folder: the user must own the parent
        out = _wheel.user_folder(out) / "demo"
        command = COMMAND if quiet else [c for c in COMMAND if c != "-q"]
        result = timed_python([*command, "-o", str(out)], src=None, python=self.python,
                              env=_wheel.user_env(home), prefix=self.prefix)
        return result["wall_s"], result["cpu_s"], result.get("stderr", "")

    def wrote_into_package(self) -> list[str]:
        """Cache files runs wrote into the installed package (none may)."""
        return sorted(_wheel.cache_files(self.package) - self.before)


def which_photo3d(src: Path) -> str:
    """The file ``import photo3d`` finds with ``src`` on PYTHONPATH (a check that the
    version under test is the one running, not the editable install)."""
    out = subprocess.run([sys.executable, "-c", "import photo3d; print(photo3d.__file__)"],
                         env=dict(os.environ, PYTHONPATH=str(src)), capture_output=True,
                         text=True, check=True)
    return out.stdout.strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--ref", default="HEAD",
                        help="the reference commit ('none': this tree alone)")
    parser.add_argument("--no-clone", action="store_true",
                        help="the wheel path alone (with --wheel)")
    parser.add_argument("--wheel", type=Path, default=None,
                        help="also the wheel path: a wheel, or 'auto' (newest in dist/)")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "first_run.json")
    args = parser.parse_args()
    ref_commit = None if args.ref == "none" else subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", args.ref],
        capture_output=True, text=True, check=True).stdout.strip()
    work = Path(tempfile.mkdtemp(prefix="bench_first_run."))
    try:
        srcs = {"ref": work / "ref", "now": work / "now"}
        if ref_commit is None or args.no_clone:
            del srcs["ref"]
        else:
            git_src(args.ref, srcs["ref"])
        if args.no_clone:
            del srcs["now"]
        else:
            shutil.copytree(ROOT / "src", srcs["now"] / "src",
                            ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        for version, folder in srcs.items():
            srcs[version] = folder / "src"
            found = which_photo3d(srcs[version])
            if not found.startswith(str(srcs[version])):
                raise SystemExit(f"{version}: photo3d imported from {found}")
        wheel = WheelPath(args.wheel, work / "wheel") if args.wheel is not None else None
        checks: dict[str, object] = {}
        if wheel is not None:  # unmeasured: a cold run that shows its progress bar
            _, _, stderr = wheel.timed(_wheel.user_folder(work / "home-shown"), work / "out-w",
                                       quiet=False)
            checks["compile_step_shown"] = "compiling" in stderr
            print(f"wheel {wheel.wheel.name}: a cold run shows 'compiling, once': "
                  f"{checks['compile_step_shown']}", flush=True)
            wheel.timed(_wheel.user_folder(work / "home-warm"), work / "out-w")
        times: dict[str, dict[str, list[float]]] = {}
        for version, src in srcs.items():  # unmeasured: fills each version's warm cache
            timed(src, work / f"cache-{version}-warm", work / "out")
        versions = [*srcs, *(["wheel"] if wheel is not None else [])]
        for run in range(args.runs):
            for mode in ("cold", "warm"):
                for version in versions:
                    if version == "wheel":
                        home = (_wheel.user_folder(work / f"home-cold{run}") if mode == "cold"
                                else work / "home-warm")
                        wall, cpu, _ = wheel.timed(home, work / "out-w")
                        if mode == "cold":
                            shutil.rmtree(home, ignore_errors=True)
                    else:
                        cache = work / (f"cache-{version}-cold{run}" if mode == "cold"
                                        else f"cache-{version}-warm")
                        wall, cpu = timed(srcs[version], cache, work / "out")
                        if mode == "cold":
                            shutil.rmtree(cache, ignore_errors=True)
                    got = times.setdefault(f"{version} {mode}",
                                           {"wall_s": [], "cpu_s": [], "load": []})
                    got["wall_s"].append(wall)
                    got["cpu_s"].append(cpu)
                    got["load"].append(os.getloadavg()[0])
                    print(f"run {run + 1}: {version} {mode}: {wall:.1f} s wall, {cpu:.1f} s CPU"
                          f" (load {os.getloadavg()[0]:.1f})", flush=True)
        if wheel is not None:
            checks["written_into_site_packages"] = wheel.wrote_into_package()
            checks["wheel"] = wheel.wheel.name
            checks["run_as"] = "nobody (setpriv)" if wheel.prefix else "read-only folders"
    finally:
        shutil.rmtree(work, ignore_errors=True)
    med = {k: {m: statistics.median(v[m]) for m in v} for k, v in times.items()}
    ratio = {v: {m: med[f"{v} cold"][m] / med[f"{v} warm"][m] for m in ("wall_s", "cpu_s")}
             for v in versions}
    rows = ["| version | cold (empty numba cache) | warm | cold / warm | cold / warm, CPU |",
            "| --- | --- | --- | --- | --- |"]
    labels = [(v, label) for v, label in (("ref", f"clone, before (`{ref_commit}`)"),
                                          ("now", "clone, now")) if v in srcs]
    if wheel is not None:
        labels.append(("wheel", f"wheel (`{wheel.wheel.name}`, fresh venv, read-only)"))
    for version, label in labels:
        cold, warm = med[f"{version} cold"], med[f"{version} warm"]
        rows.append(f"| {label} | {cold['wall_s']:.1f} s ({cold['cpu_s']:.1f} s CPU) | "
                    f"{warm['wall_s']:.1f} s ({warm['cpu_s']:.1f} s CPU) | "
                    f"{ratio[version]['wall_s']:.2f}x | {ratio[version]['cpu_s']:.2f}x |")
    note = (f"\n`photo3d demo --no-video`, whole process, median of {args.runs} runs per "
            "cell, the kinds alternated; clone cold: a new empty `NUMBA_CACHE_DIR` per run. ")
    if "ref" in srcs:
        speed = {m: med[f"now {m}"]["wall_s"] / med[f"ref {m}"]["wall_s"]
                 for m in ("cold", "warm")}
        note += (f"Now against before: cold {speed['cold']:.2f}x, warm {speed['warm']:.2f}x. ")
    loads = [load for v in times.values() for load in v.get("load", [])]
    note += (f"Load average (1 min) during the runs: {min(loads):.1f}-{max(loads):.1f}. The "
             "machine (2 cores) may be shared with other jobs: compare the ratios (on a busy "
             "machine the CPU seconds, which its load does not stretch).")
    if wheel is not None:
        note += (f" Wheel: installed into a fresh venv, run as {checks['run_as']}; cold: a new "
                 "empty user cache (`XDG_CACHE_HOME`) per run, so the shipped kernels are "
                 "copied into it first. A cold run printed 'compiling, once': "
                 f"{'yes' if checks['compile_step_shown'] else 'no'}; cache files written "
                 f"into site-packages: {len(checks['written_into_site_packages'])}.")
    record = {"ref": ref_commit, "runs": args.runs, "timed": " ".join(["python", *COMMAND]),
              "times": times, "median": med, "cold_over_warm": ratio, "checks": checks,
              "markdown": "\n".join(rows) + "\n" + note}
    save_record(record, args.out, "first_run", "bench_first_run.py")
    print("\n".join(rows) + "\n" + note)


if __name__ == "__main__":
    main()
