"""Training data: folders, region pairs from depth, pasting onto other photos."""

from __future__ import annotations

import numpy as np
import pytest
from trainkit import CROP, REGION_SIZE, write_folder

torch = pytest.importorskip("torch")

from photo3d.errors import InputError  # noqa: E402
from photo3d.inpaint.base import Patch  # noqa: E402
from photo3d.inpaint.learned import LearnedInpainter  # noqa: E402
from photo3d.nets import InpaintingNets  # noqa: E402
from photo3d.train import (  # noqa: E402
    RegionPair,
    find_training_files,
    make_batch,
    make_sample,
    prepare_data,
)
from photo3d.train.samples import place_pair  # noqa: E402


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_folder(tmp_path_factory.mktemp("train"), with_depth=4, without_depth=2)


@pytest.fixture(scope="module")
def data(folder):
    files = find_training_files(folder / "images", depth=folder / "depth")
    return prepare_data(files, crop=CROP, region_size=REGION_SIZE)


def test_folder_matches_depth_by_stem_and_lists_shape_only_maps(folder, tmp_path):
    shapes = tmp_path / "shapes"
    shapes.mkdir()
    (shapes / "extra.npy").write_bytes((folder / "depth" / "photo0.png").read_bytes())
    files = find_training_files(folder / "images", depth=folder / "depth", shapes=shapes)
    assert [f.name for f in files] == [f"photo{i}" for i in range(6)] + ["extra"]
    assert [f.depth is not None for f in files] == [True] * 4 + [False] * 2 + [True]
    assert files[-1].image is None
    with pytest.raises(InputError, match="does not exist"):
        find_training_files(folder / "nothing")
    with pytest.raises(InputError, match="no photos"):
        find_training_files(folder / "depth" / "..", depth=None)


def test_at_most_three_disjoint_pairs_per_image(data):
    sources = [p.source for p in data.pool]
    assert set(sources) == {0, 1, 2, 3}  # every photo with depth, none without
    assert max(np.bincount(sources)) <= 3
    for p in data.pool:
        assert p.context.shape == p.synthesis.shape
        assert p.context.any() and p.synthesis.any() and not (p.context & p.synthesis).any()


def test_the_cache_is_reused_and_rebuilt_when_options_change(folder, tmp_path):
    files = find_training_files(folder / "images", depth=folder / "depth")
    calls = []
    a = prepare_data(files, crop=CROP, region_size=REGION_SIZE, cache=tmp_path / "c")
    b = prepare_data(files, crop=CROP, region_size=REGION_SIZE, cache=tmp_path / "c",
                     progress=lambda stage, f: calls.append(f))
    assert calls == [1.0]  # reused: nothing recomputed
    assert len(a.pool) == len(b.pool)
    for p, q in zip(a.pool, b.pool, strict=True):
        assert (p.context == q.context).all() and (p.synthesis == q.synthesis).all()
    np.testing.assert_allclose(a.target(0).image, b.target(0).image, atol=0.5 / 255)
    c = prepare_data(files, crop=CROP, region_size=96, cache=tmp_path / "c")
    assert max(c.target(0).image.shape[:2]) == 96


def test_shape_only_maps_give_shapes_but_never_pixels(folder, tmp_path):
    files = find_training_files(folder / "images", shapes=folder / "depth")
    data = prepare_data(files, crop=CROP, region_size=REGION_SIZE)
    assert len(data) == 6 and not data.has_depth.any()
    assert min(p.source for p in data.pool) >= len(data)  # sources after the photos
    s = make_sample(data, "color", size=CROP, rng=np.random.default_rng(0))
    assert s.target_index < len(data) and s.source_index >= len(data)
    with pytest.raises(InputError, match="needs training photos with depth"):
        data.check("depth")


@pytest.mark.parametrize("kind", ["edge", "depth", "color"])
def test_samples_paste_shapes_of_another_image_and_hide_the_synthesis(data, kind):
    batch = make_batch(data, kind, size=CROP, batch=12, seed=3, step=1)
    channels = {"edge": 7, "depth": 4, "color": 6}[kind]
    for s in batch:
        assert s.inputs.shape == (channels, CROP, CROP) and np.isfinite(s.inputs).all()
        assert s.target_index != s.source_index
        assert not (s.context & s.synthesis).any() and not (s.context & s.hole).any()
        assert (s.hole >= s.synthesis).all()
        assert s.context.sum() >= 16 and s.synthesis.sum() >= 16
        masks = s.inputs[-2:]
        hidden = s.synthesis if kind == "edge" else s.hole
        np.testing.assert_array_equal(masks[0], s.context)
        np.testing.assert_array_equal(masks[1], hidden)
        # nothing but the masks (and the depth/colour nets' edge guide) is seen under
        # the synthesis region, and nothing at all outside the context and synthesis
        seen = s.inputs[:3] if kind != "depth" else s.inputs[:1]
        assert not seen[:, s.hole | ~s.context].any()
        if kind == "edge":
            assert not s.inputs[3:5][:, ~s.context].any()  # disparity, edges
        if kind in ("edge", "depth"):
            assert data.has_depth[s.target_index]
    assert {s.swapped for s in batch} == {True, False}  # the swap augmentation happens
    again = make_batch(data, kind, size=CROP, batch=12, seed=3, step=1)
    assert all((a.inputs == b.inputs).all() for a, b in zip(batch, again, strict=True))


def test_swap_exchanges_context_and_synthesis():
    ctx = np.zeros((40, 40), bool)
    ctx[:, :8] = True  # thin context, wide synthesis
    syn = np.zeros((40, 40), bool)
    syn[:, 8:] = True
    pair = RegionPair(ctx, syn, 0)
    c0, s0, swapped0 = place_pair(pair, 64, np.random.default_rng(1), swap=False)
    c1, s1, swapped1 = place_pair(pair, 64, np.random.default_rng(1), swap=True)
    assert not swapped0 and swapped1
    np.testing.assert_array_equal(c0, s1)
    np.testing.assert_array_equal(s0, c1)
    assert c0.sum() < s0.sum()
    assert 40 ** 2 <= c0.sum() + s0.sum() <= 52 ** 2 + 1  # resized by 1.0..1.3


class Recorder(torch.nn.Module):
    """Stub net: records its input, returns zeros with ``channels`` channels."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.channels, self.calls = channels, []

    def forward(self, x):
        self.calls.append(x.clone())
        return torch.zeros((x.shape[0], self.channels, *x.shape[2:]))


def test_inputs_are_what_the_learned_backend_feeds_its_nets(folder):
    """The backend's own wiring (stub nets) sees the same colour and depth inputs as
    training builds, for a 128 px patch (no padding, no rescaling)."""
    files = find_training_files(folder / "images", depth=folder / "depth")
    data = prepare_data(files, crop=128, region_size=128)
    with pytest.raises(InputError, match="smaller than the 256 px crop"):
        make_sample(data, "color", size=256, rng=np.random.default_rng(0))
    for kind in ("color", "depth"):
        s = make_sample(data, kind, size=128, rng=np.random.default_rng(5))
        nets = InpaintingNets(Recorder(1), Recorder(1), Recorder(3), torch.device("cpu"), {})
        ctx = s.context
        if kind == "color":
            color = np.moveaxis(s.target, 0, 2) * ctx[..., None]
            disparity = np.zeros(ctx.shape, np.float32)
            edges = s.inputs[3] * ctx
        else:
            color = np.zeros((*ctx.shape, 3), np.float32)
            edges = s.inputs[1] * ctx
            # disparity from the target log depth: z = exp(target + mean), d = 1 / (3 z)
            mean = float(np.log(1 / (3 * 1.0)))  # any mean works: inputs are zero-mean
            disparity = (1 / (3 * np.exp(s.target[0] + mean))).astype(np.float32) * ctx
        patch = Patch(color.astype(np.float32), disparity, edges.astype(np.float32), ctx,
                      s.synthesis, (0, 0))
        LearnedInpainter(nets=nets, edge_repeats=0).inpaint([patch])
        seen = getattr(nets, kind).calls[0][0].numpy()
        assert seen.shape == s.inputs.shape
        if kind == "color":  # edge channel: context edges only (the stub edge net adds none)
            np.testing.assert_allclose(seen[[0, 1, 2, 4, 5]], s.inputs[[0, 1, 2, 4, 5]],
                                       atol=1e-6)
            np.testing.assert_array_equal(seen[3][ctx], s.inputs[3][ctx])
        else:
            np.testing.assert_allclose(seen[0], s.inputs[0], atol=2e-5)
            np.testing.assert_array_equal(seen[2:], s.inputs[2:])


def test_edge_inputs_are_what_the_learned_backend_feeds_its_edge_net(folder):
    files = find_training_files(folder / "images", depth=folder / "depth")
    data = prepare_data(files, crop=128, region_size=128)
    checked = 0
    for seed in range(40):
        s = make_sample(data, "edge", size=128, rng=np.random.default_rng(seed))
        nets = InpaintingNets(Recorder(1), Recorder(1), Recorder(3), torch.device("cpu"), {})
        ctx = s.context
        t = data.target(s.target_index)
        color = np.moveaxis(s.inputs[:3], 0, 2)
        # the input is 1 / z over its maximum (>= 1/60 as z <= 20): d = input gives
        # 1 / z = 3 d (never below the mapping's floor) with maximum 3
        disparity = s.inputs[3].astype(np.float32)
        patch = Patch(color, disparity, s.inputs[4] * ctx, ctx, s.synthesis, (0, 0))
        LearnedInpainter(nets=nets, edge_repeats=0).inpaint([patch])
        if not nets.edge.calls:  # no context edge touches the synthesis region
            continue
        seen = nets.edge.calls[0][0].numpy()
        np.testing.assert_allclose(seen, s.inputs, atol=1e-5)
        assert t.edges is not None
        checked += 1
    assert checked >= 3


def test_regions_are_never_pasted_onto_their_own_image():
    from photo3d.train import Target, TrainingData

    ctx = np.zeros((24, 24), bool)
    ctx[:, :10] = True
    photo = Target(np.zeros((32, 32, 3), np.float32), np.zeros((32, 32), np.float32),
                   np.zeros((32, 32), bool))
    plain = Target(np.zeros((32, 32, 3), np.float32), None, None)
    pool = [RegionPair(ctx, ~ctx, 0)] * 3
    alone = TrainingData(["a"], np.array([True]), pool, [photo])
    with pytest.raises(InputError, match="other than the one image whose depth"):
        alone.check("color")
    two = TrainingData(["a", "b"], np.array([True, False]), pool, [photo, plain])
    two.check("color")
    with pytest.raises(InputError, match="needs a photo with depth other than"):
        two.check("depth")
    for seed in range(10):
        s = make_sample(two, "color", size=32, rng=np.random.default_rng(seed))
        assert (s.target_index, s.source_index) == (1, 0)


def test_photos_without_depth_take_their_region_shapes_from_the_builtin_scenes(tmp_path):
    photos = write_folder(tmp_path, with_depth=0, without_depth=2)
    files = find_training_files(photos / "images")
    assert prepare_data(files, crop=CROP, region_size=REGION_SIZE, builtin_shapes=0).pool == []
    data = prepare_data(files, crop=CROP, region_size=REGION_SIZE, builtin_shapes=3)
    sources = {p.source for p in data.pool}
    assert data.pool and sources <= {2, 3, 4}  # after the two photos: never a target
    data.check("color")
    with pytest.raises(InputError, match="needs training photos with depth"):
        data.check("edge")
    s = make_sample(data, "color", size=CROP, rng=np.random.default_rng(0))
    assert s.target_index in (0, 1) and s.source_index in sources
    assert s.synthesis.any() and not s.inputs[:3][:, s.synthesis].any()
