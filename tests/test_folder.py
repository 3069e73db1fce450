"""photo3d.folder: MakeOptions, prepare and make_folder (one photo -> its output folder)."""

from __future__ import annotations

import dataclasses
import json
import pickle

import numpy as np
import pytest
from conftest import two_planes

import photo3d
from photo3d.config import Config
from photo3d.errors import ConfigError, InputError, OutputError
from photo3d.folder import MakeOptions, make_folder, output_bytes, prepare
from photo3d.render.animate import VideoSpec
from photo3d.render.renderer import RenderSettings
from photo3d.save_options import SaveOptions

BASE = MakeOptions(config=Config(size=None, inpainter="diffusion"))
VIDEO = (VideoSpec(path="circle", size=(32, 24), frames=2),)

# One change per MakeOptions field (and per field of its SaveOptions), and where
# config.json shows it. A field missing here fails
# test_every_option_field_changes_what_config_json_records.
CHANGES = {
    "config": ({"config": Config(size=64)}, lambda m: m["config"]["size"] == 64),
    "inpainter_options": ({"inpainter_options": {"tolerance": 0.01}},
                          lambda m: m["inpainter"]["tolerance"] == 0.01),
    "depth_kind": ({"depth_kind": "depth"}, lambda m: m["config"]["depth_kind"] == "depth"
                   and m["depth_source"] == "depth array (depth)"),
    "save.ply": ({"save": SaveOptions(ply="ascii")}, lambda m: m["save"]["ply"] == "ascii"),
    "save.glb": ({"save": SaveOptions(glb=False)},
                 lambda m: m["save"]["glb"] is None),
    "save.full_glb": ({"save": SaveOptions(full_glb=True)}, lambda m: m["save"]["glb"] == "full"),
    "save.light_error": ({"save": SaveOptions(light_error=2.0)},
                         lambda m: m["save"]["light_error"] == 2.0),
    "save.viewer": ({"save": SaveOptions(viewer=False)}, lambda m: m["save"]["viewer"] is False),
    "save.videos": ({"save": SaveOptions(videos=VIDEO)},
                    lambda m: m["save"]["videos"][0]["size"] == [32, 24]),
    "save.render_settings": ({"save": SaveOptions(videos=VIDEO,
                                                  render_settings=RenderSettings(ssaa=1))},
                             lambda m: m["save"]["render_settings"]["ssaa"] == 1),
    "save.exports": ({"save": SaveOptions(exports=("splats.spz",))},
                     lambda m: m["save"]["exports"] == ["splats.spz"]
                     and m["written"] == ["splats.spz"]),
    # recorded with splat exports only (what they change); the defaults are adaptive, 3
    "save.splats": ({"save": SaveOptions(exports=("splats.spz",), splats="dense")},
                    lambda m: m["save"]["splats"] == "dense"),
    "save.spz_version": ({"save": SaveOptions(exports=("splats.spz",), spz_version=4)},
                         lambda m: m["save"]["spz_version"] == 4),
}
NOT_RECORDED = {
    "depth_model": "the model for photos without any depth: a depth array is used here "
                   "(tests/depth/test_depth_model_option.py records it)",
    "overwrite": "where the folder may be written, not what it holds",
}


def recorded(out) -> dict:
    meta = json.loads((out / "config.json").read_text())
    return {k: v for k, v in meta.items() if k not in ("stats", "timings")}


def test_every_option_field_changes_what_config_json_records(tmp_path):
    fields = {f.name for f in dataclasses.fields(MakeOptions) if f.name != "save"}
    fields |= {f"save.{f.name}" for f in dataclasses.fields(SaveOptions)}
    assert fields == set(CHANGES) | set(NOT_RECORDED), "an option field without a check"
    img, d = two_planes(32, 48, 24)
    make_folder(img, tmp_path / "base", depth=d, options=BASE)
    base = recorded(tmp_path / "base")
    assert base["save"] == {"ply": "binary", "glb": "light", "light_error": 0.5,
                            "viewer": True, "videos": [], "render_settings": None,
                            "exports": []}
    for name, (change, shows) in CHANGES.items():
        out = tmp_path / name
        make_folder(img, out, depth=d, options=dataclasses.replace(BASE, **change))
        meta = recorded(out)
        assert meta != base and shows(meta), name


def test_make_folder_writes_what_photo_save_writes_and_reports_the_depth(tmp_path):
    img, d = two_planes(32, 48, 24)
    seen = []
    photo = make_folder(img, tmp_path / "out", depth=d, options=BASE,
                        on_depth=lambda est, image: seen.append((est.source, image.shape)))
    assert seen == [("depth array (disparity)", (32, 48, 3))]
    direct = photo3d.make(img, depth=d, config=BASE.config)
    direct.save(tmp_path / "direct")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(
        p.name for p in (tmp_path / "direct").iterdir())
    back = photo3d.load(tmp_path / "out")
    np.testing.assert_array_equal(back.ldi.color, direct.ldi.color)
    assert back.inpainter == {"name": "diffusion", "iterations": 300, "tolerance": 1e-3}
    assert back.depth_source == photo.depth_source == "depth array (disparity)"
    assert "save" in photo.timings


def test_make_folder_checks_the_output_before_the_depth_and_leaves_nothing(tmp_path):
    img, d = two_planes(32, 48, 24)
    np.save(tmp_path / "d.npy", d)
    called = []
    with pytest.raises(OutputError, match="holds the input"):
        make_folder(img, tmp_path, depth=tmp_path / "d.npy", options=BASE,
                    on_depth=lambda *a: called.append(a))
    assert not called  # refused before the depth was read
    with pytest.raises(InputError, match="aspect ratios differ"):
        make_folder(img, tmp_path / "out", depth=np.ones((10, 10)), options=BASE)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.npy"]  # nothing staged left


def test_make_options_validate_and_normalise():
    options = MakeOptions(inpainter_options={"weights": "w"},
                          save=SaveOptions(videos=list(VIDEO)))
    assert options.inpainter_options == (("weights", "w"),) and options.save.videos == VIDEO
    assert str(options.weights()) == "w" and MakeOptions().weights() is None
    with pytest.raises(ConfigError, match="ply must be"):
        SaveOptions(ply="stl")
    with pytest.raises(ConfigError, match="depth_kind must be"):
        MakeOptions(depth_kind="z")
    assert pickle.loads(pickle.dumps(options)) == options  # it travels to the workers


def test_prepare_checks_memory_and_builds_the_inpainter(monkeypatch):
    assert prepare(BASE).name == "diffusion"
    with pytest.raises(ConfigError, match="unknown inpainter"):
        prepare(MakeOptions(config=Config(inpainter="magic")))
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 100_000_000)
    with pytest.raises(ConfigError, match="--size 1024 needs at least"):
        prepare(MakeOptions())


def test_output_bytes_grows_with_the_videos_and_the_exports():
    none = output_bytes(Config(size=512))
    assert output_bytes(Config(size=512), SaveOptions(videos=VIDEO)) == none + int(
        0.02 * 2 * 32 * 24)
    splats = output_bytes(Config(size=512), SaveOptions(exports=("splats.ply", "quilt")))
    assert splats == none + (55 + 12) * 512 * 512


def test_the_photo_is_decoded_and_its_depth_prepared_once(tmp_path, monkeypatch):
    """make_folder reads the photo file once and prepares the depth once (resolve_depth
    does both; the pipeline takes its results), and the output is what photo3d.make
    makes from the same files."""
    import photo3d.depth.sources as sources
    import photo3d.pipeline as pipeline
    from photo3d.io.images import write_image

    img, d = two_planes(32, 48, 24)
    write_image(tmp_path / "p.png", img)
    np.save(tmp_path / "d.npy", d)
    calls = {"read": 0, "prepare": 0}

    def counted(name, fn):
        def wrapper(*args, **kwargs):
            calls[name] += 1
            return fn(*args, **kwargs)
        return wrapper

    monkeypatch.setattr(sources, "read_image", counted("read", sources.read_image))
    monkeypatch.setattr(sources, "prepare_depth", counted("prepare", sources.prepare_depth))
    monkeypatch.setattr(pipeline, "prepare_depth", counted("prepare", pipeline.prepare_depth))
    photo = make_folder(tmp_path / "p.png", tmp_path / "out", depth=tmp_path / "d.npy",
                        options=BASE)
    assert calls == {"read": 1, "prepare": 1}
    direct = photo3d.make(str(tmp_path / "p.png"), depth=str(tmp_path / "d.npy"),
                          config=BASE.config)
    assert np.array_equal(photo.ldi.color, direct.ldi.color)
    assert np.array_equal(photo.ldi.disparity, direct.ldi.disparity)


def test_a_photo_too_large_for_memory_is_refused_before_it_is_decoded(tmp_path, monkeypatch,
                                                                      capsys):
    # issue 45: `make --size 0` of a 13000x13000 PNG (0.5 MB) was refused only after
    # decoding it (17 s, 6.5 GB); the header's size is checked first now
    from PIL import Image

    from photo3d.cli import main
    from photo3d.io import images

    Image.new("L", (3000, 2000)).save(tmp_path / "big.png")
    np.save(tmp_path / "d.npy", np.ones((20, 30), np.float32))
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 700_000_000)

    def never(*args, **kwargs):
        raise AssertionError("the photo was decoded")

    monkeypatch.setattr(images, "_read_pixels", never)
    out = tmp_path / "out"
    assert main(["make", str(tmp_path / "big.png"), "--depth", str(tmp_path / "d.npy"),
                 "--size", "0", "-o", str(out), "--no-video", "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("photo3d: error: a 3000x2000 working size needs about ")
    assert not out.exists()
    import photo3d

    with pytest.raises(photo3d.ConfigError, match="a 3000x2000 working size needs"):
        photo3d.make(tmp_path / "big.png", depth=np.ones((20, 30)),
                     config=photo3d.Config(size=None))
