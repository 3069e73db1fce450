"""photo3d batch never takes over, rewrites or deletes a ``batch.lock`` or ``batch.jsonl``
it did not write, and a full disk or a missing Ray is one line that leaves nothing behind
(issue 36, items 7, 10 and 14). Each test fails on the code before its fix."""

from __future__ import annotations

import errno
import os
import shutil
import sys

import pytest
from test_batch_hostile import add_photo, batch, records, tree

from photo3d.batch import lock as lock_module
from photo3d.cli import main


@pytest.fixture
def folders(tmp_path):
    """IN (photos a, b with depth maps), DEPTH, and OUT (made, empty)."""
    src, depth, out = tmp_path / "in", tmp_path / "depth", tmp_path / "out"
    for folder in (src, depth, out):
        folder.mkdir()
    for i, name in enumerate("ab"):
        add_photo(src, name, depth, seed=i)
    return src, depth, out


def refused(capsys, argv: list[str], root, message: str) -> str:
    """Exit 2, one line holding ``message``, nothing under ``root`` changed."""
    before = tree(root, leave_out=root / "none")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and message in err, err
    assert tree(root, leave_out=root / "none") == before
    return err


@pytest.mark.parametrize("text", ["my notes about this batch\n", "", "12 monkeys\n", "7\n",
                                  "4242\n"])
def test_a_lock_file_photo3d_did_not_write_is_refused_and_kept(folders, capsys, text):
    src, depth, out = folders
    (out / "batch.lock").write_text(text)  # before: taken over, then unlinked at the end
    err = refused(capsys, batch(src, depth, out), src.parent, "photo3d did not write it")
    assert str(out / "batch.lock") in err
    assert (out / "batch.lock").read_text() == text


@pytest.mark.parametrize("text", ["photo3d batch 4242\n"])
def test_the_lock_of_a_killed_batch_is_taken_over(folders, capsys, text):
    src, depth, out = folders
    (out / "batch.lock").write_text(text)  # what a batch killed with SIGKILL leaves
    (out / ".batch.lock.0123abcd.tmp").write_text(text)  # killed while creating it
    assert main(batch(src, depth, out)) == 0, capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["a", "b", "batch.jsonl"]


@pytest.mark.parametrize("lines", [
    ['{"id": 1, "label": "cat"}', '{"id": 2, "label": "dog"}', '{"id": 3, "label": "cow"}'],
    ["first note", "second note", "third note"],
    ['["a", "list"]'],
    ['{"name": "a", "status": "ok", "score": 0.9}'],
])
def test_a_manifest_photo3d_did_not_write_is_refused_and_kept(folders, capsys, lines):
    src, depth, out = folders
    (out / "batch.jsonl").write_text("\n".join(lines) + "\n")  # before: rewritten, lines gone
    err = refused(capsys, batch(src, depth, out), src.parent, "photo3d did not write this file")
    assert "line 1 is " in err and str(out / "batch.jsonl") in err


@pytest.mark.parametrize("kind", ["fifo", "socket"])
def test_a_manifest_that_is_not_a_regular_file_is_refused_and_kept(folders, capsys, kind):
    """Issue 45, defect 3: a FIFO named batch.jsonl was replaced by a regular file."""
    import socket

    src, depth, out = folders
    manifest = out / "batch.jsonl"
    if kind == "fifo":
        os.mkfifo(manifest)
    else:
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(str(manifest))
        sock.close()
    err = refused(capsys, batch(src, depth, out), src.parent, "is not a regular file")
    assert str(manifest) in err
    assert not manifest.is_file() and manifest.exists()


def test_a_manifest_cut_short_by_a_crash_is_still_photo3ds(folders, capsys):
    src, depth, out = folders
    assert main(batch(src, depth, out)) == 0
    manifest = out / "batch.jsonl"
    manifest.write_text(manifest.read_text().splitlines()[0] + '\n{"name": "b", "sta')
    shutil.rmtree(out / "b")  # as if the crash came before it was finished
    assert main(batch(src, depth, out)) == 0
    assert "1 bad line(s) left out (line 2: not JSON)" in capsys.readouterr().err
    assert [(r["name"], r["status"]) for r in records(out)] == [("a", "skipped"), ("b", "ok")]


def test_a_full_disk_when_taking_the_lock_is_one_line(folders, capsys, monkeypatch):
    class FullDisk:
        def __getattr__(self, name):
            return getattr(os, name)

        @staticmethod
        def write(fd, data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    src, depth, out = folders
    monkeypatch.setattr(lock_module, "os", FullDisk())
    before = tree(src.parent, leave_out=out)
    assert main(batch(src, depth, out)) == 2  # before: OSError 28, a traceback
    err = capsys.readouterr().err
    assert err == (f"photo3d: error: cannot create the lock file {out / 'batch.lock'}: "
                   "No space left on device\n")
    assert list(out.iterdir()) == []  # no lock, no temporary file, no manifest
    assert tree(src.parent, leave_out=out) == before


def test_the_ray_engine_without_ray_writes_nothing(folders, capsys, monkeypatch):
    src, depth, out = folders
    out.rmdir()
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    refused(capsys, batch(src, depth, out, "--engine", "ray"), src.parent,
            "--engine ray needs Ray: pip install 'photo3d[ray]'")
    assert not out.exists()  # before: OUT with an empty batch.jsonl


def test_a_batch_that_stops_before_its_first_photo_leaves_no_manifest(folders, monkeypatch):
    from photo3d.batch import find_photos, run_batch
    from photo3d.errors import Photo3DError

    src, depth, out = folders

    def unreachable(*args, **kwargs):
        raise Photo3DError("cannot connect to Ray at a new local Ray: refused")

    monkeypatch.setattr("photo3d.batch.ray_engine.run_ray", unreachable)
    pytest.importorskip("ray")
    with pytest.raises(Photo3DError, match="cannot connect"):
        run_batch(find_photos(src, depth=depth), out, engine="ray")
    assert list(out.iterdir()) == []


def test_a_file_system_without_hard_links_still_gets_a_lock(tmp_path, monkeypatch):
    from photo3d.batch.lock import batch_lock, is_lock_text
    from photo3d.errors import OutputError

    class NoLinks:
        def __getattr__(self, name):
            return getattr(os, name)

        @staticmethod
        def link(src, dst):
            raise OSError(errno.EPERM, os.strerror(errno.EPERM))

    monkeypatch.setattr(lock_module, "os", NoLinks())
    with batch_lock(tmp_path) as path:
        assert is_lock_text(path.read_bytes())
        with pytest.raises(OutputError, match="another photo3d batch is writing"):
            with batch_lock(tmp_path):
                pass
    assert list(tmp_path.iterdir()) == []
