"""The nets reproduce the authors' models on golden vectors (tests/nets/golden/README.md).

Weights are rebuilt by the recipe, saved as plain ``.pth`` state dicts and read by the
same loader users use; the forward pass must match the authors' outputs.
"""

from __future__ import annotations

import json
import math
import zlib
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from photo3d.nets import build_net, load_inpainting_nets  # noqa: E402

GOLDEN = Path(__file__).parent / "golden"
SHARED = Path(__file__).parents[2] / ".." / "shared" / "golden"
KINDS = ("edge", "depth", "color")

if not (GOLDEN / "official_checkpoints.json").exists():
    pytest.skip(f"golden vectors missing: {GOLDEN} (copy them from shared/golden)",
                allow_module_level=True)


def recipe(keys: list) -> dict:
    """State dict made by the golden README's recipe from ``[name, shape, dtype]`` rows."""
    state = {}
    for name, shape, _ in keys:
        g = torch.Generator().manual_seed(zlib.crc32(name.encode()))
        if name.endswith("num_batches_tracked"):
            t = torch.zeros(shape, dtype=torch.int64)
        elif name.endswith("mask_conv.weight"):
            t = torch.ones(shape)
        elif name.endswith("running_var"):
            t = 1 + 0.1 * torch.rand(shape, generator=g)
        elif name.endswith("running_mean"):
            t = 0.1 * torch.randn(shape, generator=g)
        elif name.endswith("bn.weight"):
            t = 1 + 0.1 * torch.randn(shape, generator=g)
        elif name.endswith(".bias"):
            t = 0.1 * torch.randn(shape, generator=g)
        elif name.endswith(("weight_u", "weight_v")):
            v = torch.randn(shape, generator=g)
            t = v / v.norm()
        else:
            t = torch.randn(shape, generator=g) / math.sqrt(math.prod(shape) / shape[0])
        state[name] = t
    return state


@pytest.fixture(scope="module")
def spec() -> dict:
    return json.loads((GOLDEN / "official_checkpoints.json").read_text())


@pytest.fixture(scope="module")
def nets(spec, tmp_path_factory):
    folder = tmp_path_factory.mktemp("weights")
    for kind in KINDS:
        torch.save(recipe(spec[kind]["keys"]), folder / f"{kind}-model.pth")
    return load_inpainting_nets(folder, device="cpu")


@pytest.mark.parametrize("kind", KINDS)
def test_layout_is_the_authors(spec, kind):
    net = build_net(kind)
    ours = [[k, list(v.shape), str(v.dtype).removeprefix("torch.")]
            for k, v in net.state_dict().items()]
    assert ours == spec[kind]["keys"]


@pytest.mark.parametrize("kind", KINDS)
def test_forward_matches_golden(nets, spec, kind):
    x = np.load(GOLDEN / f"{kind}_input.npy")
    ref = np.load(GOLDEN / f"{kind}_output.npy")
    assert list(x.shape) == spec[kind]["input_shape"]
    with torch.inference_mode():
        out = getattr(nets, kind)(torch.from_numpy(x)).numpy()
    assert out.shape == ref.shape
    np.testing.assert_allclose(out, ref, rtol=1e-4, atol=1e-4)
    assert nets.sources[kind] == "custom .pth"  # recipe weights are not the authors' files


def test_in_repo_copy_matches_shared():
    if not SHARED.is_dir():
        pytest.skip(f"shared golden folder not present at {SHARED.resolve()}")
    for f in sorted(SHARED.glob("*.npy")) + [SHARED / "official_checkpoints.json"]:
        assert (GOLDEN / f.name).read_bytes() == f.read_bytes(), f.name
