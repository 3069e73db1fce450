"""Machine facts recorded with every benchmark result."""

from __future__ import annotations

import os
import platform
from importlib import metadata
from pathlib import Path

# The environment before this benchmark imports photo3d, which sets variables for its
# own process (``GOMP_SPINCOUNT``, ``NUMPY_MADVISE_HUGEPAGE``): the child processes of
# both trees start from this one, so an older tree runs with its own settings.
# Python writes bytecode caches (``__pycache__``) in the children, as an installed
# photo3d has them (pip compiles them at install, an editable install writes them on
# first import): a shell with ``PYTHONDONTWRITEBYTECODE`` set (this machine's) would
# make every child compile photo3d's ~90 modules from source, 0.07 s a run.
START_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def machine_info() -> dict:
    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        with open("/proc/meminfo") as f:
            mem_gb = int(f.readline().split()[1]) / 1024**2
    except OSError:
        mem_gb = float("nan")
    versions = {}
    for pkg in ("photo3d", "numpy", "scipy", "numba", "pillow"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    if hasattr(os, "sched_getaffinity"):
        cores = len(os.sched_getaffinity(0))
    else:
        cores = os.cpu_count()
    return {
        "cpu": cpu,
        "cores": cores,
        "memory_gb": round(mem_gb, 1),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "versions": versions,
    }


def run_child(code: str, *args) -> dict:
    """Run ``python -c code args`` in a fresh process and return the JSON object it
    prints last. Unless the child reports its own ``peak_rss_mb``, that is the peak
    resident set size of the children so far (``RUSAGE_CHILDREN``: the largest of the
    runs, which is what the benchmarks report)."""
    return _run_json(["-c", code, *map(str, args)])


STEP_TIMERS = r"""
def step_timers(clock):
    spent = {}

    def timed(module, name, step):  # module.name's calls add their clock() time to spent[step]
        fn = getattr(module, name, None)
        if fn is None:  # not in this version of the code
            return

        def wrapper(*args, **kwargs):
            t = clock()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[step] = spent.get(step, 0.0) + clock() - t

        setattr(module, name, wrapper)

    return spent, timed
"""
"""Child-program source shared by the per-step render benchmarks: ``spent, timed =
step_timers(clock)``; ``timed(module, name, step)`` wraps ``module.name`` so each call
adds its ``clock()`` seconds to ``spent[step]`` (names a version lacks are skipped)."""


MAKE_CHILD = Path(__file__).with_name("_make_child.py")
"""The child program of every ``make`` timer (one timed ``photo3d.make`` of the
motorcycle sample, JSON on stdout; its docstring lists the fields)."""


def run_make(size: int, *options: str) -> dict:
    """Run :data:`MAKE_CHILD` at working size ``size`` with ``options`` (its flags:
    ``--inpainter NAME``, ``--weights DIR`` or ``--random-nets``, ``--mesh``) in a
    fresh process and return its JSON object (times, stages, stats, its own peak
    resident set size)."""
    return _run_json([str(MAKE_CHILD), str(size), *options])


def _run_json(argv: list[str]) -> dict:
    """``python argv`` in a fresh process; the JSON object it prints last."""
    import json
    import resource
    import subprocess
    import sys

    out = subprocess.run([sys.executable, *argv], capture_output=True, text=True, check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result.setdefault("peak_rss_mb",
                      resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024)
    return result


def save_record(record: dict, out, benchmark: str, script: str) -> dict:
    """Add the benchmark name, :func:`machine_info` and the command line (``python
    benchmarks/<script> <this process's arguments>``) to ``record``, write it as JSON
    to ``out`` (folders made as needed) and return it."""
    import json
    import sys

    record.update(benchmark=benchmark, machine=machine_info(),
                  command=" ".join(["python", f"benchmarks/{script}", *sys.argv[1:]]))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2))
    return record


def timed_python(argv: list[str], *, src: Path | None, cache: Path | None = None,
                 timeout: float | None = None, python: str | None = None,
                 env: dict | None = None, prefix: list[str] | None = None) -> dict | None:
    """Run ``python argv`` with ``src`` first on ``PYTHONPATH`` (None: not set) and
    numba's cache in ``cache`` (if given) and measure the whole child process:
    ``{"wall_s", "cpu_s" (user + system of the child and its own children,
    ``os.wait4``), "peak_rss_mb", "load_1min": [before, after], "stdout"}``. A failed
    child ends the benchmark with its stderr; a child still running after ``timeout``
    seconds is killed (a deadlock, not a slow run) and gives None. ``python``: the
    interpreter (default this one); ``env``: more environment variables; ``prefix``: a
    command that execs the rest (``setpriv ...``: the same process, so measured)."""
    import subprocess
    import sys
    import tempfile
    import threading
    import time

    env = dict(START_ENV, **(env or {}))
    if src is not None:
        env["PYTHONPATH"] = str(src)
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache)
    load = os.getloadavg()[0]
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        proc = subprocess.Popen([*(prefix or []), python or sys.executable, *argv], env=env,
                                stdout=out, stderr=err)
        killer = threading.Timer(timeout, proc.kill) if timeout else None
        if killer is not None:
            killer.start()
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        if killer is not None:
            killer.cancel()
            if wall >= timeout:
                return None
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise SystemExit(f"{src}: {' '.join(argv)}: exit {proc.returncode}\n"
                             f"{err.read().decode()}")
        return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime,
                "peak_rss_mb": usage.ru_maxrss / 1024,
                "load_1min": [load, os.getloadavg()[0]], "stdout": out.read().decode(),
                "stderr": err.read().decode()}


def git_src(ref: str, dest: Path) -> Path:
    """``src/`` of commit ``ref`` of this repository, extracted into ``dest`` (made if
    needed); returns ``dest / "src"``."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    dest.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(root), "archive", ref, "src"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
    return dest / "src"
