"""Peak resident memory of a command and its child processes (Linux).

Shared by ``bench_memory.py`` and ``tests/test_memory_model.py``: the larger of the
command's own ``ru_maxrss`` and its process tree's resident sum, sampled every 20 ms
(the batch's workers). The command runs under a small launcher, which reports its
``ru_maxrss``: Linux carries the high-water mark of the process that forked a child
across ``exec``, so a command forked straight from a large process (pytest late in the
suite, 2.6 GB) would measure at least that process's size.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

LAUNCH = """
import resource, subprocess, sys
status = subprocess.call(sys.argv[2:])
with open(sys.argv[1], "w") as report:
    report.write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
sys.exit(status)
"""
"""Runs a command and writes its peak (``ru_maxrss``, kB) to the file it is given."""


def tree_rss(root: int) -> int:
    """Resident bytes of process ``root`` and all its descendants now."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parents[int(entry)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
    tree, todo = {root}, [root]
    while todo:
        pid = todo.pop()
        kids = [c for c, p in parents.items() if p == pid and c not in tree]
        tree.update(kids)
        todo.extend(kids)
    total = 0
    for pid in tree:
        try:
            with open(f"/proc/{pid}/status") as f:
                total += next(int(line.split()[1]) * 1024 for line in f
                              if line.startswith("VmRSS:"))
        except (OSError, StopIteration):
            continue
    return total


def peak(cmd: list[str], *, cwd: Path, env: dict[str, str] | None = None) -> tuple[int, int, str]:
    """Run ``cmd``; ``(peak resident bytes, exit status, its stderr)``."""
    fd, report = tempfile.mkstemp(suffix=".peak")
    os.close(fd)
    proc = subprocess.Popen([sys.executable, "-c", LAUNCH, report, *cmd], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    sampled, done = [0], threading.Event()

    def sample() -> None:
        while not done.wait(0.02):
            sampled[0] = max(sampled[0], tree_rss(proc.pid))

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    err = proc.communicate()[1].decode()
    done.set()
    sampler.join()
    try:
        with open(report) as f:
            own = int(f.read() or 0) * 1024
    finally:
        os.unlink(report)
    return max(own, sampled[0]), proc.returncode, err
