"""Progress bars of the command line (tqdm on stderr, only when stderr is a terminal)."""

from __future__ import annotations

import sys

from photo3d.progress import STAGE_LABELS, STAGE_WEIGHTS


class StageBar:
    """Stage-aware progress bar: the library's ``progress(stage, fraction)`` callback.

    Stages are weighted by their usual share of a ``make`` run, so the bar moves
    at a roughly even pace (the ``compile`` step counts only if it is the first
    reported); ``quiet`` (or stderr not a terminal) shows nothing.

    >>> bar = StageBar(quiet=True)
    >>> bar("inpaint", 0.5); bar.close()
    """

    def __init__(self, quiet: bool) -> None:
        self.bar = None
        if not quiet:
            from tqdm import tqdm

            self.bar = tqdm(total=100, bar_format="{desc:<16}{bar}| {percentage:3.0f}% "
                            "[{elapsed}]", file=sys.stderr, leave=False,
                            disable=None)  # no bar when stderr is not a terminal
        self.weights = dict(STAGE_WEIGHTS)
        self.stage = None

    def __call__(self, stage: str, fraction: float) -> None:
        if self.bar is None:
            return
        if self.stage is None:  # the first report: with a warm cache, no compile step
            if stage != "compile":
                self.weights.pop("compile", None)
            self.bar.total = sum(self.weights.values())
        order = list(self.weights)
        base = sum(self.weights[s] for s in order[: order.index(stage)])
        value = base + self.weights[stage] * fraction
        if stage != self.stage:
            self.stage = stage
            self.bar.set_description_str(STAGE_LABELS.get(stage, stage), refresh=False)
        self.bar.update(max(0.0, value - self.bar.n))

    def note(self, label: str | None) -> None:
        """Show ``label`` instead of the stage's name (None: the stage's name again),
        e.g. while numba compiles a kernel on first use."""
        if self.bar is not None and self.stage is not None:
            self.bar.set_description_str(label or STAGE_LABELS.get(self.stage, self.stage))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def count_bar(total: int, desc: str, *, quiet: bool, initial: int = 0):
    """A plain tqdm counter on stderr (``train``'s data, preparation and steps)."""
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, file=sys.stderr, leave=False,
                disable=True if quiet else None, dynamic_ncols=True)


class PhotoBar:
    """Progress over the photos of a batch: ``progress(result, done, total)``.

    On a terminal: one bar (photos/s, ETA), failed photos written above it. Elsewhere
    (a log file, a pipe): one plain line per photo. Failures are shown even when
    ``quiet``.
    """

    def __init__(self, total: int, *, quiet: bool) -> None:
        self.quiet = quiet
        self.bar = None
        if not quiet and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="photos", unit="photo", file=sys.stderr,
                            dynamic_ncols=True, smoothing=0.1)

    def __call__(self, result, done: int, total: int) -> None:
        line = None
        if result.status == "failed" and (self.quiet or self.bar is not None):
            line = f"photo3d: failed: {result.name}: {result.error}"
        elif not self.quiet and self.bar is None:
            line = f"[{done}/{total}] {result.name}: {result.status}" + (
                f" ({result.seconds:.1f}s)" if result.status == "ok" else "") + (
                f": {result.error}" if result.status == "failed" else "")
        if line is not None:
            if self.bar is not None:
                self.bar.write(line, file=sys.stderr)
            else:
                print(line, file=sys.stderr, flush=True)
        if self.bar is not None:
            if result.status == "skipped":  # finished earlier: not in this run's rate
                self.bar.initial += 1
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def download_bar(quiet: bool):
    """A ``tqdm`` class for the depth model's download (bytes) on stderr."""
    from tqdm import tqdm

    class Download(tqdm):
        def __init__(self, *args, **kwargs):
            kwargs.pop("name", None)
            kwargs.setdefault("desc", "depth model")
            super().__init__(*args, **{**kwargs, "file": sys.stderr,
                                       "disable": True if quiet else None})

    return Download
