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
