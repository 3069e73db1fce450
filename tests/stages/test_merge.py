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


def fills_at(*pixels):
    """``merge_fills``' fills, one per job: ``(x, disparity)`` new pixels of a 1 x 2
    lattice whose photo is a near plane (0.9) at both positions."""
    from photo3d.stages.merge import Fill

    out = []
    for job in pixels:
        xs = np.array([x for x, _ in job], np.int32)
        none = np.zeros(0, np.int64)
        out.append(Fill(np.zeros(xs.size, np.int32), xs, np.full((xs.size, 3), 0.5, np.float32),
                        np.array([d for _, d in job], np.float32), np.zeros(xs.size, bool),
                        none, np.zeros((0, 3), np.float32), np.zeros(0, np.float32)))
    return out


def near_plane():
    return from_image(np.zeros((1, 2, 3), np.float32), np.full((1, 2), 0.9, np.float32))


def test_a_new_pixel_is_an_edge_only_where_the_next_pass_can_fill_behind_its_neighbour():
    """Fill A ends at x = 0 (0.3); at x = 1 fill B is nearer (0.6). The next pass can
    continue A's layer at x = 1 behind B: A's pixel is an edge. When fill C already
    holds x = 1 behind A's depth (0.1), no pass may put A's layer there (the regions'
    rule: every pixel at a position must be nearer): before, A's pixel was an edge all
    the same, an edge that grows nothing (on the motorcycle's raw disparity, 60 % of the
    second pass's edges)."""
    from photo3d.stages.merge import merge_fills

    from_merge = dict(label=2, threshold=THR, min_edge_length=1)
    ldi = near_plane()
    behind_b = merge_fills(ldi, fills_at([(0, 0.3)], [(1, 0.6)]), **from_merge)
    assert behind_b.edge_pixels.tolist() == [ldi.size]  # A's new pixel
    covered = merge_fills(ldi, fills_at([(0, 0.3)], [(1, 0.6)], [(1, 0.1)]), **from_merge)
    assert covered.added == 3
    assert covered.edge_pixels.tolist() == [ldi.size + 2]  # C's: it may go on behind A


def test_a_pass_hands_on_at_most_max_edges_the_longest():
    d = np.full((24, 24), 0.9, np.float32)
    d[:, :12] = 0.1
    ldi = from_image(np.zeros((24, 24, 3), np.float32), d)
    from photo3d.stages.merge import Fill, merge_fills

    def column(x, rows, disparity):
        n = len(rows)
        return Fill(np.array(rows, np.int32), np.full(n, x, np.int32),
                    np.full((n, 3), 0.5, np.float32), np.full(n, disparity, np.float32),
                    np.zeros(n, bool), np.zeros(0, np.int64), np.zeros((0, 3), np.float32),
                    np.zeros(0, np.float32))

    # two fills behind the near half, each ending on a nearer fill: edges of 6 and 3 px
    far_long, near_long = column(14, range(0, 6), 0.2), column(15, range(0, 6), 0.6)
    far_short, near_short = column(14, range(10, 13), 0.2), column(15, range(10, 13), 0.6)
    fills = [far_long, near_long, far_short, near_short]
    kw = dict(label=2, threshold=THR, min_edge_length=1)
    both = merge_fills(ldi, fills, **kw)
    assert np.diff(both.edge_ptr).tolist() in ([6, 3], [3, 6])
    one = merge_fills(ldi, fills, **kw, max_edges=1)
    assert np.diff(one.edge_ptr).tolist() == [6]


def test_a_pass_at_the_ldi_limit_keeps_each_fills_nearest_pixels_and_hands_on_no_edges():
    """Two fills behind the near half, each a row growing away from the edge (their
    pixels in the order the synthesis region grew); room for half of them."""
    from photo3d.stages.merge import Fill, merge_fills

    d = np.full((4, 24), 0.9, np.float32)
    ldi = from_image(np.zeros((4, 24, 3), np.float32), d)

    def row(y, disparity):
        xs = np.arange(12, 16, dtype=np.int32)
        return Fill(np.full(4, y, np.int32), xs, np.full((4, 3), 0.5, np.float32),
                    np.full(4, disparity, np.float32), np.zeros(4, bool),
                    np.zeros(0, np.int64), np.zeros((0, 3), np.float32), np.zeros(0, np.float32))

    fills = [row(0, 0.2), row(1, 0.6)]  # the far row ends on the near one: an edge
    kw = dict(label=2, threshold=THR, min_edge_length=1)
    assert merge_fills(ldi, fills, **kw).edge_ptr.size > 1
    half = merge_fills(ldi, fills, **kw, room=4)
    assert half.added == 4 and half.edge_ptr.size == 1
    new = half.ldi.y[ldi.size:].tolist(), half.ldi.x[ldi.size:].tolist()
    assert sorted(zip(*new, strict=True)) == [(0, 12), (0, 13), (1, 12), (1, 13)]


def test_the_merge_hands_on_the_merged_ldis_position_index():
    # the next pass starts from it instead of sorting every pixel again
    ldi, jobs = one_job()
    job = jobs[0]
    kw = dict(label=2, threshold=THR, min_edge_length=3, clamp=False)
    once = merge(ldi, jobs, [result(job, stepped(job, 12))], **kw)
    # a second layer at the same positions, farther still: two new pixels per position
    twice = merge(once.ldi, jobs, [result(job, np.full(job.patch.shape, 0.02))], **kw)
    assert twice.added == job.new_y.size and once.added == job.new_y.size
    for m in (once, twice):
        for mine, sorted_again in zip(m.index, m.ldi.position_index(), strict=True):
            np.testing.assert_array_equal(mine, sorted_again)
