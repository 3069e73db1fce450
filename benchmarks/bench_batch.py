"""Throughput of ``photo3d batch`` against a shell loop running ``photo3d make`` per photo.

The photos are 20 synthetic layered scenes at 320x240 (``photo3d.eval.synthetic``,
with their exact disparity as ``.npy`` depth maps), the default fill (no
``--inpainter``: ``photo3d.Config().inpainter``; the fill that ran is read back from
the outputs' ``config.json`` and recorded). Per configuration and round: first the
shell loop (``bash``: ``for f in photos/*.png; do python -m photo3d make $f --depth
... -o ...; done``), then ``python -m photo3d batch photos -o ... --depth depth
--workers 2`` with the same options, so the two are interleaved under the same
machine load. Both are timed as whole commands (process start-up included: that is
what the user waits for). numba's on-disk cache is warmed by a first ``make`` before
any timing. Writes ``benchmarks/results/batch.json``.

Usage: python benchmarks/bench_batch.py [--photos 20] [--rounds 1] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402

CONFIGS = {
    "meshes + viewer (--no-video)": ["--size", "0", "--no-video"],
    "with the four videos (40 frames each)": ["--size", "0", "--frames", "40"],
}


def make_photos(folder: Path, count: int) -> None:
    from photo3d.eval.synthetic import synthetic_pair
    from photo3d.io.images import write_image

    (folder / "photos").mkdir(parents=True)
    (folder / "depth").mkdir()
    for i in range(count):
        pair = synthetic_pair(i, width=320, height=240)
        write_image(folder / "photos" / f"scene{i:02d}.png", pair.left)
        np.save(folder / "depth" / f"scene{i:02d}.npy", pair.disparity.astype(np.float32))


def fill_used(folder: Path) -> str:
    """The inpainter named in the ``config.json`` of every 3D photo under ``folder``
    (one name, or a ``SystemExit``)."""
    names = {json.loads(f.read_text())["config"]["inpainter"]
             for f in folder.glob("*/config.json")}
    if len(names) != 1:
        raise SystemExit(f"{folder}: expected one inpainter, got {sorted(names)}")
    return names.pop()


def timed(cmd: list[str] | str, *, shell: bool = False) -> float:
    t = time.perf_counter()
    subprocess.run(cmd, shell=shell, check=False, capture_output=True,
                   executable="/bin/bash" if shell else None)
    return time.perf_counter() - t


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "batch.json")
    args = parser.parse_args()
    py = shlex.quote(sys.executable)
    work = Path(tempfile.mkdtemp(prefix="bench_batch."))
    try:
        make_photos(work, args.photos)
        first = work / "photos" / "scene00.png"
        timed([sys.executable, "-m", "photo3d", "make", str(first), "--depth",
               str(work / "depth" / "scene00.npy"), "-o", str(work / "warm"), "-q",
               "--frames", "4"])  # warm-up: numba's cache, page cache
        results, fills = [], set()
        for label, options in CONFIGS.items():
            opts = " ".join(shlex.quote(o) for o in options)
            loop_s, batch_s = [], []
            for r in range(args.rounds):
                loop_dir, batch_dir = work / f"loop{r}", work / f"batch{r}"
                loop_dir.mkdir()
                script = (f"cd {shlex.quote(str(work))} && for f in photos/*.png; do "
                          f"n=$(basename \"$f\" .png); {py} -m photo3d make \"$f\" --depth "
                          f"depth/$n.npy -o {shlex.quote(str(loop_dir))}/$n -q {opts}; done")
                loop_s.append(timed(script, shell=True))
                batch_s.append(timed([sys.executable, "-m", "photo3d", "batch",
                                      str(work / "photos"), "-o", str(batch_dir), "--depth",
                                      str(work / "depth"), "--workers", str(args.workers),
                                      "-q", *options]))
                made = [len(list(d.glob("*/photo3d.npz"))) for d in (loop_dir, batch_dir)]
                if made != [args.photos, args.photos]:
                    raise SystemExit(f"{label}: expected {args.photos} photos, got {made}")
                fills.update(fill_used(d) for d in (loop_dir, batch_dir))
                shutil.rmtree(loop_dir)
                shutil.rmtree(batch_dir)
                print(f"{label}, round {r + 1}: loop {loop_s[-1]:.1f} s, batch "
                      f"{batch_s[-1]:.1f} s, {loop_s[-1] / batch_s[-1]:.2f}x", flush=True)
            results.append({
                "config": label, "options": options, "loop_s": loop_s, "batch_s": batch_s,
                "speedup": statistics.median(a / b for a, b in zip(loop_s, batch_s,
                                                                   strict=True))})
    finally:
        shutil.rmtree(work, ignore_errors=True)
    rows = [f"| options | shell loop of `make` | `batch --workers {args.workers}` | speed-up |",
            "| --- | --- | --- | --- |"]
    for res in results:
        loop, batch = statistics.median(res["loop_s"]), statistics.median(res["batch_s"])
        rows.append(f"| {res['config']}: `{' '.join(res['options'])}` | {loop:.1f} s "
                    f"({args.photos / loop:.2f} photos/s) | {batch:.1f} s "
                    f"({args.photos / batch:.2f} photos/s) | {res['speedup']:.2f}x |")
    fill = ", ".join(sorted(fills))
    note = (f"\n{args.photos} synthetic 320x240 photos with exact depth, the default fill "
            f"(`{fill}`), {args.rounds} round(s), loop and batch interleaved; wall time of "
            "the whole command. The machine (2 cores) was shared with other jobs while "
            "this ran: compare the ratio, not the seconds.")
    record = {"photos": args.photos, "rounds": args.rounds, "workers": args.workers,
              "inpainter": fill, "results": results, "markdown": "\n".join(rows) + "\n" + note}
    save_record(record, args.out, "batch", "bench_batch.py")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
