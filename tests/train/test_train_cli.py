"""``photo3d train``: two steps on a tiny folder, resume, one-line errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from test_robustness import snapshot
from trainkit import CROP, REGION_SIZE, one_thread_fake_cache, write_folder

torch = pytest.importorskip("torch")

from photo3d.cli import main  # noqa: E402

TINY = ["--size", str(CROP), "--region-size", str(REGION_SIZE), "--batch", "2", "--width",
        "0.125", "--levels", "3", "--blocks", "1", "--device", "cpu", "--threads", "1"]


@pytest.fixture(autouse=True)
def one_thread(tmp_path_factory, monkeypatch):
    yield from one_thread_fake_cache(tmp_path_factory, monkeypatch)


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
        "checkpoints", "checkpoints.json", "config.json", "data", f"{kind}.safetensors",
        "losses.csv", "samples"}
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
        (["--images", str(folder / "images"), "--threads", "0"], "from 1 to 1024"),
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


# --- train --out: only a photo3d training run is resumed; nothing else is touched ---

def train(folder: Path, run: Path, *extra: str) -> list[str]:
    return ["train", "depth", "--images", str(folder / "images"), "--depth",
            str(folder / "depth"), "--out", str(run), *TINY, "-q", *extra]


def refused(capsys, argv: list[str], root: Path, message: str) -> None:
    """Exit 2, one line naming ``message``, every file under ``root`` as it was."""
    before = snapshot(root)
    dirs = sorted(str(p) for p in root.rglob("*") if p.is_dir())
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and message in err, err
    assert snapshot(root) == before
    assert sorted(str(p) for p in root.rglob("*") if p.is_dir()) == dirs


def _user_folder(root: Path) -> Path:
    user = root / "mine"
    (user / "data").mkdir(parents=True)
    (user / "data" / "survey.csv").write_text("a,b\n1,2\n")
    (user / "losses.csv").write_text("step,total\n1,0.5\n")
    (user / "depth.safetensors").write_bytes(b"my weights")
    (user / "samples").mkdir()
    (user / "samples" / "step_0000001.png").write_bytes(b"my picture")
    return user


def test_a_folder_that_is_not_a_training_run_is_refused(folder, tmp_path, capsys, monkeypatch):
    def no_work(*args, **kwargs):
        raise AssertionError("the data was prepared before the folder was checked")

    monkeypatch.setattr("photo3d.train.prepare_data", no_work)
    user = _user_folder(tmp_path)
    refused(capsys, train(folder, user, "--steps", "1"), tmp_path, "not a photo3d training run")
    for config in ("not json {", '["a list"]', '{"kind": "depth", "name": "my config"}'):
        (user / "config.json").write_text(config)
        refused(capsys, train(folder, user, "--steps", "1"), tmp_path,
                "not a photo3d training run")
    (tmp_path / "file").write_text("a file")
    refused(capsys, train(folder, tmp_path / "file", "--steps", "1"), tmp_path,
            "exists and is not a folder")


def test_a_damaged_checkpoint_state_is_one_line(folder, tmp_path, capsys):
    run = tmp_path / "run"
    assert main(train(folder, run, "--steps", "1")) == 0
    state = run / "checkpoints" / "step_0000001" / "state.json"
    for text in ("{not json", '{"step": "one"}', "[]"):
        state.write_text(text)
        refused(capsys, train(folder, run, "--steps", "2"), tmp_path, "is damaged")


def test_a_diverging_run_stops_in_one_line_and_saves_nothing_of_that_step(folder, tmp_path,
                                                                          capsys):
    run = tmp_path / "run"
    assert main(train(folder, run, "--steps", "1")) == 0
    first = (run / "depth.safetensors").read_bytes()
    capsys.readouterr()
    # step 2 makes the weights about 1e30; step 3 overflows (it said "image holds NaN
    # values", from the sample grid, or saved NaN weights when a checkpoint came first)
    assert main(train(folder, run, "--steps", "4", "--lr", "1e30", "--checkpoint-every",
                      "1", "--sample-every", "100")) == 2
    err = capsys.readouterr().err
    assert err.startswith("photo3d: error: training diverged at step 3 (the ") and (
        "--lr 1e+30); nothing of that step was saved: lower --lr" in err), err
    assert err.count("\n") == 1
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == [
        "step_0000001", "step_0000002"]
    assert (run / "depth.safetensors").read_bytes() == first  # the first run's export


def test_an_interrupted_data_preparation_is_resumed(folder, tmp_path, capsys, monkeypatch):
    import photo3d.train.dataset as dataset

    prepare_one, calls = dataset._prepare_one, []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return prepare_one(*args, **kwargs)

    monkeypatch.setattr(dataset, "_prepare_one", interrupted)
    run = tmp_path / "run"
    assert main(train(folder, run, "--steps", "1")) == 130
    assert "interrupted" in capsys.readouterr().err
    assert json.loads((run / "config.json").read_text())["kind"] == "depth"  # marked as a run
    assert (run / "data" / "targets").is_dir() and not (run / "data" / "index.json").exists()
    monkeypatch.undo()
    assert main(train(folder, run, "--steps", "1")) == 0, capsys.readouterr().err
    assert (run / "depth.safetensors").is_file()
    # a file of the user's in a stale cache is never deleted
    (run / "data" / "index.json").write_text('{"signature": "stale"}')
    (run / "data" / "mine.txt").write_text("mine")
    refused(capsys, train(folder, run, "--steps", "2"), tmp_path, "mine.txt")
