import numpy as np
import pytest

from photo3d.stages.edges import link_edges
from photo3d.stages.ldi import cut, from_image
from photo3d.stages.merge import merge
from photo3d.stages.patches import extract_patches
from photo3d.stages.regions import RegionSizes, find_regions
from photo3d.structures.patch import InpaintResult

THR = 0.04


def grow(ldi, ptr, pix, **sizes):
    """find_regions with the paper's context rule unless ``sizes`` says otherwise."""
    rule = dict(thin_context=0.0, context_around=False, thin_context_iterations=10)
    return find_regions(ldi, ptr, pix, RegionSizes(**{**rule, **sizes}))


def one_job(back=None):
    """A 24x24 scene: the back plane (``back``, default 0.1) left of column 12, a
    near plane (0.9) right of it; one edge, one job growing 8 px behind the near one."""
    d = np.full((24, 24), 0.9, np.float32)
    d[:, :12] = 0.1 if back is None else back
    edges = link_edges(d, threshold=THR, min_length=5)
    ldi = cut(from_image(np.full((24, 24, 3), 0.5, np.float32), d), edges.cuts)
    pix = np.nonzero(edges.labels.reshape(-1))[0]
    regions = grow(ldi, np.array([0, pix.size]), pix, synthesis_iterations=8,
                           context_iterations=8, dilation=0, threshold=THR)
    jobs = extract_patches(ldi, regions, pix, margin=2)
    assert len(jobs) == 1
    return ldi, jobs


def result(job, disparity, edges=None):
    h, w = job.patch.shape
    return InpaintResult(np.full((h, w, 3), 0.5, np.float32), disparity.astype(np.float32),
                         np.zeros((h, w), np.float32) if edges is None else edges)


def stepped(job, step_row):
    """The fill at the back plane's 0.1 above ``step_row``, 0.3 from it down."""
    h, w = job.patch.shape
    rows = np.arange(h)[:, None] + job.patch.origin[0]
    return np.broadcast_to(np.where(rows < step_row, 0.1, 0.3), (h, w))


def test_a_step_inside_one_fill_is_no_edge_unless_the_fill_puts_an_edge_there():
    ldi, jobs = one_job()
    job = jobs[0]
    kw = dict(label=2, threshold=THR, min_edge_length=3, clamp=False)
    plain = merge(ldi, jobs, [result(job, stepped(job, 12))], **kw)
    plain.ldi.check()
    assert plain.added == job.new_y.size
    assert plain.edge_ptr.size == 1  # the step is joined: one surface
    # the same step with the backend's edge along it: torn, the far side an edge
    h, w = job.patch.shape
    on_edge = np.zeros((h, w), np.float32)
    on_edge[12 - job.patch.origin[0]] = 1.0
    torn = merge(ldi, jobs, [result(job, stepped(job, 12), on_edge)], **kw)
    assert torn.edge_ptr.size == 2
    far = torn.ldi.disparity[torn.edge_pixels]
    assert np.all(torn.ldi.y[torn.edge_pixels] == 11) and np.allclose(far, 0.1)
    # before the rule every step of a fill was torn
    old = merge(ldi, jobs, [result(job, stepped(job, 12))], **kw | dict(link_fills=False))
    assert old.edge_ptr.size == 2


def test_fills_stay_within_their_contexts_depth_range():
    back = np.linspace(0.1, 0.2, 24, dtype=np.float32)[:, None]  # a ramp along y
    ldi, jobs = one_job(np.broadcast_to(back, (24, 12)))
    job = jobs[0]
    ctx = job.patch.disparity[job.patch.context]
    wild = np.full(job.patch.shape, 0.6, np.float32)  # nearer than all of its context
    wild[: job.patch.shape[0] // 2] = 0.0  # and farther
    m = merge(ldi, jobs, [result(job, wild)], label=2, threshold=THR, min_edge_length=3)
    new = m.ldi.disparity[ldi.size:]
    assert new.size == job.new_y.size
    assert new.min() == pytest.approx(ctx.min()) and new.max() == pytest.approx(ctx.max())
    off = merge(ldi, jobs, [result(job, wild)], label=2, threshold=THR, min_edge_length=3,
                clamp=False)
    assert off.ldi.disparity[ldi.size:].max() == pytest.approx(0.6)
