"""Hostile cases found by the audit of the sweep's issue that the other files missed.

Each test fails on the code before its fix.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import test_robustness
from conftest import texture
from PIL import Image
from test_robustness import run

from photo3d.train.dataset import find_training_files, prepare_data

NOT_UTF8 = os.fsdecode(b"\xffphoto.png")
"""A file name whose bytes are not UTF-8 (Python holds it with a surrogate escape)."""


def test_training_data_of_a_photo_whose_name_is_not_utf8_is_prepared_and_cached(tmp_path):
    images = tmp_path / "images"
    images.mkdir()
    for name in (NOT_UTF8, "plain.png"):
        Image.fromarray((texture(32, 48) * 255).astype(np.uint8)).save(images / name)
    files = find_training_files(images)
    assert sorted(f.image.name for f in files) == sorted([NOT_UTF8, "plain.png"])
    options = dict(crop=32, region_size=48, builtin_shapes=0, cache=tmp_path / "cache")
    first = prepare_data(files, **options)
    again = prepare_data(files, **options)  # the cache is recognised, not rebuilt
    assert sorted(again.names) == sorted(first.names) == sorted(
        Path(n).stem for n in (NOT_UTF8, "plain.png"))
    assert (tmp_path / "cache" / "index.json").is_file()


@pytest.fixture
def photos(tmp_path, monkeypatch) -> Path:
    """``tmp/photos/{a.png, a.npy, notes.txt}``, the current folder ``tmp``."""
    return test_robustness.photos.__wrapped__(tmp_path, monkeypatch)


@pytest.fixture
def no_work(monkeypatch) -> None:
    """Fail the test if the pipeline starts (``test_robustness.no_work``)."""
    test_robustness.no_work.__wrapped__(monkeypatch)


@pytest.mark.parametrize(("text", "message"), [
    # the view direction overflowed: a warning line, then "looks straight up or down"
    ('[{"position": [0, 0, 1e308], "look_at": [0, 0, 1]}]', "within 1e+09 of the origin"),
    ('[{"position": [0, 0, 0], "look_at": [0, 0, -1e308]}]', "within 1e+09 of the origin"),
    # the time span overflowed: a warning line
    ('[{"position": [0, 0, 0], "time": -1e308}, {"position": [0, 0, 1], "time": 1e308}]',
     "increasing times"),
    # a NaN rotation: a warning line, then a message about the pose matrix
    ('[{"position": [0, 0, 0], "rotation": [NaN, 0, 0]}]', "three finite Euler angles"),
    ('[{"position": [0, 0, 0], "rotation": [Infinity, 0, 0]}]', "three finite Euler angles"),
])
def test_keyframes_with_huge_or_undefined_numbers_are_one_line(photos, capsys, no_work,
                                                               text, message):
    (photos / "path.json").write_text(text)
    run(capsys, "make", photos / "a.png", "--depth", photos / "a.npy", "-o", "out",
        "--path", photos / "path.json", "--size", "48", "-q", status=2, message=message)


@pytest.mark.parametrize("model", ["./missing_dir", "not a/valid//id"])
def test_batch_refuses_a_bad_depth_model_before_creating_its_output(photos, capsys, model):
    (photos / "a.npy").unlink()  # a photo without depth needs the model
    run(capsys, "batch", photos, "--depth-model", model, "-o", "out", "--size", "48", "-q",
        status=2, message="depth model")
    assert not (photos.parent / "out").exists()  # the refused batch left an empty folder


def test_eval_of_a_pair_whose_names_are_not_utf8_writes_its_results(tmp_path, capsys):
    from photo3d.cli import main
    from photo3d.eval.synthetic import synthetic_pair
    from photo3d.io.depth import write_pfm

    pair = synthetic_pair(1, width=64, height=48)
    stem = os.fsdecode(b"\xffleft")
    for name, img in ((f"{stem}.png", pair.left), ("right.png", pair.right)):
        Image.fromarray(np.round(img * 255).astype(np.uint8)).save(tmp_path / name)
    write_pfm(tmp_path / "disp0.pfm", pair.disparity)
    k = pair.left_camera
    (tmp_path / "calib.txt").write_text(
        f"cam0=[{k.fx} 0 {k.cx}; 0 {k.fy} {k.cy}; 0 0 1]\n"
        f"cam1=[{k.fx} 0 {k.cx}; 0 {k.fy} {k.cy}; 0 0 1]\ndoffs=0\nbaseline={pair.baseline}\n"
        "width=64\nheight=48\nndisp=32\n")
    out = tmp_path / "results"
    code = main(["eval", "--pair", str(tmp_path / f"{stem}.png"), str(tmp_path / "right.png"),
                 str(tmp_path / "disp0.pfm"), str(tmp_path / "calib.txt"), "--methods",
                 "structured", "--no-lpips", "-o", str(out), "-q"])
    assert code == 0, capsys.readouterr().err  # was a UnicodeEncodeError writing results.md
    assert "### \\xffleft" in (out / "results.md").read_text(encoding="utf-8")
    assert (out / f"grid_{stem}.png").is_file()


def test_a_photo_folder_whose_name_is_not_utf8_gets_its_viewer(photos, capsys):
    out = photos.parent / os.fsdecode(b"\xffout")  # batch names folders after the photos
    run(capsys, "make", photos / "a.png", "--depth", photos / "a.npy", "-o", out, "--size",
        "48", "--no-video", "--no-glb", "-q", status=0)  # was a UnicodeEncodeError
    assert "<title>\\xffout</title>" in (out / "viewer.html").read_text(encoding="utf-8")
