"""Machine facts recorded with every benchmark result."""

from __future__ import annotations

import os
import platform
from importlib import metadata


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
    import json
    import resource
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", code, *map(str, args)],
                         capture_output=True, text=True, check=True)
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
    from pathlib import Path

    record.update(benchmark=benchmark, machine=machine_info(),
                  command=" ".join(["python", f"benchmarks/{script}", *sys.argv[1:]]))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2))
    return record
