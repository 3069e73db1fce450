"""``photo3d train``: two steps on a tiny folder, resume, one-line errors."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from trainkit import CROP, REGION_SIZE, write_fake_vgg, write_folder

torch = pytest.importorskip("torch")

from photo3d.cli import main  # noqa: E402

TINY = ["--size", str(CROP), "--region-size", str(REGION_SIZE), "--batch", "2", "--width",
        "0.125", "--levels", "3", "--blocks", "1", "--device", "cpu", "--threads", "1"]


@pytest.fixture(autouse=True)
def one_thread(tmp_path_factory, monkeypatch):
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    cache = tmp_path_factory.mktemp("cache")
    write_fake_vgg(cache)
    monkeypatch.setenv("PHOTO3D_CACHE", str(cache))
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_folder(tmp_path_factory.mktemp("train"))


@pytest.mark.parametrize("kind", ["edge", "depth", "color"])
def test_two_steps_then_resume(folder, tmp_path, kind, capsys):
    run = tmp_path / "run"
    args = ["train", kind, "--images", str(folder / "images"), "--depth", str(folder / "depth"),
            "--out", str(run), *TINY]
    assert main([*args, "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "data: 4 photos (3 with depth)" in out and "trained 2 steps" in out
    assert {p.name for p in run.iterdir()} == {
        "checkpoints", "config.json", "data", f"{kind}.safetensors", "losses.csv", "samples"}
    assert main([*args, "--steps", "3", "-q"]) == 0
    assert capsys.readouterr().out == ""
    with open(run / "losses.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [1, 2, 3]
    assert all(np.isfinite(float(r["total"])) for r in rows)
    from photo3d.nets.weights import load_net

    net, source = load_net(kind, run)
    assert source == "safetensors" and net.config["width"] == 0.125


def test_errors_are_one_line(folder, tmp_path, capsys):
    base = ["train", "depth", "--out", str(tmp_path / "run"), *TINY, "--steps", "1"]
    cases = [
        (["--images", str(folder / "images")], "the depth net needs training photos with depth"),
        (["--images", str(tmp_path / "nope")], "does not exist"),
        (["--images", str(folder / "images"), "--depth", str(folder / "depth"),
          "--size", "60"], "multiple of 8"),
        (["--images", "builtin", "--depth", str(folder / "depth")], "brings its own depth"),
        (["--images", str(folder / "images"), "--device", "tpu9"], "unknown torch device"),
        (["--images", str(folder / "images"), "--threads", "0"], "at least 1"),
    ]
    for extra, message in cases:
        assert main([*base, *extra]) == 2
        err = capsys.readouterr().err
        assert err.startswith("photo3d: error:") and message in err, err
        assert err.count("\n") == 1


def test_edge_and_depth_nets_need_photos_with_depth(folder, tmp_path, capsys):
    """Region shapes from a shape-only map but no photo with depth: colour trains,
    depth refuses in one line."""
    args = ["--images", str(folder / "images"), "--shapes", str(folder / "depth"), *TINY,
            "--steps", "1", "-q"]
    assert main(["train", "color", "--out", str(tmp_path / "c"), *args]) == 0
    assert main(["train", "depth", "--out", str(tmp_path / "d"), *args]) == 2
    assert "the depth net needs training photos with depth" in capsys.readouterr().err


def test_colour_net_trains_on_photos_without_any_depth(tmp_path, capsys):
    """Photos only; the region shapes come from the built-in scenes."""
    photos = write_folder(tmp_path / "photos", with_depth=0, without_depth=2)
    run = tmp_path / "run"
    args = ["train", "color", "--images", str(photos / "images"), "--out", str(run), *TINY]
    assert main([*args, "--steps", "1"]) == 0
    out = capsys.readouterr().out
    assert "data: 2 photos (0 with depth)" in out and "trained 1 steps" in out
    from photo3d.nets.weights import load_net

    net, _ = load_net("color", run)
    assert net.config.get("center") is True
    assert main(["train", "depth", "--images", str(photos / "images"),
                 "--out", str(tmp_path / "d"), *TINY, "--steps", "1"]) == 2
    assert "the depth net needs training photos with depth" in capsys.readouterr().err
