"""The shapes of progress callback the library reports through (the CLI turns
them into bars; the library never prints).

Example:
    >>> seen = []
    >>> report: StageProgress = lambda stage, fraction: seen.append((stage, fraction))
    >>> report("inpaint", 0.5); seen
    [('inpaint', 0.5)]
"""

from __future__ import annotations

from collections.abc import Callable

StageProgress = Callable[[str, float], None]
"""``progress(stage, fraction)``: ``fraction`` in [0, 1] within the named stage."""

CountProgress = Callable[[int, int], None]
"""``progress(done, total)``: items (patches, frames) finished so far."""

ByteProgress = Callable[[int, int | None], None]
"""``progress(done, total)``: bytes downloaded so far; ``total`` None when unknown."""

STAGES = ("compile", "load", "preprocess", "ldi", "inpaint", "mesh", "save", "video")
"""The stages ``make`` and a save report through :data:`StageProgress`, in order.
``compile`` is the first run's only (:func:`photo3d.kernels.compile_kernels`: numba
compiling the kernels once per installation; the command line runs it before
``make``, and reports it only when something is compiled)."""

STAGE_LABELS = {"compile": "compiling, once", "load": "load", "preprocess": "preprocess",
                "ldi": "LDI", "inpaint": "inpaint", "mesh": "mesh", "save": "save",
                "video": "video"}
"""How progress bars and timing summaries name the stages."""

STAGE_WEIGHTS = {"compile": 15, "load": 1, "preprocess": 4, "ldi": 1, "inpaint": 20,
                 "mesh": 1, "save": 3, "video": 70}
"""Each stage's usual share of a ``make`` run (the bundled sample at 1024 px, four
videos; ``compile``: of the first run's), so a bar over the stages moves at a roughly
even pace."""
