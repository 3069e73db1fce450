"""The page's progress bar: the pipeline's ``progress(stage, fraction)`` reports
(:data:`photo3d.progress.StageProgress`) turned into one fraction of the request.

Stages are weighted by their usual share of a request on the bundled sample at
1024 px (the video dominates when there is one), so the bar moves at a roughly
even pace; it never moves back.

Example:
    >>> meter = StageMeter(videos=False)
    >>> meter("inpaint", 0.5)
    (0.36, 'inpaint')
    >>> meter("preprocess", 1.0)  # a late report of an earlier stage: the bar stays
    (0.36, 'inpaint')
"""

from __future__ import annotations

from photo3d.progress import STAGE_LABELS
from photo3d.progress import STAGES as MAKE_STAGES

STAGES = ("depth", *MAKE_STAGES[:-1], "zip", MAKE_STAGES[-1], "rezip")
"""The stages of a request, in order: ``make``'s (:data:`photo3d.progress.STAGES`) and
the UI's own ``depth``, ``zip`` and ``rezip`` (the zip again with the videos)."""

LABELS = {**STAGE_LABELS, "depth": "depth", "zip": "zip", "rezip": "zip"}
"""How the page names the stages."""

_WEIGHTS = {"depth": 2, "compile": 0, "load": 1, "preprocess": 4, "ldi": 1, "inpaint": 20,
            "mesh": 4, "save": 10, "zip": 8, "video": 70, "rezip": 8}
"""A request's shares: the zips and the save of the folder weigh more than in
:data:`photo3d.progress.STAGE_WEIGHTS` (measured on the page); ``compile`` is the
warm-up's, never a request's."""


class StageMeter:
    """``meter(stage, fraction) -> (overall fraction, label)`` for one request.

    Args:
        videos: the request renders videos (else their stage weighs nothing).
    """

    def __init__(self, *, videos: bool) -> None:
        weights = dict(_WEIGHTS)
        if not videos:
            weights["video"] = weights["rezip"] = 0
        total = sum(weights.values())
        self._start: dict[str, float] = {}
        self._share: dict[str, float] = {}
        done = 0.0
        for stage in STAGES:
            self._start[stage] = done / total
            self._share[stage] = weights[stage] / total
            done += weights[stage]
        self._value = 0.0
        self._label = LABELS["depth"]

    def __call__(self, stage: str, fraction: float) -> tuple[float, str]:
        if self._share.get(stage, 0.0) > 0:  # unknown or skipped: the bar stays
            fraction = min(max(float(fraction), 0.0), 1.0)
            value = self._start[stage] + self._share[stage] * fraction
            if value >= self._value:
                self._value, self._label = value, LABELS[stage]
        return round(self._value, 4), self._label
