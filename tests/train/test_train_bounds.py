"""``photo3d train`` is bounded by the machine and touches only what the run wrote (issue 36,
items 5, 6, 10 and 14): a request that does not fit in memory or on the disk is one line
before any work; a read-only or full disk is one line and leaves no empty run folder;
checkpoint pruning removes only the checkpoints the run recorded writing, never a user's
folder or a symbolic link. Each test fails on the code before its fix."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import pytest
from test_robustness import snapshot
from test_train_cli import TINY, train
from trainkit import one_thread_fake_cache, write_folder

torch = pytest.importorskip("torch")

from photo3d.cli import main  # noqa: E402


@pytest.fixture(autouse=True)
def one_thread(tmp_path_factory, monkeypatch):
    yield from one_thread_fake_cache(tmp_path_factory, monkeypatch)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_folder(tmp_path_factory.mktemp("train"))


def refused(capsys, argv: list[str], root: Path, message: str) -> str:
    """Exit 2, one line holding ``message`` (returned), every file and folder under
    ``root`` as it was."""
    before = snapshot(root), sorted(str(p) for p in root.rglob("*") if p.is_dir())
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and message in err, err
    assert (snapshot(root), sorted(str(p) for p in root.rglob("*") if p.is_dir())) == before
    return err


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if the data is written or prepared."""
    def work(*args, **kwargs):
        raise AssertionError("the work started before the request was checked")

    monkeypatch.setattr("photo3d.train.prepare_data", work)
    monkeypatch.setattr("photo3d.train.write_builtin", work)


def _with(args: list[str], **values: str) -> list[str]:
    """``args`` with the value of each ``--NAME`` replaced (or added)."""
    args = list(args)
    for name, value in values.items():
        flag = "--" + name.replace("_", "-")
        if flag in args:
            args[args.index(flag) + 1] = value
        else:
            args += [flag, value]
    return args


@pytest.mark.parametrize(("values", "part"), [
    ({"size": "65536", "region_size": "65536"}, "a training step"),  # before: 21 GB
    ({"region_size": "1000000"}, "preparing a photo"),  # before: 22 GB
    ({"batch": "1000000000"}, "a training step"),  # before: 7 GB
    ({"width": "1000"}, "a training step"),  # before: a torch traceback (819 GB)
])
def test_a_request_larger_than_memory_is_one_line_before_any_work(
        folder, tmp_path, capsys, monkeypatch, no_work, values, part):
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 16e9)
    argv = _with(train(folder, tmp_path / "run", "--steps", "1"), **values)
    err = refused(capsys, argv, tmp_path, "GB of memory")
    assert f"({part}: " in err and "16.0 GB are available" in err
    assert not (tmp_path / "run").exists()


def test_builtin_scenes_beyond_the_disk_or_memory_are_one_line(tmp_path, capsys, monkeypatch,
                                                                no_work):
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 16e9)
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr("photo3d.resources.outputs.shutil.disk_usage",
                        lambda path: usage._replace(free=2 * 10**9))
    argv = ["train", "color", "--images", "builtin", "--out", str(tmp_path / "run"), *TINY,
            "--steps", "1", "-q"]
    # before: 131 MB a minute without end
    err = refused(capsys, _with(argv, builtin_scenes="100000000"), tmp_path, "GB of memory")
    assert "(region pairs: " in err and "fewer photos or --builtin-scenes" in err
    err = refused(capsys, _with(argv, builtin_scenes="2000", region_size="512"), tmp_path,
                  "but only 2.0 GB are free")
    assert not (tmp_path / "run").exists()


def _failing_mkdir(monkeypatch, under: Path, code: int) -> None:
    """``Path.mkdir`` fails with ``code`` for every folder under ``under``."""
    mkdir = Path.mkdir

    def failing(self, *args, **kwargs):
        if under in (self, *self.parents):
            raise OSError(code, os.strerror(code), str(self))
        return mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", failing)


def test_a_read_only_disk_is_one_line(folder, tmp_path, capsys, monkeypatch):
    _failing_mkdir(monkeypatch, tmp_path / "ro", errno.EROFS)
    err = refused(capsys, train(folder, tmp_path / "ro" / "run", "--steps", "1"), tmp_path,
                  "Read-only file system")  # before: a traceback from open_run
    assert "cannot create the run folder" in err


def test_a_full_disk_leaves_no_empty_run_folder(folder, tmp_path, capsys, monkeypatch):
    def full(final, suffix):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr("photo3d.files.atomic._create_temp", full)
    run = tmp_path / "new" / "run"
    refused(capsys, train(folder, run, "--steps", "1"), tmp_path, "No space left on device")
    assert not (tmp_path / "new").exists()  # before: an empty run folder


def test_a_disk_that_fills_up_while_training_is_one_line(folder, tmp_path, capsys,
                                                         monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr("photo3d.train.run._LossLog.write", full)
    run = tmp_path / "run"
    assert main(train(folder, run, "--steps", "1")) == 2
    err = capsys.readouterr().err
    assert err == f"photo3d: error: cannot write in the run folder {run}: No space left on device\n"


def test_pruning_removes_only_the_checkpoints_the_run_wrote(folder, tmp_path, capsys):
    run = tmp_path / "run"
    every = ["--checkpoint-every", "1"]
    assert main(train(folder, run, "--steps", "2", *every)) == 0
    checkpoints = run / "checkpoints"
    best = checkpoints / "step_0000002_best"  # a user's copy, with notes
    shutil.copytree(checkpoints / "step_0000002", best)
    (best / "NOTES.txt").write_text("my best one")
    outside = tmp_path / "outside"  # a user's link to a checkpoint kept elsewhere
    outside.mkdir()
    (outside / "state.json").write_text('{"step": 0}')
    (checkpoints / "step_0000000").symlink_to(outside, target_is_directory=True)
    # before: step_0000002_best pruned as step 2, then rmtree on the link: a traceback
    assert main(train(folder, run, "--steps", "4", *every)) == 0, capsys.readouterr().err
    assert sorted(p.name for p in checkpoints.iterdir()) == [
        "step_0000000", "step_0000002_best", "step_0000003", "step_0000004"]
    assert (best / "NOTES.txt").read_text() == "my best one"
    assert (outside / "state.json").is_file() and (checkpoints / "step_0000000").is_symlink()
    assert '"step_0000003"' in (run / "checkpoints.json").read_text()


def test_a_checkpoint_name_the_run_did_not_write_is_refused_before_the_work(folder, tmp_path,
                                                                            capsys):
    run = tmp_path / "run"
    assert main(train(folder, run, "--steps", "1")) == 0
    theirs = run / "checkpoints" / "step_0000002"
    theirs.mkdir()
    (theirs / "NOTES.txt").write_text("mine")  # before: replaced by the run's checkpoint
    err = refused(capsys, train(folder, run, "--steps", "2"), tmp_path, "did not write it")
    assert str(theirs) in err
