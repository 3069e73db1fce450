"""Throughput of ``photo3d batch --engine ray`` on a local cluster of one and of two
one-CPU nodes (issue 43, item 4).

The cluster is ``ray.cluster_utils.Cluster`` on this machine: a head without CPUs
(so no actor runs there) and worker nodes of one CPU each (``num_cpus=1``), added and
removed between runs, so a one-node run has no second node's processes beside it.
Each actor reserves its node's CPU and runs with one thread. The photos are
``--photos`` copies of the bundled sample (the Middlebury motorcycle, 741x500, its
ground-truth disparity as ``.npy``), made with the default options at ``--size``
(default 1024 px) and ``--no-video``: the whole command ``python -m photo3d batch
photos -o OUT --depth depth --engine ray --ray-address ADDRESS --no-video -q`` is
timed (the driver's start-up, the connection, each node's actors loading the
kernels included: that is what the user waits for). Runs alternate one node and two
nodes, ``--rounds`` times. numba's on-disk cache is warmed by one ``make`` first, and
after each change of nodes an unmeasured batch of one photo per node lets a new node
finish its own start-up (Ray's agents on it import for seconds) before the timed one.

Checked on every run: each photo is ``ok`` in the manifest, and the LDI arrays of
every photo (all copies of one photo) are identical across runs and to a local
``make``'s. Recorded: wall seconds, photos per hour, each photo's seconds in its
actor (the manifest's ``seconds``), the actors that made them, the 1-minute load
average before and after each run. On a 2-core machine two one-CPU nodes are the
whole machine, so the driver and Ray's own processes share the cores with the
actors: the two-node speed-up is a lower bound of what two separate machines give.

The worker nodes import photo3d from this tree (``src`` on ``PYTHONPATH``, inherited
by the nodes' processes).

Usage: python benchmarks/bench_ray.py [--photos 16] [--rounds 1] [--size 1024]

(16 photos: each batch's fixed cost, a few seconds to start the driver and the
actors, is then a small part of the wall; on an idle 2-core machine a round takes
about 3 minutes.)
Writes ``benchmarks/results/ray.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

SRC = Path(__file__).resolve().parents[1] / "src"
sys.path[:0] = [str(Path(__file__).parent), str(SRC)]  # this tree's photo3d here too
from _machine import START_ENV, save_record  # noqa: E402


def make_photos(folder: Path, count: int) -> None:
    """``count`` copies of the sample: ``photos/sampleNN.png`` and ``depth/sampleNN.npy``."""
    from photo3d.io.images import write_image
    from photo3d.sample import motorcycle

    sample = motorcycle()
    (folder / "photos").mkdir(parents=True)
    (folder / "depth").mkdir()
    for i in range(count):
        write_image(folder / "photos" / f"sample{i:02d}.png", sample.left)
        np.save(folder / "depth" / f"sample{i:02d}.npy",
                np.asarray(sample.disparity, np.float32))


def ldi_hash(folder: Path) -> str:
    """SHA-256 of the LDI arrays (colour, links) of a 3D photo folder."""
    from photo3d.io.npz import load_npz

    ldi = load_npz(folder / "photo3d.npz")[0]
    digest = hashlib.sha256()
    for array in (ldi.color, ldi.links):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


class ActorCPU:
    """The CPU seconds of this machine's Ray actor processes (``ray::_Actor``), read
    from ``/proc`` every :data:`SAMPLE_S` while a batch runs; each process counts with
    its last reading (what an actor spends after it, idle at the batch's end, is left
    out). Use as a context manager; :meth:`seconds` after it."""

    SAMPLE_S = 0.5

    def __init__(self) -> None:
        self.seen: dict[tuple[str, bytes], float] = {}  # (pid, start time) -> CPU s
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._watch, daemon=True)

    def _watch(self) -> None:
        tick = os.sysconf("SC_CLK_TCK")
        while not self.done.is_set():
            for pid in filter(str.isdigit, os.listdir("/proc")):
                try:
                    with open(f"/proc/{pid}/cmdline", "rb") as f:
                        if not f.read().startswith(b"ray::_Actor"):
                            continue
                    with open(f"/proc/{pid}/stat", "rb") as f:
                        fields = f.read().rpartition(b")")[2].split()
                except OSError:  # ended meanwhile
                    continue
                # after the name: state, ..., utime (14th field), stime, ..., starttime
                self.seen[pid, fields[19]] = (int(fields[11]) + int(fields[12])) / tick
            self.done.wait(self.SAMPLE_S)

    def __enter__(self) -> ActorCPU:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.done.set()
        self.thread.join()

    def seconds(self) -> float:
        return sum(self.seen.values())


def run_batch(work: Path, out: Path, address: str, options: list[str], *,
              only: int | None = None) -> dict:
    """One timed ``photo3d batch --engine ray`` into ``out`` (of the first ``only``
    photos, when given); its manifest checked."""
    photos = work / "photos"
    if only is not None:  # a folder of links to the first ``only`` photos
        photos = work / f"first{only}"
        photos.mkdir(exist_ok=True)
        for image in sorted((work / "photos").iterdir())[:only]:
            if not (photos / image.name).exists():
                (photos / image.name).symlink_to(image)
    load = os.getloadavg()[0]
    start = time.perf_counter()
    with ActorCPU() as cpu:
        done = subprocess.run([sys.executable, "-m", "photo3d", "batch", str(photos),
                               "-o", str(out), "--depth", str(work / "depth"), "--engine",
                               "ray", "--ray-address", address, "-q", *options],
                              env=_env(), capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"batch failed ({done.returncode}):\n{done.stdout}\n{done.stderr}")
    records = [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]
    if any(r["status"] != "ok" for r in records):
        raise SystemExit(f"not every photo is ok: {records}")
    return {"wall_s": wall, "photo_s": [r["seconds"] for r in records],
            "actor_cpu_s": cpu.seconds(), "actor_cpu_per_photo_s": cpu.seconds() / len(records),
            "actors": len({r["worker"] for r in records}),
            "load_1min": [load, os.getloadavg()[0]],
            "ldi": sorted({ldi_hash(out / r["name"]) for r in records})}


def _env() -> dict:
    """This tree's photo3d for the driver and (inherited) every node's processes."""
    return dict(START_ENV, PYTHONPATH=os.pathsep.join(
        [str(SRC), *filter(None, [START_ENV.get("PYTHONPATH")])]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=16)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--size", type=int, default=1024, help="working size (--size)")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "ray.json")
    args = parser.parse_args()
    os.environ.update(_env())  # before the cluster starts: its processes inherit it
    import ray
    from ray.cluster_utils import Cluster

    options = ["--size", str(args.size), "--no-video"]
    work = Path(tempfile.mkdtemp(prefix="bench_ray."))
    cluster = None
    try:
        make_photos(work, args.photos)
        subprocess.run([sys.executable, "-m", "photo3d", "make",
                        str(work / "photos" / "sample00.png"), "--depth",
                        str(work / "depth" / "sample00.npy"), "-o", str(work / "warm"), "-q",
                        *options], env=_env(), check=True)  # warm-up: numba's cache
        reference = ldi_hash(work / "warm")
        cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
        runs = []
        for r in range(args.rounds):
            for nodes in (1, 2):
                while len(cluster.worker_nodes) < nodes:
                    cluster.add_node(num_cpus=1)
                while len(cluster.worker_nodes) > nodes:
                    cluster.remove_node(cluster.worker_nodes[-1])
                cluster.wait_for_nodes()
                # unmeasured: a new node's own start-up (its agents import for seconds)
                # and its first worker processes, with one photo per node
                run_batch(work, work / "settle", cluster.address, options, only=nodes)
                shutil.rmtree(work / "settle")
                out = work / f"out{r}-{nodes}"
                run = {"nodes": nodes, "round": r, **run_batch(work, out, cluster.address,
                                                                options)}
                run["photos_per_hour"] = 3600 * args.photos / run["wall_s"]
                # the wall beyond the photos' own time: start-up, connecting, the actors'
                # start (imports, models, kernels from the cache), the end
                run["overhead_s"] = run["wall_s"] - sum(run["photo_s"]) / nodes
                runs.append(run)
                shutil.rmtree(out)
                print(f"round {r + 1}, {nodes} node(s): {run['wall_s']:.1f} s, "
                      f"{run['photos_per_hour']:.0f} photos/h, load "
                      f"{run['load_1min'][0]:.1f}-{run['load_1min'][1]:.1f}", flush=True)
    finally:
        if ray.is_initialized():
            ray.shutdown()
        if cluster is not None:
            cluster.shutdown()
        shutil.rmtree(work, ignore_errors=True)
    hashes = {h for run in runs for h in run["ldi"]}
    if hashes != {reference}:
        raise SystemExit(f"the LDI differs between runs or from make's: {sorted(hashes)}")
    summary = {}
    for nodes in (1, 2):
        mine = [run for run in runs if run["nodes"] == nodes]
        summary[nodes] = {"wall_s": statistics.median(r["wall_s"] for r in mine),
                          "photos_per_hour": statistics.median(r["photos_per_hour"]
                                                               for r in mine),
                          "photo_s": statistics.median(s for r in mine for s in r["photo_s"]),
                          "overhead_s": statistics.median(r["overhead_s"] for r in mine)}
        summary[nodes]["actors_per_hour"] = 3600 * nodes / summary[nodes]["photo_s"]
        summary[nodes]["actor_cpu_per_photo_s"] = statistics.median(
            r["actor_cpu_per_photo_s"] for r in mine)
    speedup = summary[2]["photos_per_hour"] / summary[1]["photos_per_hour"]
    steady = summary[2]["actors_per_hour"] / summary[1]["actors_per_hour"]
    loads = [x for run in runs for x in run["load_1min"]]
    rows = ["| nodes (1 CPU each) | wall | photos per hour | per node | a photo in its actor "
            "| wall beyond the photos | photos per hour in the actors | actors' CPU a photo |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for nodes, s in summary.items():
        rows.append(f"| {nodes} | {s['wall_s']:.1f} s | {s['photos_per_hour']:.0f} | "
                    f"{s['photos_per_hour'] / nodes:.0f} | {s['photo_s']:.2f} s | "
                    f"{s['overhead_s']:.1f} s | {s['actors_per_hour']:.0f} | "
                    f"{s['actor_cpu_per_photo_s']:.2f} s |")
    note = (f"\n{args.photos} copies of the sample, `{' '.join(options)}` (default options "
            f"otherwise), {args.rounds} round(s), one node and two alternated; whole "
            f"command timed. Two nodes: **{speedup:.2f}x** one node's throughput (target "
            f"1.8x); in the actors alone (photos per hour from the median photo's "
            f"seconds, without the fixed cost) {steady:.2f}x. 'A photo in its actor': the "
            "median of the manifest's seconds; 'wall "
            "beyond the photos': the wall minus the photos' seconds per node (the driver's "
            "start, connecting, the actors' start: imports, models, kernels from the cache); "
            "'actors' CPU a photo': the actor processes' CPU seconds (their start included) "
            "over the photos, which a busy machine does not stretch: 3600 over it is a "
            "CPU's photos per hour on an idle machine. "
            f"LDI identical in every run and to `make`'s. Load average (1 min) "
            f"{min(loads):.1f}-{max(loads):.1f} during the runs; on this machine the two "
            "nodes share its cores with the driver and Ray's processes.")
    record = {"photos": args.photos, "rounds": args.rounds, "size": args.size,
              "options": options, "runs": runs,
              "summary": {str(k): v for k, v in summary.items()}, "speedup": speedup,
              "speedup_in_actors": steady,
              "ldi_identical": True, "markdown": "\n".join(rows) + "\n" + note}
    save_record(record, args.out, "ray", "bench_ray.py")
    print("\n".join(rows) + "\n" + note)


if __name__ == "__main__":
    main()
