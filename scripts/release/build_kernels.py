"""Build the numba caches the wheel ships: make's, render's and export's kernels
compiled for a portable x86-64 CPU (``photo3d.kernel_build``; ``photo3d.kernel_cache``
adopts them).

For each CPU name (``--cpu``, default ``generic``) and each Python (``--python``,
default this one), in fresh processes with ``NUMBA_CPU_NAME`` set, ``src/`` first on
the path and an empty ``NUMBA_CACHE_DIR``, it runs the default paths on the bundled
sample:

1. ``photo3d demo`` (``make``, its files and the four standard videos: ``render``'s
   kernels), with 8 frames a video (the kernels' argument types do not depend on it);
2. ``photo3d render`` of that folder (the command's own path);
3. ``photo3d export`` of every format whose extra is installed.

Then it runs the same three again with that cache: they must compile nothing (no
cache file written or changed), or the build fails: a kernel compiled on the default
path with types the first runs did not give it would compile on every user's first
run. Last, photo3d's cache files are copied into ``OUT`` with ``manifest.json``
(file and source hashes, numba's version, the sets): ``OUT`` is what the wheel holds
as ``photo3d/_kernel_cache`` (``setup.py``, with ``PHOTO3D_KERNEL_CACHE=OUT``).

Every Python must have photo3d's dependencies (with the ``sample`` extra) and the
same numba as this one: the wheel pins one numba version. ``--all-pythons`` adds one
set for each other ``python3.N`` (3.11 or later) on ``PATH``, each in a virtual
environment of its own under ``build/`` with those dependencies and this numba.

Usage: python scripts/release/build_kernels.py --out build/kernels [--cpu generic]
       [--python PY ...] [--all-pythons]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
sys.path.insert(0, str(SRC))
from photo3d.kernel_build import collect, write_manifest  # noqa: E402
from photo3d.kernel_cache import TARGETS  # noqa: E402

EXPORTS = {"splats.ply": None, "splats.spz": None, "splats.glb": None, "quilt": None,
           "mesh.usdz": "pxr"}
"""``photo3d export``'s formats and the module each needs beyond photo3d's own."""


def workload(python: str, work: Path) -> list[list[str]]:
    """The commands (argv after the interpreter) of the default paths."""
    out = work / "demo"
    formats = [f for f, module in EXPORTS.items()
               if module is None or _has(python, module)]
    return [["-m", "photo3d", "demo", "-o", str(out), "--overwrite", "-q", "--frames", "8"],
            ["-m", "photo3d", "render", str(out), "--frames", "8", "-q"],
            ["-m", "photo3d", "export", str(out), *formats, "-q"],
            # the colour fit's kernels (photo3d.export._spark_raster, _fit_kernels), also
            # in the default export above
            ["-m", "photo3d", "export", str(out), "splats.spz", "--splat-fit", "-q",
             "-o", str(work / "fitted.spz")]]


def _has(python: str, module: str) -> bool:
    return subprocess.run([python, "-c", f"import {module}"], capture_output=True).returncode == 0


def run(python: str, argv: list[str], *, cpu: str, cache: Path, cwd: Path) -> None:
    """``python argv`` with ``src/`` first on the path, numba compiling for ``cpu``
    into ``cache``; a failure ends the build with the child's output."""
    env = dict(os.environ, PYTHONPATH=str(SRC), NUMBA_CACHE_DIR=str(cache),
               NUMBA_CPU_NAME=cpu, NUMBA_CPU_FEATURES="", PHOTO3D_SHIPPED_KERNELS="0")
    started = time.perf_counter()
    done = subprocess.run([python, *argv], env=env, cwd=cwd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{python} {' '.join(argv)}: exit {done.returncode}\n"
                         f"{done.stdout}\n{done.stderr}")
    print(f"  {' '.join(argv[1:4])}: {time.perf_counter() - started:.1f} s", flush=True)


def snapshot(cache: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``cache``: (size, modification time in ns)."""
    return {str(p.relative_to(cache)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in cache.rglob("*") if p.is_file()}


def numba_version(python: str) -> str:
    return subprocess.run([python, "-c", "import numba; print(numba.__version__)"],
                          capture_output=True, text=True, check=True).stdout.strip()


def other_pythons() -> list[str]:
    """A Python of its own (a virtual environment under ``build/``, made here, with
    photo3d's dependencies and this numba) for each other ``python3.N`` (N >= 11) on
    ``PATH``."""
    import llvmlite
    import numba

    minors = set()
    for folder in os.environ.get("PATH", "").split(os.pathsep):
        for path in Path(folder).glob("python3.*") if Path(folder).is_dir() else ():
            match = re.fullmatch(r"python3\.(\d+)", path.name)
            if match and int(match[1]) >= 11 and int(match[1]) != sys.version_info[1]:
                minors.add(int(match[1]))
    pythons = []
    for minor in sorted(minors):
        venv = ROOT / "build" / f"venv-3.{minor}"
        python = venv / "bin" / "python"
        if not python.exists():
            if subprocess.run([f"python3.{minor}", "-c", ""], capture_output=True).returncode:
                continue  # a name that does not run (a pyenv shim of an inactive version)
            subprocess.run([f"python3.{minor}", "-m", "venv", str(venv)], check=True)
        subprocess.run([str(python), "-m", "pip", "install", "--quiet",
                        f"numba=={numba.__version__}", f"llvmlite=={llvmlite.__version__}",
                        "numpy>=1.26", "scipy>=1.11", "pillow>=10.0", "tqdm>=4.60", "av>=14",
                        "scikit-image>=0.22"], check=True)
        pythons.append(str(python))
    return pythons


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--cpu", action="append", choices=sorted(TARGETS),
                        help="a CPU name to build for (repeat; most capable first)")
    parser.add_argument("--python", action="append",
                        help="an interpreter to build with (repeat; default this one)")
    parser.add_argument("--all-pythons", action="store_true",
                        help="also every other python3.N (N >= 11) on PATH")
    args = parser.parse_args()
    cpus = args.cpu or ["generic"]
    pythons = args.python or [sys.executable]
    if args.all_pythons:
        pythons += other_pythons()
    import numba

    for python in pythons:
        if numba_version(python) != numba.__version__:
            raise SystemExit(f"{python}: numba {numba_version(python)}, not "
                             f"{numba.__version__}: the wheel pins one numba version")
    out = args.out.resolve()
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    work = Path(tempfile.mkdtemp(prefix="photo3d-kernels."))
    targets = []
    try:
        for cpu in cpus:
            raw = work / f"cache-{cpu}"
            for python in pythons:
                print(f"{cpu}, {python}: compiling", flush=True)
                for argv in workload(python, work):
                    run(python, argv, cpu=cpu, cache=raw, cwd=work)
                before = snapshot(raw)
                print(f"{cpu}, {python}: again, nothing may compile", flush=True)
                for argv in workload(python, work):
                    run(python, argv, cpu=cpu, cache=raw, cwd=work)
                after = snapshot(raw)
                changed = sorted(k for k in after if before.get(k) != after[k])
                if changed:
                    raise SystemExit(f"compiled again on the second run: {changed}")
            targets.append(collect(raw, out, SRC / "photo3d", cpu=cpu))
        manifest = write_manifest(out, targets, SRC / "photo3d")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    print(f"{out}: {sum(len(t['functions']) for t in targets)} functions from "
          f"{len(manifest['sources'])} sources, {len(manifest['files'])} files, "
          f"{size / 1e6:.1f} MB, numba {manifest['numba']}, {manifest['pythons']}")


if __name__ == "__main__":
    main()
