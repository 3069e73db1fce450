"""Videos: ``photo3d render`` of one video and ``photo3d demo`` with its four, against
the previous commit in the same session, and the frames' fidelity to it.

Two versions of the code, each run with ``PYTHONPATH`` set to its own copy and its own
``NUMBA_CACHE_DIR`` (warmed by an unmeasured run first):

* ``now``: this working tree's ``src/``, copied into a temporary folder first (edits
  made while the benchmark runs do not mix in);
* ``ref``: ``--ref`` (default ``HEAD``), ``git archive``'d into a temporary folder.

The 3D photo is the demo's (``photo3d demo -o DIR --no-video``, made once by ``now``;
with ``--own-photos`` each version renders the one it made itself: a ``ref`` older than
the ``photo3d.npz`` format ``now`` writes cannot read ``now``'s).
Timed, whole process, the two versions alternated ``--runs`` times (medians of wall
seconds and of the child's CPU seconds, user + system, all threads; the machine's
1-minute load average before and after each run is recorded, since the machine may
be shared):

* ``render``: ``photo3d render DIR --path circle --size 1280x720`` (240 frames);
* ``demo`` (unless ``--no-demo``): ``photo3d demo -o DIR2 --overwrite`` (the 3D photo,
  its files and its four videos at the photo's size).

Fidelity: the frames each version hands the encoder (``uint8``, every ``--every``-th
frame of each preset path at 1280x720, rendered the way ``render`` renders them:
``photo3d.output.write_videos`` with the command line's default settings, the
encoder replaced by a capture), PSNR of ``now`` against ``ref`` per path.
Writes ``benchmarks/results/video.json``.

Usage: python benchmarks/bench_video.py [--runs 3] [--ref HEAD] [--every 10] [--no-demo]
           [--own-photos] [--out JSON]
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

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import git_src, save_record, timed_python  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PATHS = ("circle", "swing", "zoom-in", "dolly-zoom-in")

FRAMES_CHILD = r"""
import json, sys
from pathlib import Path
import numpy as np
import photo3d
import photo3d.render.animate as animate
from photo3d.output import write_videos
try:
    from photo3d.render.renderer import video_settings
except ImportError:  # before video_settings: the CLI's settings spelled out
    from photo3d.render.renderer import AUTHORS_CROP, RenderSettings
    def video_settings():
        return RenderSettings(crop=AUTHORS_CROP)
folder, out, every = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
photo = photo3d.load(folder)
frames = {}
def capture(renderer, ldi, spec, target, *, progress=None):
    cameras = animate.path_cameras(ldi, spec)[::every]
    for i, frame in enumerate(animate.render_frames(renderer, cameras)):
        frames[f"{spec.path}/{i}"] = frame
    return Path(target)
animate.render_video = capture  # write_videos imports it when called
specs = [animate.VideoSpec(path=p, size=(1280, 720)) for p in sys.argv[4:]]
write_videos(photo, None, folder, specs, settings=video_settings())
np.savez(out, **frames)
print(json.dumps({"photo3d": photo3d.__file__}))
"""


def run(src: Path, cache: Path, argv: list[str]) -> dict:
    """``python argv`` with ``src`` first on the path and numba's cache in ``cache``:
    wall and CPU seconds of the whole child process, the load average around it
    (:func:`_machine.timed_python`)."""
    result = timed_python(argv, src=src, cache=cache)
    return {k: result[k] for k in ("wall_s", "cpu_s", "load_1min", "stdout")}


def copy_sources(tmp: Path, ref: str) -> dict[str, Path]:
    """``src`` of the working tree and of ``ref`` in ``tmp``; checks ``import photo3d``
    finds each copy."""
    srcs = {"now": tmp / "now" / "src", "ref": tmp / "ref" / "src"}
    shutil.copytree(ROOT / "src", srcs["now"], ignore=shutil.ignore_patterns("__pycache__"))
    git_src(ref, srcs["ref"].parent)
    for src in srcs.values():
        found = subprocess.run([sys.executable, "-c", "import photo3d; print(photo3d.__file__)"],
                               env=dict(os.environ, PYTHONPATH=str(src)), check=True,
                               capture_output=True, text=True).stdout.strip()
        if not found.startswith(str(src)):
            raise SystemExit(f"import photo3d found {found}, not the copy in {src}")
    return srcs


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of two ``uint8`` images (99 when equal)."""
    mse = float(np.mean((a.astype(np.float64) - b) ** 2))
    return 99.0 if mse == 0 else 10 * np.log10(255.0**2 / mse)


def fidelity(srcs: dict[str, Path], caches: dict[str, Path], photos: dict[str, Path],
             tmp: Path, every: int) -> dict:
    """PSNR of ``now``'s frames against ``ref``'s per preset path: mean, lowest, count
    (each version rendering ``photos[kind]``)."""
    frames = {}
    for kind in ("ref", "now"):
        out = tmp / f"frames_{kind}.npz"
        run(srcs[kind], caches[kind], ["-c", FRAMES_CHILD, str(photos[kind]), str(out),
                                       str(every), *PATHS])
        frames[kind] = np.load(out)
    result = {}
    for path in PATHS:
        keys = [k for k in frames["ref"].files if k.split("/")[0] == path]
        values = [psnr(frames["ref"][k], frames["now"][k]) for k in keys]
        result[path] = {"mean_db": float(np.mean(values)), "min_db": float(np.min(values)),
                        "frames": len(values)}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--ref", default="HEAD")
    parser.add_argument("--every", type=int, default=10,
                        help="fidelity: every n-th frame of each path")
    parser.add_argument("--no-demo", action="store_true", help="time render only")
    parser.add_argument("--own-photos", action="store_true",
                        help="each version renders the demo photo it made itself")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "video.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        srcs = copy_sources(tmp, args.ref)
        caches = {kind: tmp / f"cache_{kind}" for kind in srcs}
        demo_out = tmp / "demo"
        photos = {kind: tmp / ("photo" if kind == "now" or not args.own_photos
                               else f"photo_{kind}") for kind in srcs}
        render = {kind: ["-m", "photo3d", "render", str(photos[kind]), "--path", "circle",
                         "--size", "1280x720", "-q"] for kind in srcs}
        demo = ["-m", "photo3d", "demo", "-o", str(demo_out), "--overwrite", "-q"]
        for kind in ("now", "ref") if args.own_photos else ("now",):
            run(srcs[kind], caches[kind], ["-m", "photo3d", "demo", "-o", str(photos[kind]),
                                           "--no-video", "-q"])
        for kind in ("ref", "now"):  # warm-ups: numba compiles into each cache
            run(srcs[kind], caches[kind], [*render[kind], "--frames", "2"])
            if not args.no_demo:
                run(srcs[kind], caches[kind], [*demo, "--frames", "2"])
        runs: dict[str, list[dict]] = {f"{job}_{kind}": [] for job in ("render", "demo")
                                       for kind in ("ref", "now")}
        sizes = {}
        for _ in range(args.runs):
            for kind in ("ref", "now"):
                runs[f"render_{kind}"].append(run(srcs[kind], caches[kind], render[kind]))
                sizes[kind] = (photos[kind] / "video" / "circle.mp4").stat().st_size
            if not args.no_demo:
                for kind in ("ref", "now"):
                    runs[f"demo_{kind}"].append(run(srcs[kind], caches[kind], demo))
        quality = fidelity(srcs, caches, photos, tmp, args.every)
    medians = {name: {key: statistics.median(r[key] for r in rs) for key in ("wall_s", "cpu_s")}
               for name, rs in runs.items() if rs}
    for rs in runs.values():
        for r in rs:
            r.pop("stdout")
    record = {"runs": runs, "median": medians, "circle_mp4_bytes": sizes,
              "psnr_now_vs_ref": quality, "ref": args.ref, "every": args.every,
              "own_photos": args.own_photos}
    for job in ("render", "demo"):
        if f"{job}_now" in medians:
            record[f"{job}_ratio"] = (medians[f"{job}_now"]["wall_s"]
                                      / medians[f"{job}_ref"]["wall_s"])
    save_record(record, args.out, "video", "bench_video.py")
    loads = [v for rs in runs.values() for r in rs for v in r["load_1min"]]
    print(f"1-minute load average during the runs: {min(loads):.1f}-{max(loads):.1f} "
          f"(machine: {record['machine']['cpu']}, {record['machine']['cores']} cores)")
    for job in ("render", "demo"):
        if f"{job}_now" not in medians:
            continue
        ref, now = medians[f"{job}_ref"], medians[f"{job}_now"]
        print(f"{job}: ref {ref['wall_s']:.2f} s ({ref['cpu_s']:.1f} s CPU), now "
              f"{now['wall_s']:.2f} s ({now['cpu_s']:.1f} s CPU): now/ref "
              f"{record[f'{job}_ratio']:.3f} (median of {args.runs}; walls ref "
              f"{[round(r['wall_s'], 2) for r in runs[f'{job}_ref']]}, now "
              f"{[round(r['wall_s'], 2) for r in runs[f'{job}_now']]})")
    print(f"circle.mp4: ref {sizes['ref'] / 1e6:.2f} MB, now {sizes['now'] / 1e6:.2f} MB")
    for path, q in quality.items():
        print(f"PSNR now vs ref, {path}: mean {q['mean_db']:.2f} dB, lowest "
              f"{q['min_db']:.2f} dB ({q['frames']} frames)")


if __name__ == "__main__":
    main()
