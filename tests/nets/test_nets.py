"""Partial convolution, spectral norm and the nets' structure (compact variants)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from torch import nn  # noqa: E402

from photo3d.nets import (  # noqa: E402
    EdgeDiscriminator,
    EdgeGenerator,
    PartialConv,
    PartialConvUNet,
    SpectralNormConv,
    partial_conv,
)
from photo3d.nets.edge import power_iteration, spectral_norm_weight  # noqa: E402


def _rand(*shape, seed=0):
    return torch.randn(*shape, generator=torch.Generator().manual_seed(seed))


def _mask(*shape, p=0.5, seed=1):
    return (torch.rand(*shape, generator=torch.Generator().manual_seed(seed)) < p).float()


@pytest.mark.parametrize("mask_channels", [1, 5])
def test_partial_conv_function_and_module_agree(mask_channels):
    pc = PartialConv(5, 7, 3, stride=2, padding=1)
    x, m = _rand(2, 5, 12, 12), _mask(2, mask_channels, 12, 12, p=0.3)
    out_m, new_m = pc(x, m)
    out_f, new_f = partial_conv(x, m, pc.input_conv.weight, pc.input_conv.bias, stride=2,
                                padding=1)
    torch.testing.assert_close(out_m, out_f)
    torch.testing.assert_close(new_m, new_f)
    assert new_m.shape == (2, 1, 6, 6)


def test_box_sum_equals_the_authors_mask_convolution():
    """The fast window count equals a full convolution with the all-ones mask kernel."""
    x, m = _rand(1, 4, 10, 10), _mask(1, 4, 10, 10, p=0.2)  # per-channel holes
    m[..., 4:, 4:] = 0  # and a hole no window reaches across
    w, b = _rand(6, 4, 5, 5, seed=2), _rand(6, seed=3)
    fast, fast_mask = partial_conv(x, m, w, b, stride=2, padding=2)
    full, full_mask = partial_conv(x, m, w, b, stride=2, padding=2,
                                   mask_weight=torch.ones(6, 4, 5, 5))
    torch.testing.assert_close(fast, full, rtol=1e-5, atol=1e-5)
    assert torch.equal(fast_mask.expand_as(full_mask), full_mask)
    assert (fast_mask == 0).any() and (fast_mask == 1).any()


def test_partial_conv_never_reads_masked_values():
    x, m = _rand(1, 3, 9, 9), _mask(1, 3, 9, 9, p=0.4)
    w = _rand(4, 3, 3, 3, seed=5)
    poisoned = torch.where(m > 0, x, torch.full_like(x, 1e6))
    a = partial_conv(x, m, w, padding=1)[0]
    b = partial_conv(poisoned, m, w, padding=1)[0]
    assert torch.equal(a, b)


def test_partial_conv_renormalises_by_the_valid_fraction():
    # Averaging kernel on a constant image: the renormalised output is the constant
    # wherever the window saw a valid pixel, plus the bias; 0 where it saw none.
    x = torch.full((1, 2, 6, 6), 3.0)
    m = torch.zeros(1, 2, 6, 6)
    m[0, 0, :2, :2] = 1  # a few valid pixels, one channel only
    m[0, 1, 0, 0] = 1
    w = torch.full((1, 2, 3, 3), 1.0 / 18)
    out, new = partial_conv(x, m, w, torch.tensor([0.5]), padding=1)
    expect_valid = torch.zeros(6, 6, dtype=torch.bool)
    expect_valid[:3, :3] = True
    assert torch.equal(new[0, 0].bool(), expect_valid)
    torch.testing.assert_close(out[0, 0][expect_valid], torch.full((9,), 3.5))
    assert (out[0, 0][~expect_valid] == 0).all()
    # One known window by hand: at (0, 0) the valid taps are 4 (ch 0) + 1 (ch 1) of 18.
    raw = (3.0 / 18) * 5
    assert out[0, 0, 0, 0].item() == pytest.approx(raw * 18 / 5 + 0.5)


def test_module_honours_a_non_ones_mask_kernel():
    pc = PartialConv(2, 3, 3, padding=1)
    state = pc.state_dict()
    state["mask_conv.weight"] = torch.full_like(state["mask_conv.weight"], 2.0)
    pc.load_state_dict(state)
    x, m = _rand(1, 2, 7, 7), _mask(1, 2, 7, 7)
    expect, _ = partial_conv(x, m, pc.input_conv.weight, pc.input_conv.bias, padding=1,
                             mask_weight=state["mask_conv.weight"])
    torch.testing.assert_close(pc(x, m)[0], expect)
    assert not torch.allclose(partial_conv(x, m, pc.input_conv.weight, pc.input_conv.bias,
                                           padding=1)[0], expect)


def test_unet_refuses_a_non_ones_mask_kernel():
    net = PartialConvUNet(4, 1, levels=2, width=0.125).eval()
    state = net.state_dict()
    state["dec_1.conv.mask_conv.weight"] = 2 * state["dec_1.conv.mask_conv.weight"]
    net.load_state_dict(state)
    with pytest.raises(ValueError, match="must be all ones"):
        net(torch.rand(1, 4, 8, 8))


@pytest.mark.parametrize("layout", ["depth", "color"])
def test_unet_ignores_pixels_outside_context_and_synthesis(layout):
    cin = 4 if layout == "depth" else 6
    net = PartialConvUNet(cin, 1 if layout == "depth" else 3, levels=3, width=0.125,
                          layout=layout).eval()
    x = torch.rand(1, cin, 32, 32)
    known = torch.zeros(32, 32)
    known[4:20, 6:30] = 1
    x[0, -2] = known * (torch.rand(32, 32) < 0.5)
    x[0, -1] = known - x[0, -2]
    poisoned = x.clone()
    poisoned[0, :-2][:, known == 0] = 123.0
    with torch.inference_mode():
        torch.testing.assert_close(net(x), net(poisoned), rtol=0, atol=0)


def test_unet_shapes_and_size_check():
    net = PartialConvUNet(6, 3, levels=4, width=0.25, layout="color").eval()
    assert net.enc_1.conv.input_conv.weight.shape == (16, 6, 7, 7)
    assert net.dec_1A.conv.input_conv.weight.shape == (3, 16 + 6, 3, 3)
    x = torch.rand(2, 6, 32, 48)
    with torch.inference_mode():
        out = net(x)
    assert out.shape == (2, 3, 32, 48) and ((out > 0) & (out < 1)).all()
    with pytest.raises(ValueError, match="multiples of 16"):
        net(torch.rand(1, 6, 24, 32))


@pytest.mark.parametrize("transposed", [False, True])
def test_spectral_norm_matches_torch_hook(transposed):
    ref = (nn.ConvTranspose2d(6, 4, 4, 2, 1) if transposed else nn.Conv2d(6, 4, 3, padding=1))
    ref = torch.nn.utils.spectral_norm(ref)
    ours = SpectralNormConv(6, 4, 4 if transposed else 3, stride=2 if transposed else 1,
                            padding=1, transposed=transposed)
    assert list(ours.state_dict()) == list(ref.state_dict())
    ours.load_state_dict(ref.state_dict())
    x = torch.rand(2, 6, 8, 8)
    # Training mode: one power iteration, buffers updated like torch's.
    torch.testing.assert_close(ours.train()(x), ref.train()(x))
    torch.testing.assert_close(ours.weight_u, ref.weight_u)
    torch.testing.assert_close(ours.weight_v, ref.weight_v)
    # Eval mode: no iteration, deterministic, buffers untouched.
    u = ours.weight_u.clone()
    torch.testing.assert_close(ours.eval()(x), ref.eval()(x))
    assert torch.equal(ours.weight_u, u)


def test_spectral_norm_weight_has_unit_norm_after_iterations():
    w = _rand(8, 3, 3, 3)
    u, v = torch.nn.functional.normalize(_rand(8, seed=1), dim=0), \
        torch.nn.functional.normalize(_rand(27, seed=2), dim=0)
    for _ in range(100):
        u, v = power_iteration(w, u, v)
    sigma = torch.linalg.matrix_norm(spectral_norm_weight(w, u, v).reshape(8, -1), ord=2)
    assert sigma.item() == pytest.approx(1.0, abs=1e-4)


def test_edge_generator_compact():
    net = EdgeGenerator(width=0.125, blocks=2).eval()
    assert list(net.state_dict())[:4] == ["encoder_0.1.bias", "encoder_0.1.weight_orig",
                                          "encoder_0.1.weight_u", "encoder_0.1.weight_v"]
    with torch.inference_mode():
        out = net(torch.rand(2, 7, 24, 32))
    assert out.shape == (2, 1, 24, 32) and ((out > 0) & (out < 1)).all()
    with pytest.raises(ValueError, match="multiples of 4"):
        net(torch.rand(1, 7, 18, 32))


def test_edge_generator_inference_forward_matches_the_autograd_forward():
    """Without autograd the edge net runs a leaner forward (in-place ReLUs, the last
    convolution split over its concatenated input): same output, no gradient path."""
    net = EdgeGenerator(width=0.25, blocks=2).eval()
    x = _rand(2, 7, 24, 32)
    ref = net(x)
    assert ref.requires_grad  # the plain forward
    with torch.inference_mode():
        lean = net(x)
    assert not lean.requires_grad
    assert torch.allclose(lean, ref.detach(), atol=1e-6)
    assert lean.std() > 0  # not a constant output


def test_edge_training_step_updates_generator_and_discriminator():
    gen, disc = EdgeGenerator(width=0.125, blocks=1), EdgeDiscriminator(1, width=0.125)
    opt = torch.optim.Adam([*gen.parameters(), *disc.parameters()], lr=1e-3)
    before = gen.decoder_2[1].weight.detach().clone()
    x, target = torch.rand(2, 7, 32, 32), (torch.rand(2, 1, 32, 32) > 0.9).float()
    for _ in range(2):
        fake = gen(x)
        scores, feats = disc(fake)
        loss = nn.functional.binary_cross_entropy(fake, target) + scores.mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert len(feats) == 5 and scores.shape == (2, 1, 2, 2)
    assert not torch.equal(before, gen.decoder_2[1].weight)
    assert np.isfinite(loss.item())


def test_a_centred_colour_net_moves_its_output_with_the_context_colour(tmp_path):
    """A centred colour net sees the context's colours minus their mean, so a
    colour shift of the whole context shifts its fill by the same amount (where not
    clamped); it keeps ``center`` through save and load."""
    from photo3d.nets import build_net, save_safetensors
    from photo3d.nets.weights import load_net

    torch.manual_seed(0)
    x = torch.zeros(2, 6, 32, 32)
    x[:, 4, :, :14] = 1  # context
    x[:, 5, :, 14:26] = 1  # synthesis
    x[:, :3] = (0.4 + 0.1 * torch.rand(2, 3, 32, 32)) * x[:, 4:5]
    shift = torch.tensor([0.1, -0.1, 0.05]).view(1, 3, 1, 1)
    moved = x.clone()
    moved[:, :3] += shift * x[:, 4:5]
    for center in (True, False):
        net = build_net("color", levels=3, width=0.125, center=center).eval()
        with torch.no_grad():
            a, b = net(x), net(moved)
        inside = (a > 0.01) & (a < 0.99) & (b > 0.01) & (b < 0.99)
        same = torch.allclose((b - a)[inside], (shift.expand_as(a))[inside], atol=1e-5)
        assert same is center
    save_safetensors(net := build_net("color", levels=3, width=0.125, center=True),
                     tmp_path / "color.safetensors")
    loaded, _ = load_net("color", tmp_path)
    assert loaded.center and loaded.config == net.config
    with pytest.raises(ValueError, match="colour net only"):
        build_net("depth", levels=3, width=0.125, center=True)
