"""The long run of the readers' fuzzing (issue 45): every format photo3d reads back,
mutated many times; any reader that answers with anything but a one-line
Photo3DError is reported with the smallest file Hypothesis finds.

The suite runs the same property with 30 examples a format
(``tests/io/test_fuzz_readers.py``); this runs ``--examples`` (default 2000) each::

    PYTHONPATH=src:tests python scripts/fuzz/fuzz_readers.py --examples 2000 [FORMAT ...]

Exit status 0 when every format held, 1 otherwise (the failures are printed).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    """Fuzz the readers; returns the exit status."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
    from fuzzing import FORMATS, mutated, one_line
    from hypothesis import HealthCheck, given, settings

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("formats", nargs="*", choices=[[], *FORMATS], default=[],
                        help="formats to fuzz (default: all)")
    parser.add_argument("--examples", type=int, default=2000)
    args = parser.parse_args(argv)
    warnings.simplefilter("error")  # as the test suite: a warning is a failure
    failed = []
    with tempfile.TemporaryDirectory() as root:
        for name in args.formats or FORMATS:
            sample = FORMATS[name](Path(root) / name.replace(".", "_"))
            data = sample.path.read_bytes()
            path = Path(root) / f"fuzzed_{sample.path.name}"

            start = time.perf_counter()
            try:
                _property(sample, path, args.examples, given, settings, HealthCheck,
                          mutated(data), one_line)()
            except AssertionError as err:
                failed.append(name)
                sys.stderr.write(f"{name}: FAILED {err}\n")
                continue
            sys.stderr.write(f"{name}: {args.examples} examples held "
                             f"({time.perf_counter() - start:.1f} s)\n")
    return 1 if failed else 0


def _property(sample, path: Path, examples: int, given, settings, health, strategy,
              one_line):
    """The property of one format: a mutated file reads or is refused in one line."""

    @settings(max_examples=examples, deadline=None, database=None,
              suppress_health_check=list(health))
    @given(strategy)
    def check(damaged: bytes) -> None:
        path.write_bytes(damaged)
        one_line(sample.read, path)

    return check


if __name__ == "__main__":
    sys.exit(main())
