import numpy as np
import pytest
from conftest import two_planes

from photo3d.errors import InputError
from photo3d.io.npz import load_npz, save_npz
from photo3d.stages.border import extend_border
from photo3d.stages.edges import link_edges
from photo3d.stages.ldi import cut, from_image
from photo3d.stages.regions import RegionSizes, find_regions
from photo3d.structures.ldi import LABEL_BORDER


def grow(ldi, ptr, pix, **sizes):
    """find_regions with the paper's context rule unless ``sizes`` says otherwise."""
    rule = dict(thin_context=0.0, context_around=False, thin_context_iterations=10)
    return find_regions(ldi, ptr, pix, RegionSizes(**{**rule, **sizes}))


def planes_ldi(border=0):
    img, disp = two_planes()  # background x < 48, foreground x >= 48
    d = (disp - 1.0).astype(np.float32)
    edges = link_edges(d, threshold=0.04, min_length=5)
    ldi = extend_border(cut(from_image(img, d), edges.cuts), border)
    pix = np.nonzero(edges.labels.reshape(-1))[0]
    return ldi, edges, pix


def test_initial_ldi_is_fully_connected_and_cut_is_symmetric():
    ldi, edges, pix = planes_ldi()
    ldi.check()
    assert edges.count == 1 and np.all(ldi.x[pix] == 47)
    assert np.all(ldi.links[pix, 1] == -1)  # lost the right neighbour
    assert np.all(ldi.links[pix + 1, 0] == -1)  # and the foreground lost its left one
    inner = (ldi.x > 0) & (ldi.x < 95) & (ldi.y > 0) & (ldi.y < 63) & (ldi.x != 47) & (
        ldi.x != 48)
    assert np.all(ldi.links[inner] >= 0)


def test_regions_of_two_planes_have_the_known_extent():
    ldi, _, pix = planes_ldi()
    r = grow(ldi, np.array([0, pix.size]), pix, synthesis_iterations=6,
                     context_iterations=10, dilation=2, threshold=0.04)
    assert sorted(set(r.synthesis_x.tolist())) == list(range(48, 54))
    assert r.synthesis_x.size == 6 * 64  # every row, no duplicates
    ctx_x = ldi.x[r.context]
    assert sorted(set(ctx_x.tolist())) == list(range(38, 48))
    assert np.array_equal(np.unique(ldi.x[r.context[r.context_step < 2]]), [46, 47])
    # disjoint: no synthesis position holds a context pixel
    ctx_pos = set(zip(ldi.y[r.context].tolist(), ctx_x.tolist(), strict=True))
    syn_pos = set(zip(r.synthesis_y.tolist(), r.synthesis_x.tolist(), strict=True))
    assert not ctx_pos & syn_pos


def test_synthesis_never_enters_positions_in_front_of_it():
    # foreground square on a background: synthesis of the background edge grows
    # under the square only, never onto background positions around it.
    d = np.zeros((40, 40), np.float32)
    d[10:30, 10:30] = 1.0
    edges = link_edges(d, threshold=0.04, min_length=5)
    ldi = cut(from_image(np.zeros((40, 40, 3), np.float32), d), edges.cuts)
    pix = np.nonzero(edges.labels.reshape(-1))[0]
    order = np.argsort(edges.labels.reshape(-1)[pix], kind="stable")
    ptr = np.concatenate([[0], np.cumsum(np.bincount(edges.labels.reshape(-1)[pix])[1:])])
    r = grow(ldi, ptr, pix[order], synthesis_iterations=30, context_iterations=5,
                     dilation=0, threshold=0.04)
    assert r.synthesis_y.size > 0
    assert np.all(d[r.synthesis_y, r.synthesis_x] == 1.0)


def _edges_of(d):
    edges = link_edges(d, threshold=0.04, min_length=1)
    ldi = cut(from_image(np.zeros((*d.shape, 3), np.float32), d), edges.cuts)
    labels = edges.labels.reshape(-1)
    pix = np.nonzero(labels)[0]
    order = np.argsort(labels[pix], kind="stable")
    ptr = np.concatenate([[0], np.cumsum(np.bincount(labels[pix])[1:])])
    return ldi, ptr, pix[order]


def test_a_thin_context_takes_what_bounds_the_synthesis_at_its_depth():
    # far background seen through a 2x2 gap in a near block: the gap's edge has a
    # 4-pixel context; its synthesis grows 8 px behind the block, and the search goes
    # on through the block to the far background around it
    d = np.zeros((40, 60), np.float32)
    d[5:35, 5:35] = 1.0
    d[18:20, 18:20] = 0.0
    ldi, ptr, pix = _edges_of(d)
    kw = dict(synthesis_iterations=8, context_iterations=10, dilation=0, threshold=0.04)
    plain = grow(ldi, ptr, pix, **kw)
    thin = grow(ldi, ptr, pix, thin_context=0.5, thin_context_iterations=3, **kw)
    gap = [e for e in range(ptr.size - 1)
           if np.all(d[ldi.y[pix[ptr[e]:ptr[e + 1]]], ldi.x[pix[ptr[e]:ptr[e + 1]]]] == 0)
           and ldi.x[pix[ptr[e]]] > 10][0]

    def ctx(r, e):
        return r.context[r.context_ptr[e]:r.context_ptr[e + 1]]

    assert ctx(plain, gap).size == 4
    extra = ctx(thin, gap)[4:]
    assert extra.size > 30
    ey, ex = ldi.y[extra], ldi.x[extra]
    assert np.all(d[ey, ex] == 0.0)  # at the gap's depth, never the block
    assert np.all((ey < 5) | (ey >= 35) | (ex < 5) | (ex >= 35))  # outside the block
    assert np.all(thin.context_step[thin.context_ptr[gap] + 4:thin.context_ptr[gap + 1]] == 10)
    # the synthesis regions are the same, and the extra context is disjoint from them
    assert np.array_equal(plain.synthesis_x, thin.synthesis_x)
    assert np.array_equal(plain.synthesis_y, thin.synthesis_y)
    s = slice(thin.synthesis_ptr[gap], thin.synthesis_ptr[gap + 1])
    assert not set(zip(ey.tolist(), ex.tolist(), strict=True)) & set(
        zip(thin.synthesis_y[s].tolist(), thin.synthesis_x[s].tolist(), strict=True))
    # an edge whose context is not thin keeps it as it was
    ldi2, _, pix2 = planes_ldi()
    a, b = (grow(ldi2, np.array([0, pix2.size]), pix2, synthesis_iterations=6,
                         context_iterations=10, dilation=2, threshold=0.04, thin_context=t)
            for t in (0.0, 0.5))
    assert np.array_equal(a.context, b.context)


def test_the_context_takes_what_surrounds_the_hidden_area_at_its_depth():
    # a near bar (columns 20-29) on a background: the hidden area behind the bar is
    # bounded on the far side by background at the same depth (a second, unlinked
    # context) -- or, when that side lies farther back, by nothing that joins
    for far_side, joins in ((0.0, True), (-0.5, False)):
        d = np.zeros((24, 50), np.float32)
        d[:, 30:] = far_side
        d[:, 20:30] = 1.0
        ldi, ptr, pix = _edges_of(d)
        left = [e for e in range(ptr.size - 1) if np.all(ldi.x[pix[ptr[e]:ptr[e + 1]]] == 19)][0]
        kw = dict(synthesis_iterations=12, context_iterations=4, dilation=0, threshold=0.04,
                  thin_context_iterations=3)
        plain = grow(ldi, ptr, pix, **kw)
        around = grow(ldi, ptr, pix, context_around=True, **kw)
        xs = ldi.x[around.context[around.context_ptr[left]:around.context_ptr[left + 1]]]
        assert np.all(ldi.x[plain.context[plain.context_ptr[left]:plain.context_ptr[left + 1]]]
                      < 20)
        if joins:
            assert sorted(set(xs[xs >= 20].tolist())) == [30, 31, 32]
        else:
            assert np.all(xs < 20)
        assert np.array_equal(plain.synthesis_x, around.synthesis_x)


def test_border_extension_replicates_pixels_and_cuts():
    ldi, _, _ = planes_ldi(border=4)
    ldi.check()
    assert ldi.size == 72 * 104
    assert ldi.layers().max() == 1 and ldi.layers().min() == 1
    out = ldi.label == LABEL_BORDER
    assert out.sum() == 72 * 104 - 64 * 96
    # top border pixel above (0, 47) copies it, and the cut continues into the border
    k = np.nonzero((ldi.y == -3) & (ldi.x == 47))[0][0]
    assert ldi.disparity[k] == ldi.disparity[47]
    assert ldi.links[k, 1] == -1 and ldi.links[k, 0] >= 0


def test_npz_round_trip_is_exact(tmp_path):
    ldi, _, _ = planes_ldi(border=2)
    save_npz(ldi, tmp_path / "a.npz", meta={"hello": [1, 2]})
    back, meta = load_npz(tmp_path / "a.npz")
    assert meta == {"hello": [1, 2]}
    for name in ("y", "x", "color", "disparity", "links", "label"):
        np.testing.assert_array_equal(getattr(back, name), getattr(ldi, name))
    assert back.intrinsics == ldi.intrinsics and back.border == 2


def test_npz_stores_links_relative_and_checks_them(tmp_path):
    """Version 2 keeps links as offsets from their pixel (0 = none); hostile offsets
    pointing outside the pixels are refused like absolute ones."""
    import zipfile

    ldi, _, _ = planes_ldi(border=2)
    save_npz(ldi, tmp_path / "a.npz")
    with np.load(tmp_path / "a.npz") as f:
        stored = f["links"]
        arrays = {k: f[k] for k in f.files}
    own = np.arange(ldi.size)[:, None]
    np.testing.assert_array_equal(np.where(stored != 0, stored + own, -1), ldi.links)
    _, counts = np.unique(stored, return_counts=True)
    assert np.sort(counts)[-5:].sum() > 0.9 * stored.size  # a few offsets: deflate packs them
    arrays["links"] = stored.copy()
    arrays["links"][5, 1] = ldi.size  # 5 + size: outside
    np.savez(tmp_path / "b.npz", **arrays)
    with pytest.raises(InputError, match="links point outside"):
        load_npz(tmp_path / "b.npz")
    assert zipfile.ZipFile(tmp_path / "a.npz").getinfo("color.npy").compress_type == 0


def test_npz_loader_refuses_foreign_and_pickled_files(tmp_path):
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(InputError, match="cannot read 3D photo"):
        load_npz(tmp_path / "other.npz")
    np.savez(tmp_path / "evil.npz", header=np.array([{"x": 1}], dtype=object))
    with pytest.raises(InputError, match="cannot read 3D photo"):
        load_npz(tmp_path / "evil.npz")
    with pytest.raises(InputError, match="not found"):
        load_npz(tmp_path / "missing.npz")


def test_regions_grown_in_groups_by_two_threads_are_those_of_one_group():
    """``find_regions`` with a limit grows 1/16 of the edges at a time, two groups at
    once, each thread with its own marks: the same regions as all edges in one go."""
    from photo3d.config import Config
    from photo3d.sample import motorcycle
    from photo3d.stages.passes import region_sizes, start
    from photo3d.stages.preprocess import preprocess
    from photo3d.stages.regions import RegionLimit

    config = Config(size=160)
    d = np.nan_to_num(np.asarray(motorcycle().disparity), posinf=0.0)
    first = start(preprocess(motorcycle().left, d, config=config), config=config)
    assert first.edges >= 32  # several edges per group
    sizes = region_sizes(config, 160)
    whole = find_regions(first.ldi, first.edge_ptr, first.edge_pixels, sizes)
    big = 10**12
    grouped = find_regions(first.ldi, first.edge_ptr, first.edge_pixels, sizes,
                           limit=RegionLimit(context=big, synthesis=big, area=big))
    for name in ("context_ptr", "context", "context_step", "synthesis_ptr", "synthesis_y",
                 "synthesis_x"):
        assert np.array_equal(getattr(whole, name), getattr(grouped, name)), name
    cut_short = find_regions(first.ldi, first.edge_ptr, first.edge_pixels, sizes,
                             limit=RegionLimit(context=1, synthesis=big, area=big))
    assert cut_short.count == -(-first.edges // 16)  # stopped after the first group
    assert np.array_equal(cut_short.context, whole.context[:cut_short.context.size])
