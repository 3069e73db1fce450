"""The refine colour net: pure functions and modules agree, the residual lands under the
hole only, and its safetensors load as the colour net."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from photo3d.errors import InputError  # noqa: E402
from photo3d.inpaint.learned import is_refine  # noqa: E402
from photo3d.nets import build_net, load_inpainting_nets, save_safetensors  # noqa: E402
from photo3d.nets.refine import GatedConv, RefineNet, compose, gated_conv  # noqa: E402
from photo3d.nets.weights import load_net, read_safetensors  # noqa: E402

TINY = dict(channels=4, levels=2, blocks=1)


def randomised(net: torch.nn.Module, seed: int = 0) -> torch.nn.Module:
    """``net`` with every parameter random (its zero-initialised head included)."""
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(torch.randn(p.shape, generator=g) * 0.3)
    return net.eval()


def inputs(b: int = 2, h: int = 16, w: int = 24, seed: int = 0) -> torch.Tensor:
    """rgb fill, edge, context, hole: context left, hole in the middle, neither right."""
    g = torch.Generator().manual_seed(seed)
    x = torch.zeros(b, 6, h, w)
    x[:, 4, :, : w // 3] = 1
    x[:, 5, :, w // 3: 2 * w // 3] = 1
    known = x[:, 4:5] + x[:, 5:6]
    x[:, :3] = torch.rand(b, 3, h, w, generator=g) * known
    x[:, 3] = (torch.rand(b, h, w, generator=g) > 0.8).float() * known[:, 0]
    return x


@pytest.mark.parametrize("stride,dilation", [(1, 1), (2, 1), (1, 2)])
def test_gated_conv_function_and_module_agree(stride, dilation):
    module = GatedConv(5, 3, 3, stride=stride, dilation=dilation)
    x = torch.rand(2, 5, 12, 12)
    c = module.conv
    by_hand = torch.nn.functional.leaky_relu(
        torch.nn.functional.conv2d(x, c.weight[:3], c.bias[:3], stride, dilation, dilation),
        0.2) * torch.sigmoid(torch.nn.functional.conv2d(x, c.weight[3:], c.bias[3:], stride,
                                                        dilation, dilation))
    torch.testing.assert_close(module(x), gated_conv(x, c.weight, c.bias, stride=stride,
                                                     padding=dilation, dilation=dilation))
    torch.testing.assert_close(module(x), by_hand)


def test_forward_is_compose_of_the_residual():
    net = randomised(RefineNet(**TINY))
    x = inputs()
    with torch.no_grad():
        torch.testing.assert_close(net(x), compose(x[:, :3], x[:, 5:6], net.residual(x)),
                                   rtol=0, atol=0)


def test_output_is_the_fill_outside_the_hole_and_changes_inside():
    net = randomised(RefineNet(**TINY), seed=1)
    x = inputs()
    with torch.no_grad():
        out = net(x)
    outside = (x[:, 5:6] == 0).expand(-1, 3, -1, -1)
    assert torch.equal(out[outside], x[:, :3][outside])  # context and the rest untouched
    inside = ~outside
    assert (out[inside] - x[:, :3][inside]).abs().mean() > 1e-3
    assert out.min() >= 0 and out.max() <= 1


def test_a_fresh_net_is_the_diffusion_fill():
    net = RefineNet(**TINY).eval()
    x = inputs()
    with torch.no_grad():
        assert torch.equal(net(x), x[:, :3])


def test_edges_false_ignores_the_edge_channel():
    net = randomised(RefineNet(**TINY, edges=False), seed=2)
    x = inputs()
    y = x.clone()
    y[:, 3] = 1 - y[:, 3]
    with torch.no_grad():
        assert torch.equal(net(x), net(y))
    net = randomised(RefineNet(**TINY, edges=True), seed=2)
    with torch.no_grad():
        assert not torch.equal(net(x), net(y))


def test_input_size_and_channels_are_checked():
    net = RefineNet(**TINY)
    with pytest.raises(ValueError, match="multiples of 4"):
        net(torch.zeros(1, 6, 10, 16))
    with pytest.raises(ValueError, match="6 input channels"):
        RefineNet(7)


def test_default_size_fits_the_weight_budget():
    net = build_net("color", arch="refine")
    params = sum(p.numel() for p in net.parameters())
    assert params * 4 <= 8e6  # <= 8 MB in float32
    assert net.input_multiple == 16 and is_refine(net)


@pytest.mark.parametrize("dtype", [None, torch.float16])
def test_safetensors_round_trip_is_recognised_as_refine(tmp_path, dtype):
    net = randomised(build_net("color", arch="refine", **TINY))
    save_safetensors(net, tmp_path / "color.safetensors", dtype=dtype)
    state, meta = read_safetensors(tmp_path / "color.safetensors")
    assert meta["photo3d_net"] == "color" and '"arch": "refine"' in meta["config"]
    assert {v.dtype for v in state.values()} == {dtype or torch.float32}
    loaded, source = load_net("color", tmp_path)
    assert isinstance(loaded, RefineNet) and source == "safetensors"
    assert loaded.config == net.config
    x = inputs()
    with torch.no_grad():
        tol = dict(rtol=0, atol=0) if dtype is None else dict(rtol=0, atol=2e-2)
        torch.testing.assert_close(loaded(x), net(x), **tol)


def test_refine_colour_net_loads_with_the_other_nets(tmp_path):
    save_safetensors(build_net("edge", width=0.125, blocks=1), tmp_path / "edge.safetensors")
    save_safetensors(build_net("depth", levels=3, width=0.125), tmp_path / "depth.safetensors")
    save_safetensors(build_net("color", arch="refine", **TINY), tmp_path / "color.safetensors")
    nets = load_inpainting_nets(tmp_path, device="cpu")
    assert is_refine(nets.color) and not is_refine(nets.depth)


def test_a_refine_file_with_wrong_shapes_is_refused_in_one_line(tmp_path):
    save_safetensors(build_net("color", arch="refine", **TINY), tmp_path / "color.safetensors")
    state, meta = read_safetensors(tmp_path / "color.safetensors")
    from safetensors.torch import save_file

    state["head.weight"] = torch.zeros(3, 1, 3, 3)
    save_file(state, str(tmp_path / "color.safetensors"), metadata=meta)
    with pytest.raises(InputError, match=r"^color.safetensors: key head.weight has shape"):
        load_net("color", tmp_path)


def test_residual_stays_finite_on_all_zero_input():
    net = randomised(RefineNet(**TINY))
    with torch.no_grad():
        assert np.isfinite(net(torch.zeros(1, 6, 8, 8)).numpy()).all()
