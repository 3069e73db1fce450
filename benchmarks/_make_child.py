"""One timed ``photo3d.make`` of the Middlebury motorcycle pair, in a fresh process.

The child program every ``make`` timer runs (``bench_make``, ``bench_fill``,
``bench_speed`` and ``bench_learned``'s reference runs), through
:func:`_machine.run_make`. Input: ``photo3d.sample.motorcycle()``, its left view with
the ground-truth disparity as depth, at working size ``SIZE``. Prints one JSON object:

- ``make_s``: wall seconds around ``photo3d.make`` only (imports and sample loading
  not counted); ``cpu_s``: this process's CPU time (user + system, all threads) over
  the same span;
- ``stages``: the pipeline's seconds per stage (``Photo3D.timings``); ``stats``:
  ``Photo3D.stats`` (working size, edges and pixels added per pass, ...), with
  ``pixels`` (working width x height), ``ldi_pixels`` and ``edges`` copied out;
- with ``--mesh``: ``mesh_s``, seconds of ``Photo3D.mesh()`` after ``make``, and
  ``faces``, its triangle count;
- ``peak_rss_mb``: this process's peak resident set size at the end (interpreter and
  imports included; the mesh too with ``--mesh``), MiB.

Usage: python benchmarks/_make_child.py SIZE [--inpainter NAME]
           [--weights DIR | --random-nets] [--mesh]
"""

from __future__ import annotations

import argparse
import json
import resource
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("size", type=int, help="working size, pixels (Config.size)")
    parser.add_argument("--inpainter", default=None,
                        help="Config.inpainter (default: Config's default; learned with "
                             "--weights or --random-nets)")
    nets = parser.add_mutually_exclusive_group()
    nets.add_argument("--weights", default=None,
                      help="learned backend with the weights in this folder")
    nets.add_argument("--random-nets", action="store_true",
                      help="learned backend, the authors' architectures, random weights "
                           "(seed 0)")
    parser.add_argument("--mesh", action="store_true", help="also time Photo3D.mesh()")
    args = parser.parse_args()

    import numpy as np

    import photo3d
    from photo3d.sample import motorcycle

    backend = None
    if args.weights or args.random_nets:
        from photo3d.inpaint.learned import LearnedInpainter

        if args.weights:
            backend = LearnedInpainter(weights=args.weights)
        else:
            from photo3d.eval.evaluate import random_nets

            backend = LearnedInpainter(nets=random_nets(seed=0))
    learned = backend is not None
    options = {"inpainter": args.inpainter or "learned"} if learned or args.inpainter else {}
    config = photo3d.Config(size=args.size, **options)
    sample = motorcycle()
    t, c = time.perf_counter(), time.process_time()
    photo = photo3d.make(sample.left, depth=np.asarray(sample.disparity), config=config,
                         inpainter=backend)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    w, h = photo.stats["working_size"]
    result = {"make_s": wall, "cpu_s": cpu, "inpainter": config.inpainter,
              "stages": photo.timings, "stats": photo.stats, "pixels": int(w * h),
              "ldi_pixels": photo.ldi.size, "edges": photo.stats["edges"]}
    if args.mesh:
        t = time.perf_counter()
        mesh = photo.mesh()
        result.update(mesh_s=time.perf_counter() - t, faces=int(mesh.faces.shape[0]))
    result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(result))


if __name__ == "__main__":
    main()
