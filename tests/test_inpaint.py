import numpy as np
import pytest
from conftest import exact_config, texture

import photo3d
from photo3d.errors import ConfigError
from photo3d.inpaint import get_inpainter
from photo3d.inpaint.diffusion import diffuse, diffuse_coarse, diffuse_in_place
from photo3d.structures.patch import Patch


def test_diffusion_reproduces_a_linear_ramp():
    # harmonic fill of a linear function is the function itself
    yy, xx = np.mgrid[0:30, 0:30].astype(np.float32)
    truth = (0.01 * xx + 0.02 * yy)[..., None]
    ctx = np.ones((30, 30), bool)
    ctx[8:22, 8:22] = False
    out = diffuse(truth * ctx[..., None], ctx, ~ctx, tolerance=1e-6, iterations=2000)
    before = np.mean((truth[~ctx]) ** 2)
    after = np.mean((out[~ctx] - truth[~ctx]) ** 2)
    assert after < 0.01 * before
    np.testing.assert_allclose(out[~ctx], truth[~ctx], atol=2e-3)


def test_diffusion_never_reads_outside_the_context():
    rng = np.random.default_rng(0)
    values = rng.random((20, 20, 4)).astype(np.float32)
    ctx = np.zeros((20, 20), bool)
    ctx[:, :5] = True
    syn = np.zeros((20, 20), bool)
    syn[:, 5:12] = True
    poisoned = values.copy()
    poisoned[~ctx] = 1e6  # foreground / unrelated pixels
    a = diffuse(poisoned, ctx, syn)
    b = diffuse(values, ctx, syn)
    np.testing.assert_array_equal(a, b)
    lo, hi = values[ctx].min(0), values[ctx].max(0)
    assert np.all(a[syn] >= lo - 1e-6) and np.all(a[syn] <= hi + 1e-6)
    assert not a[~ctx & ~syn].any()


@pytest.mark.parametrize("shape", [(31, 40), (30, 41)])  # odd sizes: partial blocks
def test_the_coarse_diffusion_follows_the_full_one(shape):
    # a smooth field: the half-size solve stays within a block's step of the full
    # one, keeps the context as given and reads nothing outside it
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    values = np.sin(xx / 9.0) + 0.5 * np.cos(yy / 7.0)
    ctx = np.ones(shape, bool)
    ctx[6:h - 5, 7:w - 6] = False
    syn = ~ctx
    poisoned = np.where(ctx, values, 1e6).astype(np.float32)
    coarse = diffuse_coarse(poisoned, ctx, syn)
    full = diffuse(values[..., None] * ctx[..., None], ctx, syn, tolerance=1e-6,
                   iterations=3000)[..., 0]
    assert coarse.shape == shape and coarse.dtype == np.float32
    np.testing.assert_array_equal(coarse[ctx], values[ctx])
    error = np.abs(coarse[syn] - full[syn])
    assert error.mean() < 0.1 * np.abs(full[syn]).mean() and error.max() < 0.2
    colours = diffuse_coarse(np.repeat(poisoned[..., None], 3, axis=2), ctx, syn)
    np.testing.assert_array_equal(colours[..., 1], coarse)  # (h, w, c) as (h, w)
    neither = syn.copy()
    neither[h // 2, :] = False  # pixels of neither region: left at zero
    assert not diffuse_coarse(poisoned, ctx, neither)[h // 2, 7:w - 6].any()


def _raster_sweeps(values, context, synthesis, reached, sweeps, omega):
    """Over-relaxed Gauss-Seidel sweeps in raster order, one pixel at a time (the
    kernel's arithmetic: float64 sums in the order L, R, U, D, float32 values)."""
    h, w, c = values.shape
    out = values.copy()
    for _ in range(sweeps):
        for y in range(h):
            for x in range(w):
                if not (synthesis[y, x] and reached[y, x]):
                    continue
                near = [(y + dy, x + dx) for dy, dx in ((0, -1), (0, 1), (-1, 0), (1, 0))
                        if 0 <= y + dy < h and 0 <= x + dx < w
                        and (context[y + dy, x + dx] or synthesis[y + dy, x + dx])]
                for ch in range(c):
                    total = 0.0
                    for q in near:
                        total += float(out[q][ch])
                    step = omega * (total * (1.0 / len(near)) - float(out[y, x, ch]))
                    out[y, x, ch] = np.float32(float(out[y, x, ch]) + step)
    return out


@pytest.mark.parametrize("channels", [1, 3, 4])  # the kernel's three loops
def test_the_relaxation_sweeps_are_raster_order_gauss_seidel(channels):
    # the kernel sweeps along diagonals of row bands; every value must be the one the
    # plain raster-order sweep gives, bit for bit
    rng = np.random.default_rng(channels)
    h, w = 13, 18
    ctx = rng.random((h, w)) < 0.35
    syn = ~ctx & (rng.random((h, w)) < 0.9)  # some pixels of neither region
    values = np.where(ctx[..., None], rng.random((h, w, channels)), 0).astype(np.float32)
    guess = values.copy()
    reached = diffuse_in_place(guess, ctx, syn, 0, 0.0, 1.9)  # the first guess only
    swept = guess.copy()
    diffuse_in_place(swept, ctx, syn, 6, 0.0, 1.9)
    expected = _raster_sweeps(guess, ctx, syn, reached, 6, 1.9)
    assert not np.array_equal(expected, guess)
    np.testing.assert_array_equal(swept, expected)


def test_unreachable_synthesis_gets_the_context_mean():
    v = np.zeros((5, 5, 1), np.float32)
    ctx = np.zeros((5, 5), bool)
    ctx[0, :] = True
    v[0, :, 0] = [0, 1, 2, 3, 4]
    syn = np.zeros((5, 5), bool)
    syn[4, 4] = True  # not 4-connected to the context through synthesis pixels
    assert diffuse(v, ctx, syn)[4, 4, 0] == pytest.approx(2.0)


def test_backend_interface_and_registry():
    inp = get_inpainter("diffusion")
    ctx = np.zeros((6, 6), bool)
    ctx[:, :3] = True
    patch = Patch(np.full((6, 6, 3), 0.25, np.float32) * ctx[..., None],
                  np.full((6, 6), 0.5, np.float32) * ctx, np.zeros((6, 6), np.float32),
                  ctx, ~ctx, (0, 0))
    (res,) = inp.inpaint([patch])
    assert res.color.shape == (6, 6, 3) and res.disparity.shape == (6, 6)
    np.testing.assert_allclose(res.color[~ctx], 0.25, atol=1e-3)
    np.testing.assert_allclose(res.disparity[~ctx], 0.5, atol=1e-3)
    with pytest.raises(ConfigError, match="unknown inpainter 'nope'"):
        get_inpainter("nope")


def staircase():
    # three fronto-parallel strips, nearest on the left
    d = np.ones((48, 96), np.float32)
    d[:, :32] = 3.0
    d[:, 32:64] = 2.0
    return texture(48, 96, seed=3), d


def test_staircase_layers_are_exactly_where_expected():
    img, d = staircase()
    cfg = exact_config(synthesis_iterations=8, context_iterations=16)
    photo = photo3d.make(img, depth=d, config=cfg)
    photo.ldi.check()
    layers = photo.ldi.layers()
    expected = np.ones((48, 96), int)
    expected[:, 24:32] = 2  # middle layer synthesised behind the front strip
    expected[:, 56:64] = 2  # back layer synthesised behind the middle strip
    np.testing.assert_array_equal(layers, expected)
    assert photo.stats["passes"] == 1  # flat strips: no new depth edge, one pass


def band_scene():
    # front on the left; on the right a horizontal middle band in front of the back.
    d = np.ones((80, 80), np.float32)
    d[:, :40] = 3.0
    d[30:50, 40:] = 2.0
    return texture(80, 80, seed=5), d


def test_multi_layer_inpainting_fills_behind_inpainted_layers():
    img, d = band_scene()
    once = photo3d.make(img, depth=d, config=exact_config(
        synthesis_iterations=12, context_iterations=20, max_passes=1))
    multi = photo3d.make(img, depth=d, config=exact_config(
        synthesis_iterations=12, context_iterations=20, max_passes=4))
    multi.ldi.check()
    assert multi.stats["passes"] == 2 and multi.stats["edges"][1] >= 1
    # Behind the front, in the band's rows and near the edge, all three depth layers
    # exist only after the second pass.
    region = (slice(30, 50), slice(28, 40))
    assert (once.ldi.layers()[region] < 3).any()
    assert (multi.ldi.layers()[region] == 3).all()


@pytest.mark.parametrize("scene", [staircase, band_scene])
def test_layers_at_a_position_are_distinct_and_behind_the_input(scene):
    img, d = scene()
    photo = photo3d.make(img, depth=d, config=exact_config(synthesis_iterations=12,
                                                           context_iterations=20))
    ldi = photo.ldi
    h, w = d.shape
    # the input pixels are the first H*W and are always the nearest at their position
    starts, order = ldi.position_index()
    for p in range(h * w):
        members = order[starts[p]:starts[p + 1]]
        disp = np.sort(ldi.disparity[members])
        assert ldi.disparity[p] == disp[-1]
        assert np.all(np.diff(disp) >= 0.04)
