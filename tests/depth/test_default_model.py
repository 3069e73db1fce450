"""Plain photos (no depth given, none embedded) get depth from the default monocular model.

No network: the default model is a tiny randomly initialised Depth Anything built
here, either named by ``PHOTO3D_DEPTH_MODEL`` or put into a Hugging Face cache under
the real default name (``depth-anything/Depth-Anything-V2-Small-hf``).
"""

from __future__ import annotations

import shutil
import sys

import numpy as np
import pytest
from test_models import tiny_depth_anything

from photo3d.cli import main
from photo3d.depth import models
from photo3d.depth.fetch import DEFAULT_MODEL, default_depth_model, fetch_model, needs_download
from photo3d.depth.sources import resolve_depth
from photo3d.errors import InputError
from photo3d.io.images import write_image

WAYS = "pass --depth FILE, --right IMAGE or --depth-model NAME"


@pytest.fixture(autouse=True)
def fresh_model_cache(monkeypatch):
    monkeypatch.delenv("PHOTO3D_DEPTH_MODEL", raising=False)
    models._load_transformers.cache_clear()
    yield
    models._load_transformers.cache_clear()


@pytest.fixture
def photo(tmp_path):
    path = tmp_path / "plain.png"
    rng = np.random.default_rng(0)
    write_image(path, rng.random((40, 56, 3)).astype(np.float32))
    return path


def offline_hub(monkeypatch, cache):
    """An offline Hugging Face hub whose cache is ``cache`` (also for child processes)."""
    from huggingface_hub import constants

    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_CACHE", str(cache))
    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", True)
    monkeypatch.setattr(constants, "HF_HUB_CACHE", str(cache))


def cache_as_default(model_folder, cache):
    """Lay ``model_folder`` out in a hub cache as the real default model's snapshot."""
    repo = cache / ("models--" + DEFAULT_MODEL.replace("/", "--"))
    commit = "0" * 40
    (repo / "refs").mkdir(parents=True)
    (repo / "refs" / "main").write_text(commit)
    shutil.copytree(model_folder, repo / "snapshots" / commit)


def test_default_model_is_depth_anything_v2_small_unless_overridden(monkeypatch):
    assert default_depth_model() == "depth-anything/Depth-Anything-V2-Small-hf"
    monkeypatch.setenv("PHOTO3D_DEPTH_MODEL", "/models/mine")
    assert default_depth_model() == "/models/mine"


def test_plain_photo_uses_the_default_model_from_the_cache_without_network(
        photo, tmp_path, monkeypatch):
    pytest.importorskip("transformers")
    cache = tmp_path / "hub"
    offline_hub(monkeypatch, cache)
    assert needs_download(DEFAULT_MODEL)
    cache_as_default(tiny_depth_anything(tmp_path / "tiny"), cache)
    assert not needs_download(DEFAULT_MODEL)
    fetch_model(DEFAULT_MODEL)  # cached: nothing to do, no network
    est = resolve_depth(photo)
    assert est.kind == "disparity" and est.depth.shape == (40, 56)
    assert est.source.startswith(f"monocular depth model {DEFAULT_MODEL} (disparity")
    assert np.isfinite(est.depth).all() and est.depth.std() > 0


def test_offline_without_the_model_gives_one_line_naming_the_three_ways(
        photo, tmp_path, monkeypatch):
    pytest.importorskip("transformers")
    offline_hub(monkeypatch, tmp_path / "empty")
    with pytest.raises(InputError) as err:
        resolve_depth(photo)
    message = str(err.value)
    assert "\n" not in message and message.endswith(WAYS)
    assert message.startswith("no depth for plain.png (no embedded depth map)")
    assert "not in the Hugging Face cache and HF_HUB_OFFLINE is set" in message
    # the old behaviour on request: refuse photos without depth
    with pytest.raises(InputError, match="no depth given"):
        resolve_depth(photo, fallback_model=None)


def test_without_the_depth_extra_the_message_names_it(photo, monkeypatch):
    monkeypatch.setitem(sys.modules, "transformers", None)
    with pytest.raises(InputError) as err:
        resolve_depth(photo)
    assert "pip install 'photo3d[depth]'" in str(err.value) and str(err.value).endswith(WAYS)


def test_unreachable_hub_is_found_out_at_once(monkeypatch, tmp_path):
    pytest.importorskip("transformers")
    import socket

    from huggingface_hub import constants

    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", False)
    monkeypatch.setattr(constants, "HF_HUB_CACHE", str(tmp_path))

    def refuse(*args, **kwargs):
        raise OSError("no route")

    monkeypatch.setattr(socket, "create_connection", refuse)
    with pytest.raises(InputError, match="is not reachable"):
        fetch_model("some/model")


def test_download_goes_through_the_given_progress_bar(monkeypatch, tmp_path):
    pytest.importorskip("transformers")
    import socket

    import huggingface_hub
    from huggingface_hub import constants
    from tqdm import tqdm

    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", False)
    monkeypatch.setattr(constants, "HF_HUB_CACHE", str(tmp_path))

    class Conn:
        def close(self):
            pass

    monkeypatch.setattr(socket, "create_connection", lambda *a, **k: Conn())
    fetched, bars = [], []

    class Bar(tqdm):
        def __init__(self, *args, **kwargs):
            bars.append(kwargs.get("desc"))
            super().__init__(*args, **{**kwargs, "disable": True})

    def fake_download(repo, filename, tqdm_class=None, **kwargs):
        fetched.append(filename)
        with tqdm_class(total=10, desc=filename) as bar:
            bar.update(10)
        return str(tmp_path / filename)

    monkeypatch.setattr(huggingface_hub, "hf_hub_download", fake_download)
    fetch_model("some/model", bar=Bar)
    assert fetched == ["config.json", "preprocessor_config.json", "model.safetensors"]
    assert bars == fetched


def test_make_and_batch_on_plain_photos_with_the_default_model(photo, tmp_path, monkeypatch,
                                                               capsys):
    pytest.importorskip("transformers")
    monkeypatch.setenv("PHOTO3D_DEPTH_MODEL", str(tiny_depth_anything(tmp_path / "tiny")))
    fast = ["--size", "64", "--no-video", "--no-glb", "--no-viewer"]
    assert main(["make", str(photo), "-o", str(tmp_path / "out"), *fast]) == 0
    err = capsys.readouterr().err
    assert "depth: monocular depth model" in err and "tiny" in err
    assert (tmp_path / "out" / "photo3d.npz").is_file()
    folder = tmp_path / "photos"
    folder.mkdir()
    photo.rename(folder / photo.name)
    assert main(["batch", str(folder), "-o", str(tmp_path / "many"), "--workers", "1",
                 *fast]) == 0
    assert "batch: 1 ok, 0 failed" in capsys.readouterr().out
    assert (tmp_path / "many" / "plain" / "photo3d.npz").is_file()
