"""One pass's regions come from one place: make's first pass, the held-out benchmark's
shapes and the training pairs are the same shapes for the same input and context rule."""

from dataclasses import replace

import numpy as np
import pytest

import photo3d
from photo3d.config import Config, RegionConfig
from photo3d.eval.heldout_data import first_pass_shapes
from photo3d.sample import motorcycle
from photo3d.stages.passes import region_sizes
from photo3d.structures.patch import InpaintResult


class Recorder:
    """A backend that keeps the patches of the first pass and fills nothing."""

    name = "recorder"
    margin = 0
    later_context = 1.0

    def __init__(self, paper_context: bool):
        self.paper_context = paper_context
        self.patches = []

    def settings(self):
        return {"name": self.name}

    def inpaint(self, patches, *, progress=None, pass_index=0):
        if pass_index == 0:
            self.patches += list(patches)
        return [InpaintResult(np.zeros((*p.shape, 3), np.float32), np.zeros(p.shape, np.float32),
                              np.zeros(p.shape, np.float32)) for p in patches]


SIZE = Config(size=200, regions=RegionConfig(max_passes=1, border_fill="replicate"))


def scene() -> np.ndarray:
    """The motorcycle's ground-truth disparity (real depth edges, some reach the frame)."""
    return np.asarray(motorcycle().disparity)


@pytest.mark.parametrize("paper", [True, False])
def test_make_first_pass_and_heldout_shapes_are_the_same(paper):
    config = SIZE
    d = scene()
    image = motorcycle().left
    backend = Recorder(paper_context=paper)
    photo3d.make(image, depth=d, config=config, inpainter=backend)
    shapes = first_pass_shapes(d, source="scene", config=config, min_synthesis=0,
                               min_context=0, paper_context=paper)
    made = [(p.context, p.synthesis & ~p.context) for p in backend.patches]
    assert len(made) == len(shapes) > 1
    for (ctx, syn), shape in zip(made, shapes, strict=True):
        assert np.array_equal(ctx, shape.context)
        assert np.array_equal(syn, shape.synthesis)


def test_the_context_rule_changes_the_shapes():
    """The parameter is live: the paper's rule and photo3d's give different contexts."""
    config = SIZE
    paper, ours = (first_pass_shapes(scene(), source="s", config=config, min_synthesis=0,
                                     min_context=0, paper_context=rule) for rule in (True, False))
    assert sum(int(s.context.sum()) for s in ours) > sum(int(s.context.sum()) for s in paper)


def test_region_sizes_take_their_defaults_from_the_config():
    sizes = region_sizes(Config(), 1024)
    reg = RegionConfig()
    assert (sizes.thin_context, sizes.context_around) == (reg.thin_context, reg.context_around)
    assert sizes.thin_context_iterations == reg.thin_context_iterations
    changed = region_sizes(Config(regions=replace(reg, thin_context=0.25, context_around=False)),
                           1024)
    assert (changed.thin_context, changed.context_around) == (0.25, False)
