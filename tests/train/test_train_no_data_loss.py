"""``photo3d train --out``: only a photo3d training run is resumed; nothing else is touched."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_robustness import snapshot
from trainkit import CROP, REGION_SIZE, write_fake_vgg, write_folder

torch = pytest.importorskip("torch")

from photo3d.cli import main  # noqa: E402

TINY = ["--size", str(CROP), "--region-size", str(REGION_SIZE), "--batch", "2", "--width",
        "0.125", "--levels", "3", "--device", "cpu", "--threads", "1", "-q"]


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


def train(folder: Path, run: Path, *extra: str) -> list[str]:
    return ["train", "depth", "--images", str(folder / "images"), "--depth",
            str(folder / "depth"), "--out", str(run), *TINY, *extra]


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
