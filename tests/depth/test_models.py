"""Monocular depth through tiny, randomly initialised models built here (no download)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from photo3d.depth import models
from photo3d.depth.models import estimate_depth, model_kind, onnx_input_size
from photo3d.errors import InputError

IMAGE = (np.random.default_rng(0).random((30, 44, 3)) * 255).astype(np.uint8)


@pytest.fixture(autouse=True)
def fresh_model_cache():
    models._load_transformers.cache_clear()
    yield
    models._load_transformers.cache_clear()


def _processor(folder, size: int, mean=(0.485, 0.456, 0.406), std=(0.229, 0.224, 0.225),
               multiple: int = 14):
    """Depth Anything style (aspect kept, multiples of 14) or, with multiple=0, DPT style."""
    dpt = pytest.importorskip("transformers.models.dpt")
    # The PIL backend avoids transformers' "requires torchvision" notice (transformers >= 5).
    cls = getattr(dpt, "DPTImageProcessorPil", None) or dpt.DPTImageProcessor
    cls(size={"height": size, "width": size}, keep_aspect_ratio=multiple > 0,
        ensure_multiple_of=max(multiple, 1), image_mean=list(mean),
        image_std=list(std)).save_pretrained(folder)


def tiny_depth_anything(folder, **extra):
    t = pytest.importorskip("transformers")
    backbone = t.Dinov2Config(hidden_size=16, num_hidden_layers=4, num_attention_heads=2,
                              intermediate_size=32, patch_size=14, image_size=56,
                              out_features=["stage1", "stage2", "stage3", "stage4"],
                              reshape_hidden_states=False)
    config = t.DepthAnythingConfig(backbone_config=backbone, reassemble_hidden_size=16,
                                   neck_hidden_sizes=[8, 8, 16, 16], fusion_hidden_size=16,
                                   head_hidden_size=8, patch_size=14, **extra)
    t.AutoModelForDepthEstimation.from_config(config).save_pretrained(folder)
    _processor(folder, 56)
    return folder


def tiny_dpt(folder):
    t = pytest.importorskip("transformers")
    config = t.DPTConfig(hidden_size=16, num_hidden_layers=4, num_attention_heads=2,
                         intermediate_size=32, image_size=32, patch_size=8,
                         backbone_out_indices=[0, 1, 2, 3], neck_hidden_sizes=[8, 8, 16, 16],
                         fusion_hidden_size=16)
    t.AutoModelForDepthEstimation.from_config(config).save_pretrained(folder)
    _processor(folder, 32, mean=(0.5, 0.5, 0.5), std=(0.5, 0.5, 0.5), multiple=0)
    return folder


def test_depth_anything_folder_gives_disparity_at_image_size(tmp_path):
    folder = tiny_depth_anything(tmp_path / "da")
    depth, kind = estimate_depth(IMAGE, str(folder))
    assert kind == "disparity"
    assert depth.shape == (30, 44) and depth.dtype == np.float32
    assert np.isfinite(depth).all() and depth.min() >= 0


def test_metric_depth_anything_gives_depth_and_kind_can_be_overridden(tmp_path):
    folder = tiny_depth_anything(tmp_path / "da-metric", depth_estimation_type="metric",
                                 max_depth=20)
    assert estimate_depth(IMAGE, folder)[1] == "depth"
    assert estimate_depth(IMAGE, folder, kind="disparity")[1] == "disparity"


def test_dpt_folder_runs_and_matches_a_direct_forward_pass(tmp_path):
    torch = pytest.importorskip("torch")
    t = pytest.importorskip("transformers")
    folder = tiny_dpt(tmp_path / "dpt")
    depth, kind = estimate_depth(IMAGE.astype(np.float32) / 255, folder, device="cpu")
    assert kind == "disparity" and depth.shape == (30, 44)
    net = t.AutoModelForDepthEstimation.from_pretrained(folder).eval()
    pil = {"backend": "pil"} if int(t.__version__.split(".")[0]) >= 5 else {}
    proc = t.AutoImageProcessor.from_pretrained(folder, **pil)
    with torch.no_grad():
        pred = net(**proc(images=IMAGE, return_tensors="pt")).predicted_depth
    pred = torch.nn.functional.interpolate(pred[:, None], size=(30, 44), mode="bilinear")
    expected = pred[0, 0].numpy()
    expected = expected - min(expected.min(), 0)
    np.testing.assert_allclose(depth, expected, rtol=1e-4, atol=1e-5)


def test_folder_without_config_is_refused(tmp_path):
    pytest.importorskip("transformers")
    with pytest.raises(InputError, match="has no config.json"):
        estimate_depth(IMAGE, tmp_path)


def test_offline_and_not_cached_gives_one_line(monkeypatch, tmp_path):
    pytest.importorskip("transformers")
    from huggingface_hub import constants

    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", True)
    monkeypatch.setattr(constants, "HF_HUB_CACHE", str(tmp_path))
    with pytest.raises(InputError) as err:
        estimate_depth(IMAGE, "depth-anything/Depth-Anything-V2-Small-hf")
    message = str(err.value)
    assert "\n" not in message
    assert "not in the Hugging Face cache and HF_HUB_OFFLINE is set" in message
    assert "download it once while online" in message and "local folder" in message


def test_missing_transformers_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "transformers", None)
    with pytest.raises(InputError, match=r"needs transformers: pip install 'photo3d\[depth\]'"):
        estimate_depth(IMAGE, "some/model")


def test_missing_onnxruntime_names_the_extra(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)
    with pytest.raises(InputError, match=r"needs onnxruntime: pip install 'photo3d\[depth\]'"):
        estimate_depth(IMAGE, tmp_path / "m.onnx")


def first_channel_onnx(path, shape):
    """An ONNX model whose output is channel 0 of its input: ``(1, h, w)``."""
    onnx = pytest.importorskip("onnx")
    h = onnx.helper
    node = h.make_node("Gather", ["pixel_values", "zero"], ["depth"], axis=1)
    zero = h.make_tensor("zero", onnx.TensorProto.INT64, [], [0])
    graph = h.make_graph(
        [node], "first_channel",
        [h.make_tensor_value_info("pixel_values", onnx.TensorProto.FLOAT, shape)],
        [h.make_tensor_value_info("depth", onnx.TensorProto.FLOAT, [shape[0], shape[2], shape[3]])],
        [zero],
    )
    model = h.make_model(graph, opset_imports=[h.make_opsetid("", 17)], ir_version=8)
    onnx.checker.check_model(model)
    path.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, path)
    return path


def ramp_image(h=30, w=44):
    red = np.tile(np.linspace(0.1, 0.9, w, dtype=np.float32), (h, 1))
    return np.stack([red, np.full_like(red, 0.5), np.full_like(red, 0.2)], axis=2)


def test_onnx_fixed_shape_with_sidecar_configs(tmp_path):
    pytest.importorskip("onnxruntime")
    path = first_channel_onnx(tmp_path / "repo" / "onnx" / "model.onnx", [1, 3, 28, 42])
    (tmp_path / "repo" / "preprocessor_config.json").write_text(
        json.dumps({"image_mean": [0, 0, 0], "image_std": [1, 1, 1]}))
    (tmp_path / "repo" / "config.json").write_text(json.dumps({"model_type": "zoedepth"}))
    depth, kind = estimate_depth(ramp_image(), path)
    assert kind == "depth"  # from config.json beside the ONNX folder
    assert depth.shape == (30, 44)
    # Identity normalisation: the output is the red channel, resized twice.
    np.testing.assert_allclose(depth[:, 3:-3], ramp_image()[:, 3:-3, 0], atol=0.02)


def test_onnx_dynamic_shape_imagenet_normalisation(tmp_path):
    pytest.importorskip("onnxruntime")
    path = first_channel_onnx(tmp_path / "depth_anything_vits.onnx",
                              ["batch", 3, "height", "width"])
    depth, kind = estimate_depth(ramp_image(), path)
    assert kind == "disparity"
    expected = (ramp_image()[..., 0] - 0.485) / 0.229
    expected -= expected.min()  # negative relative disparity is shifted to >= 0
    np.testing.assert_allclose(depth[:, 3:-3], expected[:, 3:-3], atol=0.05)


def test_onnx_missing_file_and_bad_file(tmp_path):
    pytest.importorskip("onnxruntime")
    with pytest.raises(InputError, match="depth model file not found"):
        estimate_depth(IMAGE, tmp_path / "nope.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(InputError, match="cannot load ONNX depth model"):
        estimate_depth(IMAGE, bad)


def test_onnx_input_size_rule():
    assert onnx_input_size([1, 3, 518, 518], (1000, 10)) == (518, 518)
    assert onnx_input_size([None, 3, None, None], (600, 400)) == (784, 518)
    h, w = onnx_input_size(["n", 3, "h", "w"], (123, 457))
    assert h % 14 == 0 and w % 14 == 0 and min(h, w) == 518


@pytest.mark.parametrize("model_type, name, kind", [
    ("depth_anything", "depth-anything/Depth-Anything-V2-Small-hf", "disparity"),
    ("dpt", "Intel/dpt-hybrid-midas", "disparity"),
    ("dpt", "Intel/dpt-large-kitti", "depth"),
    ("zoedepth", "Intel/zoedepth-nyu-kitti", "depth"),
    ("glpn", "vinvino02/glpn-nyu", "depth"),
    ("depth_pro", "apple/DepthPro-hf", "depth"),
    (None, "depth_anything_v2_metric_hypersim.onnx", "depth"),
    (None, "midas_v21_small_256.onnx", "disparity"),
    ("something_new", "x/y", "disparity"),
])
def test_model_kind_rule(model_type, name, kind):
    assert model_kind(model_type, name)[0] == kind


def test_invalid_kind_is_refused():
    with pytest.raises(InputError, match="depth kind must be"):
        estimate_depth(IMAGE, "x.onnx", kind="inverse")
