"""How busy the two cores are during ``make``'s inpaint stage, and on what.

Issue 35 (the fill's wall time). One process: ``photo3d.make`` on the bundled sample
(``--raw``: its raw disparity, unknown = 0) once to warm up, then ``--runs`` times
measured. While a measured ``make`` runs, a sampler thread reads every thread's CPU
clock (``pthread_getcpuclockid``) every 2 ms, and the stage's parts record their wall
and thread CPU time: the passes (``fill_pass``), their regions, extraction of each
patch, each patch's fill and its parts (edge continuation, piecewise diffusion,
PatchMatch, texture weight), ``take``, the merge, and the frame (``fill_border``, its
own thread). Prints, per run: the stage's wall and CPU seconds, the time spent with
about 0, 1 or 2 cores busy, each part's total wall and CPU, the main thread's
sections in order, and (``--bins``) a 50 ms timeline.

The sampler and the wrappers cost a little CPU themselves; a busy machine stretches
the wall seconds (note the load average printed with each run). To compare two trees,
run it with each tree's ``src`` first on ``PYTHONPATH``, alternating.

Usage: python benchmarks/profile_inpaint.py [--runs 2] [--raw] [--bins]
"""

from __future__ import annotations

import argparse
import os
import threading
import time
from collections import defaultdict

import numpy as np

import photo3d
import photo3d.inpaint.structured as structured
import photo3d.pipeline as pipeline
import photo3d.stages.passes as passes
from photo3d.sample import motorcycle

SPANS: list[tuple[str, str, float, float, float]] = []  # name, thread, start, end, cpu


def record(name: str, start: float, cpu: float) -> None:
    SPANS.append((name, threading.current_thread().name, start, time.perf_counter(),
                  time.thread_time() - cpu))


def timed(module, attr: str, name: str | None = None) -> None:
    """Replace ``module.attr`` by a wrapper recording each call as a span."""
    inner = getattr(module, attr)

    def call(*args, **kwargs):
        start, cpu = time.perf_counter(), time.thread_time()
        try:
            return inner(*args, **kwargs)
        finally:
            record(name or attr, start, cpu)

    setattr(module, attr, call)


def timed_iter(module, attr: str, name: str) -> None:
    """Replace the generator function ``module.attr``; each item made is a span."""
    inner = getattr(module, attr)

    def call(*args, **kwargs):
        items = inner(*args, **kwargs)
        while True:
            start, cpu = time.perf_counter(), time.thread_time()
            try:
                item = next(items)
            except StopIteration:
                return
            finally:
                record(name, start, cpu)
            yield item

    setattr(module, attr, call)


def instrument() -> None:
    for attr in ("pass_regions", "merge_fills", "take"):
        timed(passes, attr)
    timed(pipeline, "fill_border")
    timed(pipeline, "fill_pass")
    # the texture weight calls itself on its window: only the outer call is a span
    for attr in ("continue_edges", "piecewise_diffuse", "exemplar_fill"):
        timed(structured, attr)
    weight, depth = structured.texture_weight, threading.local()

    def texture_weight(*args, **kwargs):
        outer = not getattr(depth, "inside", False)
        start, cpu = time.perf_counter(), time.thread_time()
        depth.inside = True
        try:
            return weight(*args, **kwargs)
        finally:
            if outer:
                depth.inside = False
                record("texture_weight", start, cpu)

    structured.texture_weight = texture_weight
    timed(structured.StructuredInpainter, "fill", "patch")
    timed_iter(passes, "iter_patches", "extract")


def sample_clocks(samples: list, stop: threading.Event) -> None:
    me = threading.get_ident()
    while not stop.is_set():
        now, clocks = time.perf_counter(), {}
        for thread in threading.enumerate():
            if thread.ident in (me, None):
                continue
            try:
                clocks[thread.ident] = time.clock_gettime(
                    time.pthread_getcpuclockid(thread.ident))
            except (OSError, ProcessLookupError):  # the thread just ended
                pass
        samples.append((now, clocks))
        time.sleep(0.002)


def busy(samples: list, start: float, end: float) -> tuple[float, dict[float, float]]:
    """CPU seconds of all threads between ``start`` and ``end``, and the seconds spent
    with about 0, 0.5, 1, 1.5, 2 ... cores busy."""
    total, spread = 0.0, defaultdict(float)
    for (t0, c0), (t1, c1) in zip(samples, samples[1:], strict=False):
        if not (start <= t1 <= end):
            continue
        used = sum(max(0.0, c1[k] - c0[k]) for k in c1 if k in c0)
        total += used
        spread[round(min(used / max(t1 - t0, 1e-9), 3.0) * 2) / 2] += t1 - t0
    return total, dict(sorted(spread.items()))


def report(samples: list, bins: bool) -> None:
    w0 = min(s[2] for s in SPANS if s[0] in ("fill_pass", "fill_border"))
    w1 = max(s[3] for s in SPANS if s[0] == "fill_pass")
    cpu, spread = busy(samples, w0, w1)
    print(f"  inpaint: {w1 - w0:.3f} s wall, {cpu:.3f} s CPU ({cpu / (w1 - w0):.2f} cores)")
    print("  seconds with about N cores busy:",
          {k: round(v, 3) for k, v in spread.items()})
    parts = defaultdict(lambda: [0, 0.0, 0.0])
    for name, _, a, b, c in SPANS:
        parts[name][0] += 1
        parts[name][1] += b - a
        parts[name][2] += c
    for name, (n, wall, c) in sorted(parts.items(), key=lambda kv: -kv[1][2]):
        print(f"    {name:18s} n={n:4d} wall={wall:7.3f} cpu={c:7.3f}")
    print("  main thread's sections (s from the stage's start):")
    for name, thread, a, b, c in sorted(SPANS, key=lambda s: s[2]):
        if name == "fill_border" or (thread == "MainThread"
                                     and name not in ("extract", "take", "patch")):
            print(f"    {name:18s} {a - w0:6.3f} .. {b - w0:6.3f}  wall {b - a:6.3f} "
                  f"cpu {c:6.3f}")
    if not bins:
        return
    print("  50 ms bins: start, cores busy, fills running, frame, extraction")
    for k in range(int((w1 - w0) / 0.05) + 1):
        a, b = w0 + 0.05 * k, w0 + 0.05 * (k + 1)
        used, _ = busy(samples, a, b)

        def running(name: str, a: float = a, b: float = b) -> float:
            return sum(max(0.0, min(s[3], b) - max(s[2], a))
                       for s in SPANS if s[0] == name) / 0.05

        print(f"    {a - w0:5.2f} {used / 0.05:4.2f} {running('patch'):4.2f} "
              f"{running('fill_border'):3.1f} {running('extract'):4.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--raw", action="store_true", help="the raw disparity, unknown = 0")
    parser.add_argument("--bins", action="store_true", help="print a 50 ms timeline")
    args = parser.parse_args()
    sample = motorcycle()
    disparity = np.asarray(sample.disparity)
    if args.raw:
        disparity = np.where(np.isfinite(disparity), disparity, 0.0)
    instrument()
    photo3d.make(sample.left, depth=disparity)  # warm-up: kernels, caches
    for run in range(args.runs):
        SPANS.clear()
        samples: list = []
        stop = threading.Event()
        sampler = threading.Thread(target=sample_clocks, args=(samples, stop), daemon=True)
        sampler.start()
        cpu = time.process_time()
        photo = photo3d.make(sample.left, depth=disparity)
        cpu = time.process_time() - cpu
        stop.set()
        sampler.join()
        stages = {k: round(v, 3) for k, v in photo.timings.items()}
        print(f"run {run + 1}: load {os.getloadavg()[0]:.2f}, make {cpu:.2f} s CPU, "
              f"stages {stages}, edges {photo.stats['edges']}")
        report(samples, args.bins)


if __name__ == "__main__":
    main()
