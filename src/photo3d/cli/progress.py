"""Progress bars of the command line (tqdm on stderr, only when stderr is a terminal)."""

from __future__ import annotations

import sys

from photo3d.cli.options import STAGE_LABELS


class StageBar:
    """Stage-aware progress bar: the library's ``progress(stage, fraction)`` callback.

    Stages are weighted by their usual share of a ``make`` run, so the bar moves
    at a roughly even pace; ``quiet`` (or stderr not a terminal) shows nothing.

    >>> bar = StageBar(quiet=True)
    >>> bar("inpaint", 0.5); bar.close()
    """

    def __init__(self, quiet: bool) -> None:
        self.bar = None
        if not quiet:
            from tqdm import tqdm

            self.bar = tqdm(total=100, bar_format="{desc:<12}{bar}| {percentage:3.0f}% "
                            "[{elapsed}]", file=sys.stderr, leave=False,
                            disable=None)  # no bar when stderr is not a terminal
        self.weights = {"load": 1, "preprocess": 4, "ldi": 1, "inpaint": 20, "mesh": 1,
                        "save": 3, "video": 70}
        self.stage = None

    def __call__(self, stage: str, fraction: float) -> None:
        if self.bar is None:
            return
        order = list(self.weights)
        base = sum(self.weights[s] for s in order[: order.index(stage)])
        value = base + self.weights[stage] * fraction
        if stage != self.stage:
            self.stage = stage
            self.bar.set_description_str(STAGE_LABELS.get(stage, stage), refresh=False)
        self.bar.update(max(0.0, value - self.bar.n))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def count_bar(total: int, desc: str, *, quiet: bool, initial: int = 0):
    """A plain tqdm counter on stderr (``train``'s data, preparation and steps)."""
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, file=sys.stderr, leave=False,
                disable=True if quiet else None, dynamic_ncols=True)
