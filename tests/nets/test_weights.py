"""Loading the authors' checkpoints and our safetensors; every refusal names the file."""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

from photo3d.errors import InputError  # noqa: E402
from photo3d.nets import build_net, load_inpainting_nets, save_safetensors  # noqa: E402
from photo3d.nets import weights as W  # noqa: E402
from photo3d.nets.weights import load_net  # noqa: E402

SMALL = {"edge": dict(width=0.125, blocks=1), "depth": dict(levels=3, width=0.125),
         "color": dict(levels=3, width=0.125)}


def _zeros_like_authors(kind: str) -> dict:
    """A full-size state dict with the authors' keys and shapes (zeros: cheap; the
    fixed mask kernels are ones, as in the authors' files)."""
    return {k: torch.ones_like(v) if k.endswith("mask_conv.weight") else torch.zeros_like(v)
            for k, v in build_net(kind).state_dict().items()}


@pytest.fixture(scope="module")
def edge_state():
    return _zeros_like_authors("edge")


def test_wrong_shape_names_file_key_and_shapes(tmp_path):
    state = _zeros_like_authors("depth")
    state["enc_2.conv.input_conv.weight"] = torch.zeros(64, 4, 5, 5)
    torch.save(state, tmp_path / "depth-model.pth")
    with pytest.raises(InputError) as err:
        load_net("depth", tmp_path)
    assert str(err.value) == ("depth-model.pth: key enc_2.conv.input_conv.weight has shape "
                              "(64, 4, 5, 5), expected (128, 64, 5, 5)")


def test_missing_and_unexpected_keys(tmp_path, edge_state):
    state = dict(edge_state)
    del state["middle.3.conv_block.5.weight_u"]
    torch.save(state, tmp_path / "edge-model.pth")
    with pytest.raises(InputError, match=r"^edge-model.pth: missing key "
                                         r"middle.3.conv_block.5.weight_u \(expected shape "
                                         r"\(256,\)\)$"):
        load_net("edge", tmp_path)
    state = dict(edge_state, **{"decoder_3.weight": torch.zeros(1)})
    torch.save(state, tmp_path / "edge-model.pth")
    with pytest.raises(InputError, match=r"^edge-model.pth: unexpected key decoder_3.weight$"):
        load_net("edge", tmp_path)


def test_missing_folder_and_missing_file(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        load_inpainting_nets(tmp_path / "nope")
    with pytest.raises(InputError, match=r"missing edge-model.pth \(or edge.safetensors\)"):
        load_inpainting_nets(tmp_path)


@pytest.mark.parametrize("content", [os.urandom(256), b"", b"hello world"])
def test_not_a_state_dict(tmp_path, content):
    (tmp_path / "color-model.pth").write_bytes(content)
    with pytest.raises(InputError, match="^cannot read color-model.pth: not a PyTorch state "
                                         "dict"):
        load_net("color", tmp_path)


def test_a_list_of_tensors_is_not_a_state_dict(tmp_path):
    torch.save([torch.zeros(2)], tmp_path / "color-model.pth")
    with pytest.raises(InputError, match=r"not a PyTorch state dict \(holds list"):
        load_net("color", tmp_path)


class _Payload:
    """Unpickling this would create a file: weights_only loading must refuse it."""

    def __init__(self, target: Path) -> None:
        self.target = target

    def __reduce__(self):
        return (Path.touch, (self.target,))


def test_unsafe_pickle_is_refused_without_running_it(tmp_path):
    target = tmp_path / "pwned"
    torch.save({"encoder_0.1.bias": _Payload(target)}, tmp_path / "edge-model.pth")
    with pytest.raises(InputError, match=r"refused: it needs unpickling beyond tensors"):
        load_net("edge", tmp_path)
    assert not target.exists()


def test_official_versus_custom_is_logged(tmp_path, edge_state, caplog, monkeypatch):
    path = tmp_path / "edge-model.pth"
    torch.save(edge_state, path)
    with caplog.at_level(logging.INFO, logger="photo3d.nets.weights"):
        _, source = load_net("edge", tmp_path)
    assert source == "custom .pth" and "loaded custom .pth weights" in caplog.text
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    monkeypatch.setitem(W.OFFICIAL_SHA256, "edge", digest)
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="photo3d.nets.weights"):
        module, source = load_net("edge", tmp_path)
    assert source == "official" and "loaded official weights" in caplog.text
    assert not module.training


def test_safetensors_round_trip(tmp_path):
    torch.manual_seed(0)
    nets = {kind: build_net(kind, **cfg).eval() for kind, cfg in SMALL.items()}
    for kind, net in nets.items():
        # Perturb BN statistics so buffers are part of what must survive.
        for mod in net.modules():
            if isinstance(mod, torch.nn.BatchNorm2d):
                mod.running_mean.uniform_(-0.1, 0.1)
        save_safetensors(net, tmp_path / f"{kind}.safetensors")
    loaded = load_inpainting_nets(tmp_path, device="cpu")
    assert loaded.sources == {k: "safetensors" for k in SMALL}
    assert loaded.device == torch.device("cpu")
    x = torch.rand(1, 7, 32, 32)
    x[:, 5:] = (x[:, 5:] > 0.5).float()
    inputs = {"edge": x, "depth": x[:, 3:], "color": torch.cat([x[:, :3], x[:, 4:]], 1)}
    with torch.inference_mode():
        for kind, net in nets.items():
            new = getattr(loaded, kind)
            assert type(new) is type(net) and new.config == net.config
            assert torch.equal(new(inputs[kind]), net(inputs[kind]))


def test_safetensors_errors(tmp_path):
    save_safetensors(build_net("depth", **SMALL["depth"]), tmp_path / "color.safetensors")
    with pytest.raises(InputError, match="color.safetensors holds the depth net, not color"):
        load_net("color", tmp_path)
    (tmp_path / "color.safetensors").write_bytes(b"\x10\x00\x00\x00\x00\x00\x00\x00{garbage")
    with pytest.raises(InputError, match="cannot read color.safetensors"):
        load_net("color", tmp_path)
    torch.save({}, tmp_path / "color-model.pth")
    with pytest.raises(InputError, match="holds both color-model.pth and color.safetensors"):
        load_net("color", tmp_path)


def test_device_defaults_to_cuda_only_when_available():
    expect = "cuda" if torch.cuda.is_available() else "cpu"
    assert W.resolve_device().type == expect
    assert W.resolve_device("cpu") == torch.device("cpu")


def test_mask_kernels_must_be_ones(tmp_path):
    state = {k: torch.ones_like(v) if k.endswith("mask_conv.weight") else v
             for k, v in build_net("color", **SMALL["color"]).state_dict().items()}
    state["dec_1A.conv.mask_conv.weight"][0, 0, 0, 0] = 0.5
    with pytest.raises(InputError, match="key dec_1A.conv.mask_conv.weight must be all ones"):
        W.check_state_dict(state, build_net("color", **SMALL["color"]), "color.safetensors")


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_non_finite_weights_are_refused(tmp_path, value):
    """A NaN weight would fill every hole with NaN colours: a 3D photo photo3d's own
    reader then refuses."""
    net = build_net("depth", **SMALL["depth"])
    with torch.no_grad():
        net.dec_1.conv.input_conv.weight[0, 0, 0, 0] = value
    save_safetensors(net, tmp_path / "depth.safetensors")
    with pytest.raises(InputError, match=r"^depth.safetensors: key dec_1.conv.input_conv.weight "
                                         r"holds NaN or infinite values$"):
        load_net("depth", tmp_path)


@pytest.mark.parametrize("config, message", [
    ({"width": 1e6}, r"^edge.safetensors: missing key middle.1.conv_block.1.weight_orig "
                     r"\(expected shape \(256000000, 256000000, 3, 3\)\) \(and \d+ more"),
    ({"width": 1e12}, r"^edge.safetensors: bad architecture metadata \(Storage size"),
    ({"width": 0.125, "blocks": 2000}, r"^edge.safetensors: bad architecture metadata "
                                       r"\(blocks 2000, but the file holds \d+ tensors\)$"),
])
def test_metadata_cannot_ask_for_a_huge_net(tmp_path, config, message):
    """The architecture in a file's metadata is checked against the file's tensors
    before any memory is taken: a few bytes of JSON asked for terabytes (or hours)."""
    from safetensors.torch import save_file

    state = build_net("edge", **SMALL["edge"]).state_dict()
    save_file(state, str(tmp_path / "edge.safetensors"),
              metadata={"photo3d_net": "edge", "config": json.dumps(config)})
    with pytest.raises(InputError, match=message):
        load_net("edge", tmp_path)


def _deflated(path: Path) -> None:
    """Rewrite the zip ``path`` with every record compressed (a zip bomb's form)."""
    import zipfile

    with zipfile.ZipFile(path) as zin:
        records = [(info.filename, zin.read(info)) for info in zin.infolist()]
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zout:
        for name, data in records:
            zout.writestr(name, data)


def test_compressed_records_are_refused_before_torch_inflates_them(tmp_path, edge_state):
    """torch.load inflates a compressed record: 256 KB of zeros became 256 MB."""
    torch.save(edge_state, tmp_path / "edge-model.pth")
    _deflated(tmp_path / "edge-model.pth")
    with pytest.raises(InputError, match=r"^cannot read edge-model.pth: not a PyTorch state "
                                         r"dict \(its records are compressed, which "
                                         r"torch.save never does\)$"):
        load_net("edge", tmp_path)
