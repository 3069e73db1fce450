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


# edges="exact": the held-out shapes come from the depth alone (no photo to align its
# steps with), so make's first pass matches them when it does not align either
SIZE = Config(size=200, edges="exact",
              regions=RegionConfig(max_passes=1, border_fill="replicate"))


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


def noise_pass(side: int = 128):
    """The first pass of a ``side`` px map of uniform noise with the regions' full
    1024 px sizes: an edge every few pixels, each edge's regions 40 and 100 px deep."""
    from photo3d.stages.passes import start
    from photo3d.stages.preprocess import preprocess

    config = Config(size=None, spatial_scale=1.0)
    noise = np.random.default_rng(0).random((side, side)).astype(np.float32)
    pre = preprocess(np.zeros((side, side, 3), np.float32), noise, config=config)
    return start(pre, config=config), config


def test_a_pass_over_a_noise_depth_stays_within_its_limit():
    """Before, the regions of its 37 edges overlapped into 11 times the lattice's
    pixels of context and 21 times of patches (at 1024 px: 33 and 79 times, 6 GB)."""
    from photo3d.stages.passes import AREA_LIMIT, CONTEXT_LIMIT, SYNTHESIS_LIMIT, pass_patches

    first, config = noise_pass()
    rows, cols = first.ldi.lattice_shape
    lattice = rows * cols
    jobs = pass_patches(first, config=config, working_size=128, margin=1)
    assert len(jobs) == first.edges  # every edge is still filled, less deep
    assert sum(int(j.patch.context.sum()) for j in jobs) <= CONTEXT_LIMIT * lattice
    assert sum(j.new_y.size for j in jobs) <= SYNTHESIS_LIMIT * lattice
    assert sum(j.patch.context.size for j in jobs) <= 1.1 * AREA_LIMIT * lattice  # + margins


class Fill:
    """A backend made of a function ``fill(patches) -> results``: ``patchwise`` or not."""

    name = "fill"
    margin = 1

    def __init__(self, fill, *, patchwise=True):
        self.fill, self.patchwise = fill, patchwise

    def inpaint(self, patches, *, progress=None, pass_index=0):
        return self.fill(patches)


def test_make_gives_a_patchwise_backend_its_patches_in_batches_for_the_same_result():
    from photo3d.pipeline import fill_pass
    from photo3d.stages.passes import plan_pass

    first, config = noise_pass(64)
    calls = []

    def grey(patches):
        calls.append(len(patches))
        return [InpaintResult(np.full((*p.shape, 3), 0.5, np.float32), p.disparity + 0.01,
                              np.zeros(p.shape, np.float32)) for p in patches]

    plan = plan_pass(config, 64, margin=1)
    whole = fill_pass(first, plan, Fill(grey, patchwise=False))
    assert calls == [first.edges]
    batched = fill_pass(first, plan, Fill(grey))  # batches of half the lattice
    assert len(calls) > 2 and sum(calls[1:]) == first.edges
    assert np.array_equal(whole.ldi.disparity, batched.ldi.disparity)
    assert np.array_equal(whole.edge_pixels, batched.edge_pixels)


@pytest.mark.parametrize("threads", [1, 2])
def test_an_error_in_a_batched_pass_is_raised_from_the_pass(threads):
    # the next batch is extracted on another thread meanwhile (with a budget of 2): an
    # error of the fill or of the extraction (here the frame's) still comes out of
    # fill_pass
    from concurrent.futures import Future

    from photo3d.parallel import share
    from photo3d.pipeline import fill_pass
    from photo3d.stages.passes import plan_pass

    first, config = noise_pass(64)
    calls = []

    def grey(patches):
        calls.append(len(patches))
        return [InpaintResult(np.full((*p.shape, 3), 0.5, np.float32), p.disparity,
                              np.zeros(p.shape, np.float32)) for p in patches]

    def failing(patches):
        if len(calls) == 1:
            raise ValueError("the second batch")
        return grey(patches)

    plan = plan_pass(config, 64, margin=1)
    with share(threads), pytest.raises(ValueError, match="the second batch"):
        fill_pass(first, plan, Fill(failing))
    assert len(calls) == 1
    calls.clear()

    no_frame = Future()
    no_frame.set_exception(RuntimeError("no frame"))
    with share(threads), pytest.raises(RuntimeError, match="no frame"):
        fill_pass(first, plan, Fill(grey), frame=no_frame)  # (every context reads it)


def test_later_passes_find_no_more_edges_than_the_first_on_a_raw_disparity():
    """The motorcycle's ground truth with unknown pixels = 0 (infinitely far: holes to
    the far plane everywhere the matcher gave up). Before: edges [112, 124, 30] at
    384 px (at 1024: [354, 994, 201]), the second pass's seams between fills of one
    layer counted as edges."""
    d = scene()
    d = np.where(np.isfinite(d), d, 0.0)
    photo = photo3d.make(motorcycle().left, depth=d, config=Config(size=384))
    edges = photo.stats["edges"]
    assert len(edges) == 3 and all(b <= a for a, b in zip(edges, edges[1:], strict=False))


def test_a_first_pass_filled_while_the_frame_is_filled_gives_the_same_result():
    """``fill_pass(frame=...)``: the patches that read no border pixel are filled from
    the LDI whose frame is not filled yet, the others from the frame's; the fills
    are merged in edge order, so the result is the one of the framed LDI."""
    from concurrent.futures import Future

    from photo3d.pipeline import fill_pass
    from photo3d.stages.border import fill_border
    from photo3d.stages.passes import plan_pass, start
    from photo3d.stages.preprocess import preprocess

    config = Config(size=128)
    sample = motorcycle()
    pre = preprocess(sample.left, np.nan_to_num(scene(), posinf=0.0), config=config)
    first = start(pre, config=config)
    # a frame fill that tells the framed LDI apart: colours by position
    framed = fill_border(first.ldi, lambda color, disparity, context, synthesis: np.stack(
        np.broadcast_arrays(*np.mgrid[0:1:synthesis.shape[0] * 1j,
                                      0:1:synthesis.shape[1] * 1j], 0.5), -1), context=8)
    seen = []

    def mean_colour(patches):
        seen.extend(p.context.sum() for p in patches)
        return [InpaintResult(np.broadcast_to(p.color[p.context].mean(axis=0), (*p.shape, 3))
                              .astype(np.float32), p.disparity, np.zeros(p.shape, np.float32))
                for p in patches]

    class Frame(Future):  # the frame's LDI, noting how many patches were filled before
        def result(self, timeout=None):
            waited.append(len(seen))
            return framed

    plan = plan_pass(config, 128, margin=1)
    direct = fill_pass(replace(first, ldi=framed), plan, Fill(mean_colour))
    seen.clear()
    waited = []
    later = fill_pass(first, plan, Fill(mean_colour), frame=Frame())
    assert waited and 0 < waited[0] < len(seen)  # some patches were filled before
    for name in ("color", "disparity", "links", "y", "x", "label"):
        assert np.array_equal(getattr(direct.ldi, name), getattr(later.ldi, name)), name
    assert np.array_equal(direct.edge_pixels, later.edge_pixels)
    assert not np.array_equal(direct.ldi.color,
                              fill_pass(first, plan, Fill(mean_colour)).ldi.color)
