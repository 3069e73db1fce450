"""``photo3d batch`` on the machine at hand, on one core and under a CPU quota, against
a lone ``photo3d make`` and against a previous commit.

The photos are ``--photos`` (default 16) copies of the bundled sample (the Middlebury
motorcycle with its ground-truth disparity, as ``photo3d demo`` makes it), made at the
default 1024 px with ``--no-video`` and every other option at its default (the
workers too: ``photo3d batch`` picks them from the budget, :mod:`photo3d.parallel`).

Measured, each as a whole command in a fresh process (start-up included), CPU time
from ``RUSAGE_CHILDREN`` (the command and every process it waited for):

* **lone make**: ``photo3d make`` of one copy, ``--runs`` times, this tree and the
  ``--ref`` tree alternated (after one warm-up run each: numba's cache);
* **batch**: the whole folder, this tree and ``--ref`` (one run each, alternated);
  photos per hour, CPU per photo, how busy the cores were (CPU / (wall x cores));
* **one core**: the batch under ``taskset -c <first allowed core>``;
* **a quota of one CPU**: the batch in a cgroup of its own with a CPU quota of one
  CPU (``cpu.max`` in cgroup v2, ``cpu.cfs_quota_us`` in v1; made by hand, which
  needs root; skipped otherwise).

While each batch runs, the threads of every process under it are counted every
0.2 s from ``/proc`` (the largest count per process is recorded): with one core, no
process should run more threads than its main thread, the batch's own bookkeeping
threads and one worker.

Writes ``benchmarks/results/batch.json``.

Usage: python benchmarks/bench_batch.py [--photos 16] [--runs 3] [--ref HEAD~1]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import START_ENV, git_src, save_record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def make_photos(folder: Path, count: int) -> None:
    """``count`` copies of the sample in ``folder/photos`` with ``folder/depth``."""
    from photo3d.io.images import write_image
    from photo3d.sample import motorcycle

    sample = motorcycle()
    (folder / "photos").mkdir(parents=True)
    (folder / "depth").mkdir()
    write_image(folder / "photos" / "p00.png", sample.left)
    np.save(folder / "depth" / "p00.npy", np.asarray(sample.disparity, np.float32))
    for i in range(1, count):
        shutil.copy(folder / "photos" / "p00.png", folder / "photos" / f"p{i:02d}.png")
        shutil.copy(folder / "depth" / "p00.npy", folder / "depth" / f"p{i:02d}.npy")


def descendants(pid: int) -> list[int]:
    """``pid`` and every process under it, from ``/proc``."""
    parents: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        parents.setdefault(ppid, []).append(int(entry))
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        found.append(p)
        todo += parents.get(p, [])
    return found


def threads_of(pid: int) -> tuple[str, int] | None:
    """``(command, threads)`` of a process, None if it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()[:80]
    except OSError:
        return None
    count = next(int(line.split()[1]) for line in status.splitlines()
                 if line.startswith("Threads:"))
    return cmd, count


def run(argv: list[str], *, tree: Path, setup: str | None = None,
        watch: bool = False) -> dict:
    """Run ``argv`` (photo3d's command line, ``python -m photo3d ...``) from ``tree``;
    wall and CPU seconds, and with ``watch`` the largest thread count seen per process.
    ``setup``: a shell line run first in the same shell (``exec`` then starts photo3d:
    e.g. joining a cgroup)."""
    env = {**START_ENV, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, "-m", "photo3d", *argv]
    if setup is not None:
        cmd = ["/bin/sh", "-c", setup + ' && exec "$@"', "sh", *cmd]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    peak: dict[int, tuple[str, int]] = {}
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.2):
            for pid in descendants(proc.pid):
                seen = threads_of(pid)
                if seen is not None and seen[1] > peak.get(pid, ("", 0))[1]:
                    peak[pid] = seen

    sampler = threading.Thread(target=sample, daemon=True) if watch else None
    if sampler is not None:
        sampler.start()
    _, err = proc.communicate()
    wall = time.perf_counter() - t
    done.set()
    if sampler is not None:
        sampler.join()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}): "
                         f"{err.decode()[-800:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    result = {"wall_s": round(wall, 3), "cpu_s": round(cpu, 3)}
    if watch:
        workers = [n for cmd, n in peak.values() if "multiprocessing" in cmd]
        result["threads"] = {"main": max((n for cmd, n in peak.values()
                                          if "multiprocessing" not in cmd), default=0),
                             "worker_max": max(workers, default=0), "workers": len(workers)}
    return result


def batch_row(result: dict, photos: int, cores: int) -> dict:
    """Photos per hour, CPU per photo and how busy the cores were."""
    return {**result, "photos_per_hour": round(photos / result["wall_s"] * 3600),
            "cpu_per_photo_s": round(result["cpu_s"] / photos, 2),
            "busy": round(result["cpu_s"] / (result["wall_s"] * cores), 3)}


def quota_cgroup() -> tuple[str, Path] | None:
    """A cgroup of its own with a quota of one CPU: ``(shell line that joins it, its
    folder)``; None where none can be made (no cgroups, not root)."""
    name = f"photo3d-bench-{os.getpid()}"
    v2 = Path("/sys/fs/cgroup/cgroup.controllers")
    try:
        if v2.exists() and "cpu" in v2.read_text().split():
            folder = Path("/sys/fs/cgroup") / name
            folder.mkdir()
            (folder / "cpu.max").write_text("100000 100000\n")
        else:
            base = next(p for p in (Path("/sys/fs/cgroup/cpu"), Path("/sys/fs/cgroup/cpu,cpuacct"))
                        if (p / "cpu.cfs_quota_us").exists())
            folder = base / name
            folder.mkdir()
            (folder / "cpu.cfs_period_us").write_text("100000\n")
            (folder / "cpu.cfs_quota_us").write_text("100000\n")
    except (OSError, StopIteration):
        return None
    return f"echo $$ > {folder}/cgroup.procs", folder


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=16)
    parser.add_argument("--runs", type=int, default=3, help="lone makes per tree")
    parser.add_argument("--ref", default="HEAD~1", help="the commit to compare with")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "batch.json")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_batch."))
    cores = len(os.sched_getaffinity(0))
    ref_commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", args.ref],
                                capture_output=True, text=True, check=True).stdout.strip()
    trees = {"now": ROOT / "src", "ref": git_src(args.ref, work / "ref")}
    cgroup = None
    try:
        make_photos(work, args.photos)
        photo, depth = work / "photos" / "p00.png", work / "depth" / "p00.npy"

        def make(name: str, i: int) -> dict:
            return run(["make", str(photo), "--depth", str(depth), "-o",
                        str(work / f"make-{name}-{i}"), "--no-video", "-q"], tree=trees[name])

        def batch(name: str, label: str, setup: str | None = None) -> dict:
            out = work / f"batch-{name}-{label}"
            result = run(["batch", str(work / "photos"), "-o", str(out), "--depth",
                          str(work / "depth"), "--no-video", "-q"], tree=trees[name],
                         setup=setup, watch=True)
            made = len(list(out.glob("*/photo3d.npz")))
            if made != args.photos:
                raise SystemExit(f"batch {name} {label}: {made} of {args.photos} photos made")
            shutil.rmtree(out)
            return result

        for name in trees:  # warm-up: numba's cache of each tree, the page cache
            make(name, -1)
        lone: dict[str, list[dict]] = {name: [] for name in trees}
        for i in range(args.runs):
            for name in (("now", "ref") if i % 2 == 0 else ("ref", "now")):
                lone[name].append(make(name, i))
                print(f"make {name}: {lone[name][-1]}", flush=True)
        batches = {}
        for name in ("ref", "now"):
            batches[name] = batch_row(batch(name, "free"), args.photos, cores)
            print(f"batch {name}: {batches[name]}", flush=True)
        first = min(os.sched_getaffinity(0))
        batches["now, one core (taskset)"] = batch_row(
            batch("now", "taskset", setup=f"taskset -p -c {first} $$ >/dev/null"),
            args.photos, 1)
        print(f"batch taskset: {batches['now, one core (taskset)']}", flush=True)
        cgroup = quota_cgroup()
        if cgroup is not None:
            batches["now, quota of one CPU"] = batch_row(
                batch("now", "quota", setup=cgroup[0]), args.photos, 1)
            print(f"batch quota: {batches['now, quota of one CPU']}", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
        if cgroup is not None:
            try:
                cgroup[1].rmdir()
            except OSError:
                pass

    med = {name: {k: statistics.median(r[k] for r in runs) for k in ("wall_s", "cpu_s")}
           for name, runs in lone.items()}
    free = batches["now"]
    rows = ["| | wall | CPU | photos per hour | CPU per photo | cores busy | threads: "
            "batch process, largest worker (workers) |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    for name in ("ref", "now"):
        rows.append(f"| lone `make`, {'this tree' if name == 'now' else ref_commit} "
                    f"(median of {args.runs}) | {med[name]['wall_s']:.2f} s | "
                    f"{med[name]['cpu_s']:.2f} s | | {med[name]['cpu_s']:.2f} s | | |")
    for label, row in batches.items():
        names = {"ref": f"`batch`, {ref_commit}", "now": "`batch`, this tree"}
        name = names.get(label) or f"`batch`, this tree, {label.partition(', ')[2]}"
        t = row["threads"]
        rows.append(f"| {name} | {row['wall_s']:.1f} s | {row['cpu_s']:.1f} s | "
                    f"{row['photos_per_hour']} | {row['cpu_per_photo_s']:.2f} s | "
                    f"{100 * row['busy']:.0f} % | {t['main']}, {t['worker_max']} "
                    f"({t['workers']}) |")
    checks = {
        "lone make now / ref (wall)": round(med["now"]["wall_s"] / med["ref"]["wall_s"], 3),
        "batch CPU per photo / lone make CPU": round(
            free["cpu_per_photo_s"] / med["now"]["cpu_s"], 3),
    }
    for label in ("now, one core (taskset)", "now, quota of one CPU"):
        if label in batches:
            checks[f"{label}: CPU per photo / unconstrained"] = round(
                batches[label]["cpu_per_photo_s"] / free["cpu_per_photo_s"], 3)
    note = (f"\n{args.photos} copies of the sample at 1024 px, `--no-video`, default "
            f"options and workers; {cores} cores. Checks: " + "; ".join(
                f"{k}: {v}" for k, v in checks.items()) + ". The thread counts are the "
            "largest seen per process (every 0.2 s): the batch's own process holds "
            "the process pool's bookkeeping threads.")
    record = {"photos": args.photos, "runs": args.runs, "ref": ref_commit, "cores": cores,
              "lone_make": lone, "lone_make_median": med, "batches": batches,
              "checks": checks, "markdown": "\n".join(rows) + "\n" + note}
    save_record(record, args.out, "batch", "bench_batch.py")
    print("\n".join(rows) + "\n" + note)


if __name__ == "__main__":
    main()
